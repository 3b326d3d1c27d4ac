"""PtuTurret and its line: against replies written by hand from the PTU-D46 User's
Manual (a scripted unit answering as its examples do), and against the emulated
PTU-E46 on a pseudo-terminal and over TCP."""

from __future__ import annotations

import contextlib
import itertools
import math
import re
import time
from collections.abc import Callable, Iterator

import pytest

from dronetrack.actuators.ptu.line import PtuLine
from dronetrack.actuators.ptu.turret import PtuTurret, goal_limits
from dronetrack.actuators.ptu.uri import PtuUri, parse_ptu_uri
from dronetrack.actuators.turrets import check_turret_uri, open_turret
from dronetrack.config.rig import make_turret
from dronetrack.errors import ConfigError, DeviceError
from dronetrack.formats.ptu import ARCSEC
from dronetrack.sim.emulate.ptu import EmulatedPtu
from dronetrack.sim.emulate.ptu_link import PtyPtuLink, TcpPtuServer
from dronetrack.types import TurretCommand

E46 = make_turret("ptu-e46")
D46_R = 185.1428  # §4.3.3's resolution [arc-seconds/position]
TAU = 10.0 / 9600.0

# What a D46 answers in terse mode, from the manual's examples (§4.3.3, §4.3.4, §4.4.6)
D46_ANSWERS = {
    "PR": b"* 185.1428\r\n",
    "TR": b"* 185.1428\r\n",
    "PN": b"* -3090\r\n",
    "PX": b"* 3090\r\n",
    "TN": b"* -907\r\n",
    "TX": b"* 604\r\n",
    "PU": b"* 2902\r\n",
    "TU": b"* 2902\r\n",
}


class ManualClock:
    def __init__(self, t: float = 10.0) -> None:
        self.t = t

    def __call__(self) -> float:
        return self.t


class ScriptedUnit:
    """A transport whose unit answers each command with the bytes ``answer(command)``
    gives (None: no answer); what was written is kept in ``written``, the longest wait
    each read was allowed [s] in ``waits``."""

    def __init__(self, answer: Callable[[str], bytes | None]) -> None:
        self.answer = answer
        self.written: list[bytes] = []
        self.waits: list[float] = []
        self.pending = b""
        self.closed = False

    def write(self, data: bytes) -> None:
        self.written.append(data)
        for command in data.decode().split():
            reply = self.answer(command)
            if reply is not None:
                self.pending += reply

    def read(self, timeout_s: float) -> bytes:
        self.waits.append(timeout_s)
        out, self.pending = self.pending, b""
        if not out:
            time.sleep(min(timeout_s, 0.002))
        return out

    def discard_input(self) -> None:
        self.pending = b""

    def close(self) -> None:
        self.closed = True


def d46(positions: dict[str, int], silent: set[str] | None = None) -> Callable[[str], bytes | None]:
    """A terse D46: queries from ``D46_ANSWERS`` and ``positions`` (``PP``, ``TP``);
    any other command ``*``; nothing for the commands in ``silent``."""

    def answer(command: str) -> bytes | None:
        if silent and command in silent:
            return None
        if command in D46_ANSWERS:
            return D46_ANSWERS[command]
        if command in positions:
            return f"* {positions[command]}\r\n".encode()
        return b"*\r\n"

    return answer


def _scripted(
    answer: Callable[[str], bytes | None], clock: ManualClock
) -> tuple[ScriptedUnit, PtuTurret]:
    unit = ScriptedUnit(answer)
    line = PtuLine(unit, "FLIR PTU on /dev/fake", baud=9600, clock=clock, timeout_s=0.05)
    return unit, PtuTurret(line, turret=E46, clock=clock, poll_hz=0)


