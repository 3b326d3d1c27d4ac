"""The emulated FLIR PTU-E46: each command's reply as the PTU-D46 User's Manual
(v2.14.0, §4.2-4.5) words it, written here by hand; its motion; its line paced as a
9600-baud serial line; and its pseudo-terminal and TCP server spoken to with raw
bytes."""

from __future__ import annotations

import math
import os
import select
import socket
import time

import pytest

from dronetrack.config.rig import make_turret
from dronetrack.errors import ConfigError
from dronetrack.formats.ptu import ARCSEC
from dronetrack.sim.emulate.ptu import FIRMWARE_BANNER, EmulatedPtu
from dronetrack.sim.emulate.ptu_link import LineTiming, PtyPtuLink, TcpPtuServer

E46 = make_turret("ptu-e46")
R = 46.44  # the preset's 0.0129° in arc-seconds
TAU = 10.0 / 9600.0  # one byte at 9600 baud, 8N1


class ManualClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def _unit(clock: ManualClock | None = None) -> EmulatedPtu:
    return EmulatedPtu.from_turret(E46, clock=clock or ManualClock())


def _say(ptu: EmulatedPtu, command: str) -> str:
    return ptu.handle(command, b" ").decode()


def test_it_powers_up_echoing_in_verbose_mode() -> None:
    ptu = _unit()
    assert _say(ptu, "PP") == "PP * Current Pan position is 0\r\n"
    assert _say(ptu, "ED") == "ED *\r\n"  # echoed: echo was on when it came
    assert _say(ptu, "PP") == "* Current Pan position is 0\r\n"
    assert _say(ptu, "F") == "* ASCII verbose mode\r\n"
    assert _say(ptu, "FT") == "*\r\n"
    assert _say(ptu, "PP") == "* 0\r\n"  # §4.5.4: "FT *  PP * 0"
    assert _say(ptu, "E") == "* Echoing OFF\r\n"


def test_the_presets_resolution_limits_and_speeds_in_positions() -> None:
    # 0.0129° = 46.44″; pan ±159° → ±12325.6; tilt 31° up (+2403.1) and 47° down
    # (-3643.4); 300°/s → 23255.8 positions/s; verbose answers in the D46 manual's words
    ptu = _unit()
    _say(ptu, "ED")
    assert _say(ptu, "PR") == "* 46.4400 seconds arc per Pan position\r\n"
    assert _say(ptu, "PN") == "* Minimum Pan position is -12325\r\n"
    assert _say(ptu, "PU") == "* Maximum Pan speed is 23255 positions/sec\r\n"
    _say(ptu, "FT")
    expected = {
        "PR": "46.4400",
        "TR": "46.4400",
        "PN": "-12325",
        "PX": "12325",
        "TN": "-3643",
        "TX": "2403",
        "PU": "23255",
        "TU": "23255",
        "PL": "0",
        "PS": "23255",
        "PA": "23256",  # 300°/s² → 23255.8 positions/s²
    }
    for command, value in expected.items():
        assert _say(ptu, command) == f"* {value}\r\n", command


def test_refusals_as_the_manual_words_them() -> None:
    ptu = _unit()
    _say(ptu, "ED")
    _say(ptu, "FT")
    assert _say(ptu, "PP12326") == "! Maximum allowable Pan position is 12325\r\n"
    assert _say(ptu, "TP-3644") == "! Minimum allowable Tilt position is -3643\r\n"
    assert _say(ptu, "PS23256") == "! Pan speed cannot exceed 23255 positions/sec\r\n"
    assert _say(ptu, "TS-1") == "! Motor speed cannot be less than 0 pos/sec\r\n"
    assert _say(ptu, "QQ") == "! Illegal command\r\n"
    assert _say(ptu, "PO100") == "! Illegal command\r\n"  # not emulated
    assert _say(ptu, "PPABC") == "! Illegal argument\r\n"
    assert _say(ptu, "PN5") == "! Illegal argument\r\n"
    assert _say(ptu, "FT1") == "! Illegal argument\r\n"
    assert _say(ptu, "PA0") == "! Illegal argument\r\n"
    assert _say(ptu, "CV") == "! Mode not emulated\r\n"
    assert _say(ptu, "EDX") == "! Illegal argument\r\n"
    assert ptu.refused == 12
    # §4.3.5: limits off, a goal beyond them is taken
    assert _say(ptu, "LD") == "*\r\n"
    assert _say(ptu, "PP12326") == "*\r\n"
    assert _say(ptu, "L") == "* Limit bounds are DISABLED\r\n"
    assert _say(ptu, "V") == f"* {FIRMWARE_BANNER}\r\n"
    assert _say(ptu, "ci") == "*\r\n"  # case does not matter
    assert _say(ptu, "i") == "*\r\n"


