"""DynamixelTurret, through the official DYNAMIXEL SDK, against the emulated
XM430-W350s on a pseudo-terminal (no hardware)."""

from __future__ import annotations

import contextlib
import itertools
import math
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.actuators.dynamixel.port import READ_WAIT_S
from dronetrack.actuators.dynamixel.turret import (
    DynamixelTurret,
    DynamixelUri,
    axis_tick_limits,
    parse_dynamixel_uri,
)
from dronetrack.actuators.state_poller import FAIL_AFTER
from dronetrack.config.rig import make_turret
from dronetrack.errors import ConfigError, DeviceError, MissingExtraError
from dronetrack.formats.dynamixel import (
    ADDR,
    BROADCAST_ID,
    Inst,
    rad_to_ticks,
    rate_to_units,
    ticks_to_rad,
    units_to_rate,
)
from dronetrack.sim.emulate.servos import PtyServoLink, ServoBus, turret_bus
from dronetrack.types import TurretCommand

if TYPE_CHECKING:
    from dronetrack.formats.dynamixel import BadPacket, Packet

pytest.importorskip("dynamixel_sdk")

WIDOWX = make_turret("widowx")
TICK = 2.0 * math.pi / 4096


class ManualClock:
    """One clock for the emulated servos and the driver, moved by hand: motion has
    exact known answers whatever the machine's load."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


@dataclass
class Rig:
    clock: ManualClock
    bus: ServoBus
    link: PtyServoLink
    turret: DynamixelTurret


def _rig() -> Rig:
    clock = ManualClock()
    bus = turret_bus(1, 2, clock)
    link = PtyServoLink(bus, lifetime=120.0)
    try:
        turret = DynamixelTurret.from_uri(
            f"dynamixel://{link.device}?baud=1000000&pan=1&tilt=2", turret=WIDOWX, clock=clock
        )
    except BaseException:
        link.close()
        raise
    return Rig(clock, bus, link, turret)


@pytest.fixture
def rig() -> Iterator[Rig]:
    made = _rig()
    yield made
    with contextlib.suppress(DeviceError):  # a test that unplugged the emulator
        made.turret.close()
    made.link.close()


@pytest.fixture(scope="module")
def shared_rig() -> Iterator[Rig]:
    made = _rig()
    yield made
    made.turret.close()
    made.link.close()


def _applied(rig: Rig, count: int) -> None:
    """Wait (at most 1 s) until both emulated servos have accepted ``count`` goals: a
    sync write has no answer, and the hand-moved clock must not pass the emulator."""
    deadline = time.monotonic() + 1.0
    while time.monotonic() < deadline:
        with rig.bus.lock:
            if all(len(rig.bus.servo(i).goals) >= count for i in (1, 2)):
                return
        time.sleep(0.001)
    raise AssertionError(f"the emulator did not receive goal number {count}")


def _command(rig: Rig, command: TurretCommand) -> None:
    count = len(rig.bus.servo(1).goals) + 1
    rig.turret.command(command)
    _applied(rig, count)


def _heard(bus: ServoBus) -> list[tuple[int, int, int | None]]:
    """From now on, (ID, instruction, line speed) of every packet the emulated bus gets."""
    heard: list[tuple[int, int, int | None]] = []
    handle = bus.handle

    def handle_and_note(packet: Packet | BadPacket, baud: int | None = None) -> list[bytes]:
        heard.append((packet.ident, getattr(packet, "instruction", -1), baud))
        return handle(packet, baud)

    bus.handle = handle_and_note  # type: ignore[method-assign]
    return heard


def _looks(turret: DynamixelTurret) -> list[tuple[float, float]]:
    """From now on, every look the SDK takes at the line for a status packet (a
    ``readPort``), with its packet's start and time-out [ms] on the SDK's clock."""
    looks: list[tuple[float, float]] = []
    port = turret.line.port
    read = port.readPort

    def read_and_note(length: int) -> object:
        looks.append((port.packet_start_time, port.packet_timeout))
        return read(length)

    port.readPort = read_and_note
    return looks


# -- the URI --------------------------------------------------------------------------


def test_uri_defaults_and_values() -> None:
    assert parse_dynamixel_uri("dynamixel:///dev/ttyUSB0") == DynamixelUri("/dev/ttyUSB0")
    assert parse_dynamixel_uri("dynamixel:///dev/ttyDXL?baud=57600&tilt=4&pan=3") == (
        DynamixelUri("/dev/ttyDXL", 57600, 3, 4)
    )


@pytest.mark.parametrize(
    ("uri", "problem"),
    [
        ("serial:///dev/ttyUSB0", "dynamixel://DEVICE"),
        ("dynamixel://?baud=1000000", "names no serial device"),
        ("dynamixel:///dev/ttyUSB0?speed=1000000", "unknown key 'speed'"),
        ("dynamixel:///dev/ttyUSB0?baud=fast", "baud='fast' is not an integer"),
        ("dynamixel:///dev/ttyUSB0?baud=1234", "baud 1234 is not one"),
        ("dynamixel:///dev/ttyUSB0?pan=253", "pan ID 253 is not in 0–252"),
        ("dynamixel:///dev/ttyUSB0?pan=2&tilt=2", "pan and tilt share ID 2"),
        ("dynamixel:///dev/ttyUSB0?pan=1&pan=3", "pan given twice"),
        ("dynamixel:///dev/ttyUSB0?baud", "'baud' is not key=value"),
    ],
)
def test_bad_uris_raise_one_line_config_errors(uri: str, problem: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_dynamixel_uri(uri)
    assert problem in str(info.value)
    assert "\n" not in str(info.value)


def test_without_the_sdk_the_error_names_the_extra(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "dynamixel_sdk", None)  # import fails
    with pytest.raises(MissingExtraError, match=r"dronetrack\[live\]"):
        DynamixelTurret("/dev/null")


def test_tick_limits_lie_inside_the_joint_limits() -> None:
    lo, hi = axis_tick_limits(WIDOWX.tilt)
    assert WIDOWX.tilt.lower <= ticks_to_rad(lo) < WIDOWX.tilt.lower + TICK
    assert WIDOWX.tilt.upper - TICK < ticks_to_rad(hi) <= WIDOWX.tilt.upper
    assert axis_tick_limits(WIDOWX.pan) == (0, 4095)  # ±180°: the servo's whole turn


# -- opening --------------------------------------------------------------------------


def test_opening_configures_both_servos(rig: Rig) -> None:
    for ident, axis in ((1, WIDOWX.pan), (2, WIDOWX.tilt)):
        assert rig.bus.value(ident, ADDR.TORQUE_ENABLE) == 1
        assert rig.bus.value(ident, ADDR.OPERATING_MODE) == 3
        # 180°/s → 131 × 0.229 rpm; 360°/s² → 17 × 214.577 rev/min²
        assert rig.bus.value(ident, ADDR.PROFILE_VELOCITY) == 131
        assert rig.bus.value(ident, ADDR.PROFILE_ACCELERATION) == 17
        lo, hi = axis_tick_limits(axis)
        assert rig.bus.value(ident, ADDR.MIN_POSITION) == lo
        assert rig.bus.value(ident, ADDR.MAX_POSITION) == hi
    # tilt ±68°: 2048 ∓ 68/360 · 4096 = 2048 ∓ 773.7
    assert axis_tick_limits(WIDOWX.tilt) == (1275, 2821)


def test_opening_clears_a_time_based_profile_and_keeps_reverse_mode() -> None:
    clock = ManualClock()
    bus = turret_bus(1, 2, clock)
    bus.servo(2).values[ADDR.DRIVE_MODE] = 0x05  # reverse + time-based profile
    with PtyServoLink(bus, lifetime=30.0) as link:
        turret = DynamixelTurret(link.device, clock=clock)
        assert bus.value(2, ADDR.DRIVE_MODE) == 0x01
        turret.close()


@pytest.mark.parametrize(("model", "problem"), [(1060, "model number 1060"), (None, "no status")])
def test_a_wrong_or_absent_servo_is_named(model: int | None, problem: str) -> None:
    bus = turret_bus(1, 2, ManualClock())
    if model is None:
        bus.set_online(2, False)
    else:
        bus.servo(2).values[ADDR.MODEL_NUMBER] = model
    with PtyServoLink(bus, lifetime=30.0) as link, pytest.raises(DeviceError) as info:
        DynamixelTurret(link.device)
    message = str(info.value)
    assert f"on {link.device}" in message
    assert "servo ID 2 (tilt)" in message
    assert problem in message


@pytest.mark.slow
def test_servos_at_another_baud_rate_are_one_error_naming_the_rate_tried() -> None:
    """One error after two packets at the URI's rate (the pan servo's ping, then a
    broadcast ping), no retry; at the servos' own rate they answer."""
    bus = turret_bus(1, 2, ManualClock())
    with PtyServoLink(bus, lifetime=30.0) as link:
        heard = _heard(bus)
        with pytest.raises(DeviceError) as info:
            DynamixelTurret.from_uri(f"dynamixel://{link.device}?baud=57600")
        assert heard == [(1, Inst.PING, 57600), (BROADCAST_ID, Inst.PING, 57600)]
        turret = DynamixelTurret(link.device)  # at the servos' 1 Mbit/s they answer
        turret.close()
    message = str(info.value)
    assert message.startswith(f"Dynamixel turret on {link.device}: no servo answered at 57600 baud")
    assert "\n" not in message