def test_opening_sets_the_unit_up_from_its_answers() -> None:
    clock = ManualClock()
    unit, turret = _scripted(d46({"PP": 0, "TP": 0}), clock)
    sent = b"".join(unit.written).decode()
    assert sent.startswith(" ED FT CI I PR TR PN PX TN TX PU TU ")
    # the preset's 300°/s is 300 · 3600 / 185.1428 = 5833 positions/s, over the bound
    # 2902; 300°/s² is 5833 positions/s²
    assert "PS2902 PA5833 TS2902 TA5833 " in sent
    pan, tilt = turret.axes
    assert pan.resolution == pytest.approx(math.radians(185.1428 / 3600.0))  # 0.0514285°
    # pan: ±159° is ±3091.7, inside the unit's ±3090; tilt: 47° down is -913.9 and
    # 31° up 602.8, so [-907, 602] with the unit's [-907, 604]
    assert pan.limits == (-3090, 3090)
    assert tilt.limits == (-907, 602)
    assert (pan.max_speed, pan.speed, pan.accel) == (2902, 2902, 5833)
    turret.close()
    assert unit.closed


def test_positions_read_convert_with_the_resolution_and_are_stamped_on_the_line() -> None:
    clock = ManualClock(10.0)
    _, turret = _scripted(d46({"PP": 414, "TP": -194}), clock)
    state = turret.state()
    assert math.degrees(state.pan) == pytest.approx(414 * 0.0514285, abs=1e-4)  # 21.29°
    assert math.degrees(state.tilt) == pytest.approx(194 * 0.0514285, abs=1e-4)  # down
    # "PP TP ": the unit has PP after 3 bytes, TP after 6; the state is stamped between
    assert state.stamp == pytest.approx(10.0 + 4.5 * TAU)
    assert (state.pan_rate, state.tilt_rate) == (0.0, 0.0)


def test_rates_are_the_slope_between_readings() -> None:
    clock = ManualClock(10.0)
    positions = {"PP": 0, "TP": 0}
    _, turret = _scripted(d46(positions), clock)
    turret.state()
    clock.t, positions["PP"], positions["TP"] = 10.1, 100, -50
    state = turret.state()
    r = D46_R * ARCSEC
    assert state.pan_rate == pytest.approx(100 * r / 0.1)
    assert state.tilt_rate == pytest.approx(50 * r / 0.1)
    clock.t = 11.0  # more than RATE_GAP_S later: no rate
    assert turret.state().pan_rate == 0.0


def test_goals_are_clamped_and_only_changed_ones_sent() -> None:
    clock = ManualClock()
    unit, turret = _scripted(d46({"PP": 0, "TP": 0}), clock)
    unit.written.clear()
    turret.command(TurretCommand(0.0, math.radians(170.0), math.radians(60.0)))
    assert unit.written == [b"PP3090 TP-907 "]
    turret.command(TurretCommand(0.0, math.radians(170.0), math.radians(-10.0)))
    assert unit.written[-1] == b"TP194 "  # 10° up
    turret.command(TurretCommand(0.0, math.radians(180.0), math.nan))
    assert len(unit.written) == 2  # nothing changed: nothing sent
    # a rate command: q + ω T from the position read now (PP 0)
    turret.command(TurretCommand(0.0, math.radians(10.0), 0.0, "velocity"))
    assert unit.written[-2] == b"PP TP "
    assert unit.written[-1] == b"PP19 TP0 "  # 1° = 19.4 positions; tilt back to 0


def test_a_refusal_is_a_device_error_naming_the_unit_and_the_command() -> None:
    clock = ManualClock()

    def refusing(command: str) -> bytes | None:
        if command.startswith("PP") and command != "PP":
            return b"! Maximum allowable Pan position is 3090\r\n"
        return d46({"PP": 0, "TP": 0})(command)

    _, turret = _scripted(refusing, clock)
    with pytest.raises(DeviceError) as info:
        turret.command(TurretCommand(0.0, math.radians(5.0), 0.0))
    assert str(info.value) == (
        "FLIR PTU on /dev/fake: PP97: the unit answered ! Maximum allowable Pan position is 3090"
    )


