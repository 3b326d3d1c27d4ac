"""A turret command as the goal angles a position-controlled turret is sent.

A position command is its own goal.  A velocity command (pan and tilt rates ω [rad/s])
becomes the position one horizon T ahead of the measured one:

    q* = q + ω T

with q the newest reading a poller holds when there is one (no read in the caller's
path), else one read now.
"""

from __future__ import annotations

from collections.abc import Callable

from dronetrack.errors import ConfigError
from dronetrack.types import TurretCommand, TurretState

__all__ = ["goal_angles"]


def goal_angles(
    command: TurretCommand,
    newest: TurretState | None,
    read: Callable[[], TurretState],
    horizon_s: float,
) -> tuple[float, float]:
    """(pan, tilt) goal [rad] of ``command``; ``newest`` is the newest polled reading
    (None: ``read()`` is called for a velocity command).  ConfigError for a mode that
    is neither position nor velocity."""
    if command.mode == "position":
        return command.pan, command.tilt
    if command.mode == "velocity":
        now = newest if newest is not None else read()
        return now.pan + command.pan * horizon_s, now.tilt + command.tilt * horizon_s
    raise ConfigError(f"turret command mode must be position or velocity, got {command.mode!r}")