def test_a_missing_device_raises_device_error() -> None:
    with pytest.raises(DeviceError, match="cannot open the port"):
        DynamixelTurret("/nonexistent/ttyDXL")


# -- motion ---------------------------------------------------------------------------


def test_commands_converge_at_the_preset_rate(rig: Rig) -> None:
    # The profile velocity is the preset's 180°/s rounded to 0.229 rpm units.
    w = units_to_rate(rate_to_units(WIDOWX.pan.rate))
    assert w == pytest.approx(WIDOWX.pan.rate, rel=1e-3)
    _command(rig, TurretCommand(0.0, math.pi / 2, -1.0))
    rig.clock.t = 0.25
    now = rig.turret.state()
    assert now.stamp == 0.25
    # q(t) = ω t until the goal, read to the nearest tick
    assert now.pan == pytest.approx(w * 0.25, abs=TICK)
    assert now.tilt == pytest.approx(-w * 0.25, abs=TICK)
    assert now.pan_rate == pytest.approx(w, rel=1e-3)
    assert now.tilt_rate == pytest.approx(-w, rel=1e-3)
    rig.clock.t = 0.6  # π/2 at ω ≈ π rad/s takes 0.5 s, 1 rad 0.32 s
    now = rig.turret.state()
    assert now.pan == math.pi / 2
    assert now.tilt == ticks_to_rad(rad_to_ticks(-1.0))
    assert (now.pan_rate, now.tilt_rate) == (0.0, 0.0)