def test_a_reply_that_never_comes_is_a_device_error_in_bounded_time() -> None:
    """The query is written once and its replies waited for until one deadline, the
    time-out the error states: every wait the line asks of the transport fits in it,
    none longer than the one before (the deadline is never pushed back)."""
    clock = ManualClock()
    silent: set[str] = set()
    unit, turret = _scripted(d46({"PP": 0, "TP": 0}, silent), clock)
    silent.add("TP")
    writes, reads = len(unit.written), len(unit.waits)
    with pytest.raises(
        DeviceError,
        match=r"FLIR PTU on /dev/fake: read the positions: no answer at 9600 baud within 0\.\d+ s "
        r"\(1 of 2 replies\)",
    ) as info:
        turret.state()
    assert unit.written[writes:] == [b"PP TP "]
    waits = unit.waits[reads:]
    stated = re.search(r"within (\d+\.\d+) s", str(info.value))
    assert stated is not None
    assert 0 < max(waits) <= float(stated[1]) + 0.005  # stated to 10 ms
    assert all(b <= a for a, b in itertools.pairwise(waits))
    assert turret.line.timeouts == 1
    silent.clear()
    assert turret.state().pan == 0.0  # the line recovers


def test_echo_verbose_leftovers_and_limit_markers_are_taken_in_stride() -> None:
    clock = ManualClock()

    def echoing(command: str) -> bytes | None:
        if command == "ED":
            return b"ED *\r\n"  # echoed before echo went off
        if command == "FT":
            return b"!P*\r\n"  # a limit hit just before
        return d46({"PP": 7, "TP": 0})(command)

    _, turret = _scripted(echoing, clock)
    assert turret.goals == [7, 0]
    assert turret.line.limit_hits == 1


def test_a_verbose_answer_where_a_number_is_due_is_a_device_error() -> None:
    clock = ManualClock()

    def verbose(command: str) -> bytes | None:
        if command == "PR":
            return b"* 185.1428 seconds arc per Pan position\r\n"
        return d46({})(command)

    with pytest.raises(DeviceError, match="PR: expected a number"):
        _scripted(verbose, clock)


def test_limits_that_miss_the_units_are_a_config_error() -> None:
    assert goal_limits(E46.pan, "pan", D46_R, (-3090, 3090)) == (-3090, 3090)
    with pytest.raises(ConfigError, match="do not overlap"):
        goal_limits(E46.tilt, "tilt", D46_R, (1000, 2000))


# -- URIs ------------------------------------------------------------------------------


def test_uris() -> None:
    assert parse_ptu_uri("ptu:///dev/ttyUSB0") == PtuUri("/dev/ttyUSB0")
    assert parse_ptu_uri("ptu:///dev/ttyUSB0?baud=38400&poll_hz=0") == PtuUri(
        "/dev/ttyUSB0", baud=38400, poll_hz=0.0
    )
    assert parse_ptu_uri("ptu://COM3") == PtuUri("COM3")
    tcp = parse_ptu_uri("ptu://192.168.1.110:4000?poll_hz=50")
    assert (tcp.device, tcp.host, tcp.port, tcp.poll_hz) == (None, "192.168.1.110", 4000, 50.0)
    assert tcp.name == "FLIR PTU at 192.168.1.110:4000"
    assert parse_ptu_uri("ptu://[fe80::1]:4000").host == "fe80::1"


@pytest.mark.parametrize(
    ("uri", "message"),
    [
        ("dynamixel:///dev/ttyUSB0", "a FLIR PTU is ptu://DEVICE or ptu://HOST:PORT"),
        ("ptu://", "names no serial device or HOST:PORT"),
        ("ptu:///dev/ttyUSB0?baud=1234", "baud 1234 is not a standard rate"),
        ("ptu:///dev/ttyUSB0?baud=fast", "baud='fast' is not an integer"),
        ("ptu:///dev/ttyUSB0?poll_hz=500", "poll_hz 500 is neither 0"),
        ("ptu:///dev/ttyUSB0?poll_hz=x", "poll_hz='x' is not a number"),
        ("ptu:///dev/ttyUSB0?speed=1", "unknown key 'speed'"),
        ("ptu:///dev/ttyUSB0?baud=9600&baud=9600", "baud given twice"),
        ("ptu:///dev/ttyUSB0?baud", "'baud' is not key=value"),
        ("ptu://host:4000?baud=9600", "baud is for a serial line, not TCP"),
        ("ptu://host:70000", "port 70000 is not in 1-65535"),
        ("ptu://192.168.1.110", "give a serial device's path"),
        ("ptu://ttyUSB0", "give a serial device's path"),
    ],
)
def test_bad_uris_are_one_line_config_errors(uri: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace("(", r"\(").replace("?", r"\?")):
        parse_ptu_uri(uri)
    if uri.startswith("ptu://"):
        with pytest.raises(ConfigError):
            check_turret_uri(uri)


