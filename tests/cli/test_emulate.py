"""``dronetrack emulate``: what it prints, its exit codes and its truth file, driven by the
host-side clients on loopback (the Livox SDK 1 client, the DYNAMIXEL SDK turret).

The command runs in a subprocess on a loopback address of its own (127.0.0.x), so its
fixed device port 65000 meets no other test's; every wait is bounded."""

from __future__ import annotations

import math
import os
import re
import signal
import time
from contextlib import AbstractContextManager
from pathlib import Path

import numpy as np
import pytest

from dronetrack.actuators.dynamixel.turret import DynamixelTurret
from dronetrack.cli.main import run
from dronetrack.errors import DeviceError
from dronetrack.sim.emulate.servos import PtyServoLink, turret_bus
from dronetrack.sources.livox.sdk1 import LivoxClient, LivoxEndpoint
from emulated_rig import Emulator, emulator
from livox_helpers import read_for

AVIA_SLICE_S = 50 * 96 * 4_167e-9  # one device block: 50 packets of 96 firings


def _scenario(tmp_path: Path, flight_s: float) -> Path:
    toml = tmp_path / "short.toml"
    toml.write_text(
        f'base = "default"\nduration_s = {flight_s}\n\n[pipeline.background]\nscan_s = 0.5\n'
    )
    return toml


def _emulator(tmp_path: Path, flight_s: float) -> AbstractContextManager[Emulator]:
    """``dronetrack emulate`` of the default scenario with a 0.5 s scan and ``flight_s``
    of flight."""
    return emulator(tmp_path, str(_scenario(tmp_path, flight_s)))


def _client(ip: str) -> LivoxClient:
    return LivoxClient(LivoxEndpoint(ip, None, 0, 0, 0), discover_s=0.1)


@pytest.mark.slow
def test_emulate_prints_its_devices_streams_the_scenario_and_exits_0(tmp_path: Path) -> None:
    with _emulator(tmp_path, flight_s=0.5) as emu:
        lidar, turret_line = emu.lines
        assert lidar.startswith(f"lidar: livox://{emu.ip}  (Livox Avia, UDP {emu.ip}:65000)")
        pattern = (
            r"turret: dynamixel://(\S+)  \(2 XM430-W350, pan ID 1, tilt ID 2, 1000000 baud, on "
        )
        found = re.match(pattern, turret_line)
        assert found is not None
        assert found.group(1) == str(emu.link)
        assert os.path.realpath(emu.link).startswith("/dev/pts/")
        turret = DynamixelTurret(found.group(1))
        points, lost = 0, -1
        try:
            with _client(emu.ip) as client:
                client.open(timeout_s=3.0)
                deadline = time.monotonic() + 10.0
                # until the stream ends: no packet for the client's 1 s
                with pytest.raises(DeviceError, match="no point packet"):  # noqa: PT012
                    while time.monotonic() < deadline:
                        points += len(client.read(0.05))
                lost = client.packets_lost
            assert emu.proc.poll() is None  # still answering while the host closes
        finally:
            turret.close()
        rc = emu.proc.wait(timeout=10)
        err = emu.proc.stderr.read().decode() if emu.proc.stderr else ""
    assert rc == 0, err
    assert points > 0
    assert lost == 0
    assert "sampling started" in err
    assert "Traceback" not in err
    # 0.5 s scan + 0.5 s flight + 2 periods of tail, in whole device blocks, a truth row
    # at each block's end and at 0, flushed as it went
    slices = math.ceil((0.5 + 0.5 + 0.2) / AVIA_SLICE_S)
    assert f"streamed {slices * AVIA_SLICE_S:.2f} s" in err
    table = np.loadtxt(emu.truth, delimiter=",", skiprows=1)
    assert table.shape == (slices + 1, 4)
    np.testing.assert_allclose(table[:, 0], np.arange(slices + 1) * AVIA_SLICE_S, atol=1e-9)
    assert not emu.link.exists()  # the link goes with the command


def _finish(emu: Emulator, within_s: float) -> tuple[int, str]:
    """The emulator's exit code and stderr, once it has ended by itself."""
    rc = emu.proc.wait(timeout=within_s)
    return rc, emu.proc.stderr.read().decode() if emu.proc.stderr else ""


@pytest.mark.slow
def test_emulate_exits_0_by_itself_when_the_host_stops_before_the_end(tmp_path: Path) -> None:
    # 0.5 s scan + 0.5 s flight + 0.2 s tail from the start, then 2 s while the host
    # closes: about 3.2 s after the start
    with _emulator(tmp_path, flight_s=0.5) as emu:
        with _client(emu.ip) as client:
            client.open(timeout_s=3.0)
            read_for(client, 0.3)
        assert emu.proc.poll() is None  # still serving: a host may start it again
        rc, err = _finish(emu, within_s=15.0)
    assert rc == 0, err
    assert err.count("sampling started") == 1
    assert re.search(r"streamed \d\.\d\d s of short: \d+ point packets", err)
    assert "Traceback" not in err