def test_a_rate_command_aims_one_horizon_ahead(rig: Rig) -> None:
    _command(rig, TurretCommand(0.0, 1.0, -2.0, mode="velocity"))
    # q* = q + ω T with q = 0 and T = 0.1 s
    assert rig.bus.servo(1).goals[-1] == rad_to_ticks(0.1)
    assert rig.bus.servo(2).goals[-1] == rad_to_ticks(-0.2)


def test_a_non_finite_goal_keeps_the_axis_goal(rig: Rig) -> None:
    _command(rig, TurretCommand(0.0, 0.3, 0.2))
    _command(rig, TurretCommand(0.0, math.nan, -0.2))
    assert rig.bus.servo(1).goals[-1] == rad_to_ticks(0.3)
    assert rig.bus.servo(2).goals[-1] == rad_to_ticks(-0.2)


@settings(max_examples=60)
@given(
    pan=st.floats(-1e3, 1e3) | st.sampled_from([math.inf, -math.inf]),
    tilt=st.floats(-1e3, 1e3) | st.sampled_from([math.inf, -math.inf]),
    mode=st.sampled_from(["position", "velocity"]),
)
def test_the_turret_never_leaves_its_limits(
    shared_rig: Rig, pan: float, tilt: float, mode: str
) -> None:
    rig = shared_rig
    _command(rig, TurretCommand(rig.clock.t, pan, tilt, mode=mode))  # type: ignore[arg-type]
    for ident, axis in ((1, WIDOWX.pan), (2, WIDOWX.tilt)):
        goal = rig.bus.servo(ident).goals[-1]
        assert axis.lower <= ticks_to_rad(goal) <= axis.upper
    rig.clock.t += 0.2  # part way, then all the way
    mid = rig.turret.state()
    rig.clock.t += 5.0
    end = rig.turret.state()
    for now in (mid, end):
        assert WIDOWX.pan.lower <= now.pan <= WIDOWX.pan.upper
        assert WIDOWX.tilt.lower <= now.tilt <= WIDOWX.tilt.upper