# -- against the emulator ---------------------------------------------------------------


@pytest.fixture
def emulated() -> Iterator[tuple[EmulatedPtu, PtyPtuLink]]:
    ptu = EmulatedPtu.from_turret(E46)
    link = PtyPtuLink(ptu, lifetime=60.0)
    yield ptu, link
    link.close()


def test_the_emulated_unit_is_set_up_and_followed(
    emulated: tuple[EmulatedPtu, PtyPtuLink],
) -> None:
    ptu, link = emulated
    with contextlib.closing(
        PtuTurret.from_uri(f"ptu://{link.device}?poll_hz=0", turret=E46)
    ) as turret:
        assert (ptu.echo, ptu.terse) == (False, True)
        pan, tilt = turret.axes
        assert pan.resolution_arcsec == pytest.approx(46.44)
        assert pan.limits == (-12325, 12325)
        assert tilt.limits == (-3643, 2403)
        assert (ptu.axes["P"].speed, ptu.axes["T"].accel) == (23255, 23256)
        turret.command(TurretCommand(0.0, math.radians(10.0), math.radians(-5.0)))
        assert (ptu.axes["P"].goal, ptu.axes["T"].goal) == (775, 388)  # 10°, 5° up
        time.sleep(0.2)  # 300°/s: there long since
        state = turret.state()
        assert math.degrees(state.pan) == pytest.approx(10.0, abs=0.0129)
        assert math.degrees(state.tilt) == pytest.approx(-5.0, abs=0.0129)
        # the guard's limits and the unit's: 170° goes to the last position inside both
        turret.command(TurretCommand(0.0, math.radians(170.0), 0.0))
        assert ptu.axes["P"].goal == 12325
        refused = ptu.refused
    assert ptu.refused == refused == 0
    assert link.serving


def test_the_poller_reads_the_emulated_unit_at_its_rate(
    emulated: tuple[EmulatedPtu, PtyPtuLink],
) -> None:
    _, link = emulated
    guard = open_turret(f"ptu://{link.device}?poll_hz=20", E46)
    try:
        assert guard.name == f"FLIR PTU on {link.device}"
        guard.readings(timeout_s=2.0)  # starts the poller
        guard.command(TurretCommand(0.0, math.radians(-30.0), 0.0))
        time.sleep(0.5)
        got = guard.readings(time.monotonic(), timeout_s=2.0)
        assert 6 <= len(got) <= 12  # 20 a second for 0.5 s
        stamps = [s.stamp for s in got]
        assert stamps == sorted(stamps)
        assert math.degrees(got[-1].pan) == pytest.approx(-30.0, abs=0.013)
        assert guard.reads_missed == 0
    finally:
        guard.close()


def test_an_unplugged_unit_ends_polling_with_an_error_naming_it(
    emulated: tuple[EmulatedPtu, PtyPtuLink],
) -> None:
    _, link = emulated
    turret = PtuTurret.from_uri(f"ptu://{link.device}?poll_hz=50", turret=E46)
    try:
        turret.readings(timeout_s=2.0)
        link.close()
        time.sleep(0.2)  # 10 polls: three misses in a row end the polling
        with pytest.raises(DeviceError, match=f"FLIR PTU on {link.device}"):
            turret.readings(time.monotonic(), timeout_s=2.0)
        assert turret.reads_missed == 3
    finally:
        with contextlib.suppress(DeviceError):
            turret.close()


def test_over_tcp() -> None:
    ptu = EmulatedPtu.from_turret(E46)
    with TcpPtuServer(ptu) as server:
        uri = server.uri
        turret = PtuTurret.from_uri(uri + "?poll_hz=0", turret=E46)
        assert turret.name == f"FLIR PTU at {server.address[0]}:{server.address[1]}"
        turret.command(TurretCommand(0.0, 0.0, math.radians(20.0)))
        assert ptu.axes["T"].goal == -1550  # 20° down: -20 · 3600 / 46.44
        turret.close()
    with pytest.raises(DeviceError, match="cannot open the line"):
        PtuTurret.from_uri(uri)
