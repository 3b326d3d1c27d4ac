"""Primitives: the simple shapes scenes and targets are built from, as parallel arrays.

Every shape has a kind, a centre, an orientation ``world_R_local`` and three
half-extents in its local frame.

- BOX: |x| ≤ hx, |y| ≤ hy, |z| ≤ hz.
- ELLIPSOID: (x/hx)² + (y/hy)² + (z/hz)² ≤ 1.
- CYLINDER: (x/hx)² + (y/hy)² ≤ 1 and |z| ≤ hz (capped, axis along local z).
- PLANE: the horizontal plane z = centre z (the ground); extents unused.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray

__all__ = ["BOX", "CYLINDER", "ELLIPSOID", "PLANE", "Primitives"]

BOX = 0
ELLIPSOID = 1
CYLINDER = 2
PLANE = 3


@dataclass(frozen=True, slots=True)
class Primitives:
    """A set of primitives as parallel arrays (structure of arrays)."""

    kind: NDArray[np.int64]  # (P,)
    center: FloatArray  # (P, 3) [m]
    rotation: FloatArray  # (P, 3, 3) world_R_local
    half: FloatArray  # (P, 3) half-extents [m]
    reflectivity: FloatArray  # (P,) diffuse reflectivity at 905 nm, 0..1

    def __post_init__(self) -> None:
        p = len(self.kind)
        shapes = {
            "center": (self.center.shape, (p, 3)),
            "rotation": (self.rotation.shape, (p, 3, 3)),
            "half": (self.half.shape, (p, 3)),
            "reflectivity": (self.reflectivity.shape, (p,)),
        }
        for name, (got, want) in shapes.items():
            if got != want:
                raise InputError(f"primitive {name} must have shape {want}, got {got}")
        if p and (np.any(self.half[self.kind != PLANE] <= 0)):
            raise InputError("primitive half-extents must be positive")

    def __len__(self) -> int:
        return len(self.kind)

    @property
    def bound_radius(self) -> FloatArray:
        """Radius of a sphere around each primitive's centre that contains it."""
        h = self.half
        r = np.linalg.norm(h, axis=1)
        r = np.where(self.kind == ELLIPSOID, h.max(axis=1), r)
        r = np.where(self.kind == CYLINDER, np.hypot(h[:, :2].max(axis=1), h[:, 2]), r)
        return np.where(self.kind == PLANE, np.inf, r)

    @staticmethod
    def concat(parts: list[Primitives]) -> Primitives:
        """Join several primitive sets into one."""
        if not parts:
            return Primitives.empty()
        return Primitives(
            kind=np.concatenate([p.kind for p in parts]),
            center=np.concatenate([p.center for p in parts]),
            rotation=np.concatenate([p.rotation for p in parts]),
            half=np.concatenate([p.half for p in parts]),
            reflectivity=np.concatenate([p.reflectivity for p in parts]),
        )

    @staticmethod
    def empty() -> Primitives:
        return Primitives(
            kind=np.empty(0, np.int64),
            center=np.empty((0, 3)),
            rotation=np.empty((0, 3, 3)),
            half=np.empty((0, 3)),
            reflectivity=np.empty(0),
        )

    def subset(self, index: NDArray[np.int64]) -> Primitives:
        """The primitives at ``index``."""
        return Primitives(
            kind=self.kind[index],
            center=self.center[index],
            rotation=self.rotation[index],
            half=self.half[index],
            reflectivity=self.reflectivity[index],
        )