# -- failures and closing ---------------------------------------------------------------


def test_an_unplugged_servo_raises_device_error_within_the_timeout(rig: Rig) -> None:
    """The sync read and two pings (naming the silent servo), each waiting out one
    time-out of the SDK's (2 × 16 ms + 2 ms + transfer), and no more."""
    rig.bus.set_online(2, False)
    heard = _heard(rig.bus)
    with pytest.raises(DeviceError) as info:
        rig.turret.state()
    assert heard == [(BROADCAST_ID, Inst.SYNC_READ, 1_000_000)] + [
        (i, Inst.PING, 1_000_000) for i in (1, 2)
    ]
    assert "servo ID 2 (tilt)" in str(info.value)
    assert rig.link.device in str(info.value)


def test_a_closed_emulator_raises_device_error_within_the_timeout(rig: Rig) -> None:
    """A line whose other end is gone fails at once: the error is the line's, not the
    SDK's time-out (no status packet), and no read waited for an answer."""
    rig.link.close()
    looks = _looks(rig.turret)
    for call in (rig.turret.state, lambda: rig.turret.command(TurretCommand(0.0, 0.1, 0.1))):
        with pytest.raises(DeviceError, match=r"servo IDs? [12]") as info:
            call()
        assert "no status packet" not in str(info.value)
    assert len(looks) <= 1
    with pytest.raises(DeviceError):
        rig.turret.close()  # cannot hold, but the port is closed all the same
    rig.turret.close()  # and closing again does nothing
    with pytest.raises(DeviceError, match="port is closed"):
        rig.turret.state()


def test_close_holds_the_present_position(rig: Rig) -> None:
    _command(rig, TurretCommand(0.0, math.pi / 2, 0.0))
    rig.clock.t = 0.25
    here = rig.bus.value(1, ADDR.PRESENT_POSITION)
    assert 2048 < here < 3072  # under way
    rig.turret.close()
    _applied(rig, 2)
    assert rig.bus.servo(1).goals[-1] == here
    rig.clock.t = 2.0
    assert rig.bus.value(1, ADDR.PRESENT_POSITION) == here
    assert rig.bus.value(1, ADDR.TORQUE_ENABLE) == 1


# -- the poller and the serial line -----------------------------------------------------


@pytest.mark.parametrize(
    ("query", "poll_hz"), [("", 100.0), ("?poll_hz=0", 0.0), ("?baud=57600&poll_hz=12.5", 12.5)]
)
def test_uri_poll_rate(query: str, poll_hz: float) -> None:
    assert parse_dynamixel_uri(f"dynamixel:///dev/ttyDXL{query}").poll_hz == poll_hz


@pytest.mark.parametrize(
    ("query", "problem"),
    [
        ("poll_hz=fast", "poll_hz='fast' is not a number"),
        ("poll_hz=0.5", "poll_hz 0.5 is neither 0"),
        ("poll_hz=2000", "in 1–1000 Hz"),
        ("poll_hz=nan", "poll_hz nan"),
        ("poll_hz=-1", "poll_hz -1"),
    ],
)
def test_bad_poll_rates_are_config_errors(query: str, problem: str) -> None:
    with pytest.raises(ConfigError) as info:
        parse_dynamixel_uri(f"dynamixel:///dev/ttyDXL?{query}")
    assert problem in str(info.value)


@contextlib.contextmanager
def _polled(poll_hz: float) -> Iterator[tuple[ServoBus, DynamixelTurret]]:
    """The emulated servos and a turret on the host's clock, polled at ``poll_hz``."""
    bus = turret_bus(1, 2)
    with PtyServoLink(bus, lifetime=60.0) as link:
        turret = DynamixelTurret.from_uri(f"dynamixel://{link.device}?poll_hz={poll_hz:g}")
        try:
            yield bus, turret
        finally:
            with contextlib.suppress(DeviceError):
                turret.close()


