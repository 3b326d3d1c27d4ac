"""The turrets a live run opens: ``none``, the limit guard every command passes, and
``info``'s servo probe, against the emulated XM430s through the official SDK."""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import replace

import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.actuators.dynamixel.turret import axis_tick_limits, probe_servos
from dronetrack.actuators.turrets import (
    FixedSensor,
    LimitGuard,
    check_turret_uri,
    clamp_command,
    open_turret,
)
from dronetrack.config.rig import make_turret
from dronetrack.errors import ConfigError, DeviceError
from dronetrack.formats.dynamixel import ADDR
from dronetrack.sim.emulate.servos import PtyServoLink, ServoBus, turret_bus
from dronetrack.types import TurretCommand

WIDOWX = make_turret("widowx")
# A site's narrower limits than the preset's: pan ±90°, tilt −20° to 30°
SITE = replace(
    WIDOWX,
    pan=replace(WIDOWX.pan, lower=math.radians(-90.0), upper=math.radians(90.0)),
    tilt=replace(WIDOWX.tilt, lower=math.radians(-20.0), upper=math.radians(30.0)),
)

angles = st.floats(min_value=-1e9, max_value=1e9) | st.sampled_from([math.inf, -math.inf, math.nan])


@given(angles, angles, st.sampled_from(["position", "velocity"]))
def test_a_guarded_command_is_always_inside_the_limits(pan: float, tilt: float, mode: str) -> None:
    out = clamp_command(TurretCommand(1.0, pan, tilt, mode), SITE)  # type: ignore[arg-type]
    for value, given_value, axis in ((out.pan, pan, SITE.pan), (out.tilt, tilt, SITE.tilt)):
        lo, hi = (axis.lower, axis.upper) if mode == "position" else (-axis.rate, axis.rate)
        if math.isfinite(given_value):
            assert lo <= value <= hi
            if lo <= given_value <= hi:
                assert value == given_value  # inside: untouched
        else:
            assert math.isnan(value)  # the driver keeps that axis's goal
    assert (out.stamp, out.mode) == (1.0, mode)


def test_the_none_turret_is_a_fixed_sensor() -> None:
    guard = open_turret("none", SITE)
    assert isinstance(guard.turret, FixedSensor)
    guard.command(TurretCommand(0.0, 3.0, 3.0))
    assert guard.state() is None
    assert guard.turret.commands == 1
    assert guard.clamped == 1
    guard.close()


@pytest.mark.parametrize(
    ("uri", "problem"),
    [
        ("pantilt://192.168.1.5", "dynamixel://DEVICE"),
        ("ptu://192.168.1.5", "HOST:PORT"),
        ("", "dynamixel://DEVICE"),
        ("dynamixel:///dev/ttyUSB0?baud=1234", "baud 1234"),
    ],
)
def test_a_bad_turret_uri_is_a_one_line_config_error(uri: str, problem: str) -> None:
    with pytest.raises(ConfigError, match=problem) as info:
        check_turret_uri(uri)
    assert "\n" not in str(info.value)


@pytest.fixture
def servos() -> Iterator[tuple[ServoBus, PtyServoLink]]:
    pytest.importorskip("dynamixel_sdk")
    bus = turret_bus(1, 2)
    link = PtyServoLink(bus, lifetime=60.0)
    yield bus, link
    link.close()


def _goals(bus: ServoBus, count: int) -> tuple[int, int]:
    """The servos' goal positions once both have taken ``count`` goals (within 1 s)."""
    deadline = time.monotonic() + 1.0
    while time.monotonic() < deadline:
        with bus.lock:
            if all(len(bus.servo(i).goals) >= count for i in (1, 2)):
                return bus.value(1, ADDR.GOAL_POSITION), bus.value(2, ADDR.GOAL_POSITION)
        time.sleep(0.002)
    raise AssertionError(f"the servos did not take goal number {count}")


def test_the_servos_never_get_a_goal_outside_the_configured_limits(
    servos: tuple[ServoBus, PtyServoLink],
) -> None:
    """The tracker asks for 5 rad of pan and −5 rad of tilt: the servos get the limits'
    own ticks (axis_tick_limits of the site's limits); NaN keeps the goals."""
    bus, link = servos
    guard = open_turret(f"dynamixel://{link.device}", SITE)
    try:
        count = len(bus.servo(1).goals)
        guard.command(TurretCommand(0.0, 5.0, -5.0))
        pan, tilt = _goals(bus, count + 1)
        assert pan == axis_tick_limits(SITE.pan)[1]
        assert tilt == axis_tick_limits(SITE.tilt)[0]
        guard.command(TurretCommand(0.1, math.nan, math.inf))
        assert _goals(bus, count + 2) == (pan, tilt)
        assert guard.clamped == 2
    finally:
        guard.close()


def test_the_probe_reports_each_servo_and_changes_nothing(
    servos: tuple[ServoBus, PtyServoLink],
) -> None:
    bus, link = servos
    reports = probe_servos(f"dynamixel://{link.device}?baud=1000000&pan=1&tilt=2")
    assert [(r.ident, r.role) for r in reports] == [(1, "pan"), (2, "tilt")]
    for r in reports:
        assert (r.model, r.firmware, r.position, r.torque, r.hardware_error) == (
            1020, 48, 2048, False, 0
        )  # fmt: skip
        assert r.angle == 0.0
        assert r.problem is None
    assert bus.value(1, ADDR.TORQUE_ENABLE) == 0


def test_the_probe_names_a_servo_that_does_not_answer(
    servos: tuple[ServoBus, PtyServoLink],
) -> None:
    bus, link = servos
    bus.set_online(2, False)
    reports = probe_servos(f"dynamixel://{link.device}")
    assert reports[0].problem is None
    assert reports[1].role == "tilt"
    assert reports[1].problem is not None
    assert "ping" in reports[1].problem


def test_a_port_that_cannot_open_is_a_device_error() -> None:
    pytest.importorskip("dynamixel_sdk")
    with pytest.raises(DeviceError, match="cannot open"):
        probe_servos("dynamixel:///nonexistent/ttyUSB9")


def test_a_guard_passes_the_state_through() -> None:
    guard = LimitGuard(FixedSensor(), SITE)
    assert guard.state() is None
    assert guard.name == FixedSensor.name
