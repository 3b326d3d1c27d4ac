"""The commands to a pan-tilt unit and its measured state."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

__all__ = ["TurretCommand", "TurretState"]


@dataclass(frozen=True, slots=True)
class TurretCommand:
    """A command to the pan-tilt unit, issued at ``stamp`` [s].

    mode "position": goal angles [rad]; mode "velocity": rates [rad/s].
    """

    stamp: float
    pan: float
    tilt: float
    mode: Literal["position", "velocity"] = "position"


@dataclass(frozen=True, slots=True)
class TurretState:
    """Measured turret joint state at ``stamp`` [s]: angles [rad], rates [rad/s]."""

    stamp: float
    pan: float
    tilt: float
    pan_rate: float = 0.0
    tilt_rate: float = 0.0