def test_goals_move_the_joints_at_the_speed_set() -> None:
    clock = ManualClock()
    ptu = _unit(clock)
    _say(ptu, "FT")
    assert _say(ptu, "PS1000") == "PS1000 *\r\n"  # 1000 positions/s; echo still on
    _say(ptu, "ED")
    assert _say(ptu, "PP1000") == "*\r\n"
    clock.t = 0.5
    assert _say(ptu, "PP") == "* 500\r\n"
    clock.t = 2.0
    assert _say(ptu, "PP") == "* 1000\r\n"
    joint = ptu.axes["P"].joint
    assert joint.position(2.0) == pytest.approx(1000 * R * ARCSEC)
    # tilt: the unit's positions grow upwards, the turret's angle downwards
    _say(ptu, "TS23255")
    _say(ptu, "TP-100")
    clock.t = 3.0
    assert ptu.axes["T"].joint.position(3.0) == pytest.approx(100 * R * ARCSEC)
    assert _say(ptu, "TP") == "* -100\r\n"


def test_a_preset_without_a_resolution_is_refused() -> None:
    from dataclasses import replace

    flat = replace(E46, pan=replace(E46.pan, resolution=0.0))
    with pytest.raises(ConfigError, match="resolution"):
        EmulatedPtu.from_turret(flat)


def test_the_line_is_paced_as_9600_baud() -> None:
    ptu = _unit()
    _say(ptu, "ED")
    _say(ptu, "FT")
    timing = LineTiming(ptu, 9600)
    timing.receive(b"PP TP ", 100.0)
    # PP whole at 3 bytes, TP at 6; each reply "* 0\r\n" is 5 bytes, the second
    # waits for the first: 3τ + 5τ = 8τ, then max(6τ, 8τ) + 5τ = 13τ
    assert timing.next_due == pytest.approx(100.0 + 3 * TAU)
    assert timing.step(100.0 + 7.9 * TAU) == []
    assert timing.step(100.0 + 8.0 * TAU + 1e-9) == [b"* 0\r\n"]
    assert timing.next_due == pytest.approx(100.0 + 13 * TAU)
    assert timing.step(100.0 + 12.9 * TAU) == []
    assert timing.step(100.0 + 13 * TAU + 1e-9) == [b"* 0\r\n"]
    assert timing.next_due == math.inf
    # bytes read while earlier ones are still crossing the line queue behind them
    timing.receive(b"PP ", 200.0)
    timing.receive(b"TP ", 200.0)
    assert timing.next_due == pytest.approx(200.0 + 3 * TAU)
    timing.step(200.0 + 3 * TAU + 1e-9)
    assert timing.next_due == pytest.approx(200.0 + 6 * TAU)


def _read_lines(fd: int, count: int, timeout_s: float = 2.0) -> tuple[list[bytes], float]:
    out, start = b"", time.monotonic()
    while out.count(b"\n") < count and time.monotonic() - start < timeout_s:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            out += os.read(fd, 4096)
    return out.splitlines(), time.monotonic() - start


def test_a_pseudo_terminal_answers_raw_bytes_at_the_lines_pace() -> None:
    ptu = EmulatedPtu.from_turret(E46)
    with PtyPtuLink(ptu, lifetime=30.0) as link:
        fd = os.open(link.device, os.O_RDWR | os.O_NOCTTY)
        try:
            os.write(fd, b"ED FT ")
            lines, _ = _read_lines(fd, 2)
            assert lines == [b"ED *", b"*"]
            begin = time.monotonic()
            os.write(fd, b"PR TR PN ")
            lines, _ = _read_lines(fd, 3)
            took = time.monotonic() - begin
            assert lines == [b"* 46.4400", b"* 46.4400", b"* -12325"]
            # 9 bytes in; the replies of 11, 11 and 9 bytes go one after the other
            assert took >= (3 + 11 + 11 + 9) * TAU
        finally:
            os.close(fd)


def test_a_host_at_another_baud_rate_gets_no_answer() -> None:
    serial = pytest.importorskip("serial")
    with (
        PtyPtuLink(_unit(), lifetime=30.0) as link,
        serial.Serial(link.device, baudrate=38400, timeout=0.3) as line,
    ):
        line.write(b"ED ")
        assert line.read(16) == b""  # 0.3 s: the reply would take 6 ms at 9600
        assert link.host_baud == 38400
        line.baudrate = 9600
        line.write(b"ED ")
        assert line.read_until(b"\n", 16) == b"ED *\r\n"
    with PtyPtuLink(_unit(), lifetime=30.0) as link:
        assert link.host_baud == 9600  # the terminal starts at the unit's rate


def test_the_tcp_server_answers_each_connection() -> None:
    ptu = EmulatedPtu.from_turret(E46)
    with TcpPtuServer(ptu) as server:
        host, port = server.address
        assert server.uri == f"ptu://127.0.0.1:{port}"
        for _ in range(2):
            with socket.create_connection((host, port), timeout=2.0) as conn:
                conn.sendall(b"FT\rPP\rTX\r")
                got = b""
                deadline = time.monotonic() + 2.0
                while got.count(b"\n") < 3 and time.monotonic() < deadline:
                    got += conn.recv(4096)
                # echo is on until a host turns it off: CR-delimited commands echo
                # their CR, which ends a line of its own
                assert [line for line in got.split(b"\r\n") if line] == [
                    b"FT\r*",
                    b"PP\r* 0",
                    b"TX\r* 2403",
                ]
        assert server.connections == 2
