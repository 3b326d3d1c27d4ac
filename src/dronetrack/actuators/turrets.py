"""The turrets a live run drives, by URI, and the guard on their limits.

``--turret`` takes ``dynamixel://DEVICE?baud=…&pan=…&tilt=…`` (``actuators.dynamixel.turret``),
``ros2:///NAMESPACE`` (``actuators.ros2_turret``), ``ptu://DEVICE?baud=…`` or
``ptu://HOST:PORT`` (a FLIR pan-tilt unit, ``actuators.ptu.turret``) or ``none``: a fixed
sensor, whose pose is the mount's at pan = tilt = 0; its commands go nowhere.

Whatever the tracker or controller says, a command reaches the turret only through
``LimitGuard``: goal angles are clamped into the configured joint limits,

    q* = min(max(q, q_lo), q_hi)

and rates into ±ω_max of each axis; a non-finite value is passed as NaN, which the
drivers take as "keep this axis's goal".  The Dynamixel driver clamps to the same
limits again (written into the servos as their position limits), so the guard is
the first of three; the PTU driver clamps to them and to the unit's own limits.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from typing import Protocol

from dronetrack.config.rig import TurretSpec
from dronetrack.errors import ConfigError
from dronetrack.seams import Actuator
from dronetrack.types import TurretCommand, TurretState

__all__ = [
    "NONE_URI",
    "FixedSensor",
    "LimitGuard",
    "LiveTurret",
    "check_turret_uri",
    "clamp_command",
    "open_turret",
]

NONE_URI = "none"


class LiveTurret(Actuator, Protocol):
    """An actuator that holds its position and lets go of its device on ``close``."""

    def close(self) -> None: ...


class FixedSensor:
    """The ``none`` turret: no joints; commands are counted and go nowhere."""

    name = "no turret (fixed sensor)"

    def __init__(self) -> None:
        self.commands = 0

    def command(self, command: TurretCommand) -> None:
        self.commands += 1

    def state(self) -> TurretState | None:
        return None

    def close(self) -> None:
        pass


def _clamp(x: float, lo: float, hi: float) -> float:
    return min(max(x, lo), hi) if math.isfinite(x) else math.nan


def clamp_command(command: TurretCommand, spec: TurretSpec) -> TurretCommand:
    """``command`` inside ``spec``'s limits: goals into [lower, upper], rates into
    [−rate, rate] of each axis; non-finite values become NaN."""
    if command.mode == "position":
        pan = _clamp(command.pan, spec.pan.lower, spec.pan.upper)
        tilt = _clamp(command.tilt, spec.tilt.lower, spec.tilt.upper)
    elif command.mode == "velocity":
        pan = _clamp(command.pan, -spec.pan.rate, spec.pan.rate)
        tilt = _clamp(command.tilt, -spec.tilt.rate, spec.tilt.rate)
    else:
        raise ConfigError(f"turret command mode must be position or velocity, got {command.mode!r}")
    return TurretCommand(command.stamp, pan, tilt, command.mode)


class LimitGuard:
    """``turret`` behind ``clamp_command``; counts the commands it had to change."""

    def __init__(self, turret: LiveTurret, spec: TurretSpec) -> None:
        self.turret = turret
        self.spec = spec
        self.clamped = 0

    @property
    def name(self) -> str:
        return str(getattr(self.turret, "name", type(self.turret).__name__))

    def command(self, command: TurretCommand) -> None:
        safe = clamp_command(command, self.spec)
        if (safe.pan, safe.tilt) != (command.pan, command.tilt):
            self.clamped += 1
        self.turret.command(safe)

    def state(self) -> TurretState | None:
        return self.turret.state()

    def readings(self, until: float = -math.inf, timeout_s: float = 1.0) -> list[TurretState]:
        """The turret's new measured states (``DynamixelTurret.readings``,
        ``PtuTurret.readings``); a turret
        without them: its ``state`` now (none for a fixed sensor)."""
        read = getattr(self.turret, "readings", None)
        if read is not None:
            return list(read(until, timeout_s))
        state = self.turret.state()
        return [] if state is None else [state]

    @property
    def reads_missed(self) -> int:
        """The turret's polled reads that got no answer (0 if it keeps no count)."""
        return int(getattr(self.turret, "reads_missed", 0))

    def close(self) -> None:
        self.turret.close()


def check_turret_uri(uri: str) -> None:
    """ConfigError with one line unless ``uri`` is ``none`` or a valid dynamixel:// or
    ptu:// URI."""
    if uri.strip().lower() == NONE_URI:
        return
    if uri.startswith("dynamixel://"):
        from dronetrack.actuators.dynamixel.turret import parse_dynamixel_uri

        parse_dynamixel_uri(uri)
        return
    if uri.startswith("ros2://"):
        from dronetrack.actuators.ros2_turret import parse_ros2_turret_uri

        parse_ros2_turret_uri(uri)
        return
    if uri.startswith("ptu://"):
        from dronetrack.actuators.ptu.uri import parse_ptu_uri

        parse_ptu_uri(uri)
        return
    raise ConfigError(
        f"--turret {uri!r}: give dynamixel://DEVICE?baud=1000000&pan=1&tilt=2, "
        "ptu://DEVICE?baud=9600, ptu://HOST:PORT, ros2:///NAMESPACE or none"
    )


def open_turret(
    uri: str,
    spec: TurretSpec,
    clock: Callable[[], float] = time.monotonic,
    ros_domain_id: int | None = None,
) -> LimitGuard:
    """The turret ``uri`` names, opened and behind its limit guard; ConfigError for a
    URI that names none, DeviceError if it does not answer.  ``ros_domain_id``: the
    ROS 2 domain of a ``ros2://`` turret."""
    check_turret_uri(uri)
    if uri.strip().lower() == NONE_URI:
        return LimitGuard(FixedSensor(), spec)
    if uri.startswith("ros2://"):
        from dronetrack.actuators.ros2_turret import Ros2Turret

        return LimitGuard(Ros2Turret(uri, ros_domain_id, clock=clock), spec)
    if uri.startswith("ptu://"):
        from dronetrack.actuators.ptu.turret import PtuTurret

        return LimitGuard(PtuTurret.from_uri(uri, turret=spec, clock=clock), spec)
    from dronetrack.actuators.dynamixel.turret import DynamixelTurret

    return LimitGuard(DynamixelTurret.from_uri(uri, turret=spec, clock=clock), spec)