def test_the_poller_reads_while_goals_are_written() -> None:
    """Goals every 5 ms from this thread while the poller reads at 100 Hz: the port's
    lock keeps the two apart, so every goal arrives, no read is missed, and the
    readings follow the turret."""
    with _polled(100.0) as (bus, turret):
        first = turret.readings(time.monotonic(), timeout_s=1.0)  # starts the poller
        sent = 0
        start = time.monotonic()
        while time.monotonic() - start < 0.5:
            turret.command(TurretCommand(0.0, 0.4 if sent % 2 else 0.2, 0.0))
            sent += 1
            time.sleep(0.005)
        turret.command(TurretCommand(0.0, 0.6, -0.3))
        time.sleep(0.4)  # 0.4 rad at the preset's 180°/s: 0.13 s
        got = first + turret.readings(time.monotonic(), timeout_s=1.0)
        assert turret.poller is not None
        assert turret.poller.misses == 0
        deadline = time.monotonic() + 1.0
        while len(bus.servo(1).goals) < sent + 1 and time.monotonic() < deadline:
            time.sleep(0.005)
        assert len(bus.servo(1).goals) == sent + 1
    # 0.9 s at 100 Hz: 90 reads due (a loaded machine delays some)
    assert len(got) >= 50
    stamps = [s.stamp for s in got]
    assert all(b > a for a, b in itertools.pairwise(stamps))
    assert got[-1].pan == ticks_to_rad(rad_to_ticks(0.6))
    assert got[-1].tilt == ticks_to_rad(rad_to_ticks(-0.3))
    assert not turret.poller.running  # closing stopped it


def _read_until_it_fails(turret: DynamixelTurret) -> None:
    """Take fresh readings every 10 ms (at most 100 times)."""
    for _ in range(100):
        turret.readings(time.monotonic(), timeout_s=1.0)
        time.sleep(0.01)


def test_a_silent_servo_ends_the_polling_with_its_id() -> None:
    """Three sync reads in a row without an answer (each the SDK's 34 ms time-out, and
    the pings that name the servo) end the polling: readings raises the poller's
    error naming servo 2, not its own time-out's (no present position read for 1 s)."""
    with _polled(100.0) as (bus, turret):
        turret.readings(time.monotonic(), timeout_s=1.0)
        bus.set_online(2, False)
        with pytest.raises(DeviceError) as info:
            _read_until_it_fails(turret)
        assert "servo ID 2 (tilt)" in str(info.value)
        assert "sync read of present position" in str(info.value)
        assert turret.poller is not None
        assert turret.reads_missed >= FAIL_AFTER
        assert turret.poller._thread is not None
        turret.poller._thread.join(timeout=1.0)
        assert not turret.poller.running


def test_without_a_poller_readings_reads_there_and_then() -> None:
    with _polled(0.0) as (_, turret):
        assert turret.poller is None
        before = time.monotonic()
        (state,) = turret.readings(before + 10.0)  # no staleness to wait for
        assert before <= state.stamp <= time.monotonic()


def test_a_read_waits_for_its_answer_without_spinning(rig: Rig) -> None:
    """A sync read that gets no answer waits out the SDK's time-out (2 × 16 ms + 2 ms
    per packet) in select, not in a busy loop: each look at the silent line waits
    READ_WAIT_S, so the looks are at most the time-outs over READ_WAIT_S (measured:
    63 for 68 ms; the SDK's own loop looks some 13,000 times in them)."""
    rig.bus.set_online(1, False)
    rig.bus.set_online(2, False)
    looks = _looks(rig.turret)
    with pytest.raises(DeviceError, match="There is no status packet"):  # the SDK's time-out
        rig.turret.state()
    timeouts_ms = dict(looks)  # one time-out per packet waited for: the sync read, a ping
    assert len(timeouts_ms) == 2
    assert min(timeouts_ms.values()) >= 34.0  # 2 × 16 ms + 2 ms, and the packet's bytes
    assert len(looks) <= 2 * sum(timeouts_ms.values()) / (1000.0 * READ_WAIT_S)


def test_from_a_frames_readings_to_its_command_the_line_is_the_frames() -> None:
    """After readings the poller starts no read until the next command (HOLD_S at
    most), so the command does not wait behind one."""
    with _polled(100.0) as (_, turret):
        turret.readings(time.monotonic(), timeout_s=1.0)
        assert turret.poller is not None
        time.sleep(0.005)  # a read under way finishes
        reads = turret.poller.reads
        time.sleep(0.03)  # three reads would have been due
        assert turret.poller.reads == reads
        turret.command(TurretCommand(0.0, 0.1, 0.0))
        time.sleep(0.05)
        assert turret.poller.reads >= reads + 2