@pytest.mark.slow
def test_emulate_serves_a_host_that_starts_again_after_the_stream(tmp_path: Path) -> None:
    slices = math.ceil((0.5 + 0.5 + 0.2) / AVIA_SLICE_S)
    with _emulator(tmp_path, flight_s=0.5) as emu:
        for _ in range(2):  # the second starts within the 2 s after the first stream
            with _client(emu.ip) as client:
                client.open(timeout_s=3.0)
                with pytest.raises(DeviceError, match="no point packet"):
                    read_for(client, 10.0)  # until the stream ends
                # the whole scenario, 50 packets a slice (the last slice's may end
                # early, with its last point)
                assert client.packets_received > 50 * (slices - 1)
        rc, err = _finish(emu, within_s=15.0)
    assert rc == 0, err
    assert err.count("sampling started") == 2
    assert len(np.loadtxt(emu.truth, delimiter=",", skiprows=1)) == slices + 1


@pytest.mark.slow
def test_emulate_without_a_host_gives_up_after_its_wait(tmp_path: Path) -> None:
    with emulator(tmp_path, str(_scenario(tmp_path, 0.5)), "--wait-s", "1") as emu:
        rc, err = _finish(emu, within_s=15.0)
    assert rc == 2, err
    want = "error: short: waited 1 s for a host to start sampling, none came (--wait-s)"
    assert err.strip().splitlines()[-1] == want
    assert not emu.link.exists()


def test_emulate_refuses_a_serial_link_another_emulator_holds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    link = tmp_path / "ttyDXL"
    ip = f"127.0.0.{20 + (os.getpid() + 100) % 200}"  # not the subprocess emulators'
    with PtyServoLink(turret_bus(), link=link, lifetime=60.0) as held:
        args = ["emulate", str(_scenario(tmp_path, 0.5)), "--lidar-ip", ip]
        assert run([*args, "--serial-link", str(link)]) == 2
        assert os.readlink(link) == held.path  # still the first one's
    err = capsys.readouterr().err.strip()
    want = rf"error: cannot link {link} to /dev/pts/\d+: it links to {held.path}, still open"
    assert re.match(want, err)
    assert "\n" not in err


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
@pytest.mark.slow
def test_emulate_stopped_by_a_signal_exits_130_and_keeps_the_truth(
    tmp_path: Path, signum: signal.Signals
) -> None:
    with _emulator(tmp_path, flight_s=20.0) as emu, _client(emu.ip) as client:
        client.open(timeout_s=3.0)
        deadline = time.monotonic() + 0.5
        while time.monotonic() < deadline:
            client.read(0.05)
        emu.proc.send_signal(signum)
        rc = emu.proc.wait(timeout=10)
        err = emu.proc.stderr.read().decode() if emu.proc.stderr else ""
    assert rc == 130, err
    last = err.strip().splitlines()[-1]
    assert last.startswith("interrupted; truth (")
    assert str(emu.truth) in last
    assert "Traceback" not in err
    table = np.loadtxt(emu.truth, delimiter=",", skiprows=1, ndmin=2)
    # about 0.5 s of slices were made before the signal (20 ms each)
    assert len(table) >= 10
    assert table[0, 0] == 0.0
    assert np.all(np.diff(table[:, 0]) > 0)
    assert not emu.link.exists()


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--lidar-ip", "300.1.2.3"], "error: --lidar-ip '300.1.2.3' is not an IPv4 address"),
        (["--lidar-dest", "127.0.0.1:2368"], "error: --lidar-dest is for a VLP-16"),
        (["walk-square", "--lidar-dest", "127.0.0.1:0"], "error: --lidar-dest '127.0.0.1:0'"),
        (["walk-square", "--lidar-dest", "localhost"], "error: --lidar-dest 'localhost'"),
        (
            ["walk-square", "--lidar-ip", "192.0.2.1"],
            "error: emulated VLP-16: cannot send from 192.0.2.1 to 255.255.255.255:2368",
        ),
        (["nowhere"], "error: unknown scenario 'nowhere'"),
        (["--duration", "0"], "error: Invalid value for '--duration'"),
        (["--ptu-baud", "1234"], "error: --ptu-baud 1234 is not a standard rate (1200, "),
        (["--lidar-ip", "192.0.2.1"], "error: emulated Livox: cannot bind 192.0.2.1:65000"),
    ],
)
def test_emulate_bad_options_fail_with_one_line_and_exit_2(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(["emulate", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(message)
    assert "\n" not in err
