"""A scan pattern seen through a fixed mounting rotation.

Seed 003 lays its VLP-16 on its side on the PTU-E46: rolled 90° about its forward
x axis, the head's spin sweeps *elevation* in the sensor's x-z plane (the thesis
matches the "LiDAR internal spin angle" with the drone's pitch), and the 16 beams,
±15° apart by 2°, fan out in *azimuth*.  Panning the turret then sweeps that thin
vertical fan across the sky.

``RotatedPattern`` turns every pulse of a pattern by a fixed rotation
``R = mounted_R_base``: directions d → R d and beam origins o → R o, in the
sensor frame the rest of the simulator uses (x forward, y left, z up).  Times and
line indices are unchanged, so the frame still holds the base pattern's pulses.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dronetrack.errors import SensorError
from dronetrack.geometry.transforms import FloatArray, rot_x
from dronetrack.sim.patterns import Pulses, ScanPattern

__all__ = ["RotatedPattern", "side_mount"]


def side_mount(roll: float = 0.5 * math.pi) -> FloatArray:
    """The rotation of a sensor rolled by ``roll`` [rad] about its forward x axis.

    With the default +90° the sensor's up axis (its spin axis) points to the
    right (−y) and its left axis (y) points up, so a VLP-16 azimuth az becomes
    the in-plane elevation atan2(z, x) = az and a laser elevation e becomes an
    azimuth offset −e.
    """
    return rot_x(roll)


@dataclass(frozen=True, slots=True, eq=False)
class RotatedPattern:
    """``base`` fired through the fixed rotation ``rotation`` (3, 3), mounted_R_base."""

    base: ScanPattern
    rotation: FloatArray

    def __post_init__(self) -> None:
        R = np.asarray(self.rotation, dtype=np.float64)
        if R.shape != (3, 3) or not np.all(np.isfinite(R)):
            raise SensorError(f"a mounting rotation must be a finite 3 × 3 matrix, got {R.shape}")
        if not np.allclose(R @ R.T, np.eye(3), atol=1e-9) or np.linalg.det(R) < 0.0:
            raise SensorError("a mounting rotation must be orthonormal with determinant +1")
        object.__setattr__(self, "rotation", R)

    @property
    def n_lines(self) -> int:
        return self.base.n_lines

    def pulses(self, t_start: float, t_end: float) -> Pulses:
        p = self.base.pulses(t_start, t_end)
        R_T = self.rotation.T
        # Row vectors: (R d)ᵀ = dᵀ Rᵀ.  A rotation keeps |origins|, so the bound stands.
        return Pulses(
            t=p.t,
            dirs=np.ascontiguousarray(p.dirs @ R_T),
            line=p.line,
            origins=np.ascontiguousarray(p.origins @ R_T),
            max_origin_offset=p.max_origin_offset,
        )
