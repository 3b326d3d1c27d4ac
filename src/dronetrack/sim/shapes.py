"""Builders for primitives: boxes, cylinders, ellipsoids and the ground plane."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.geometry.transforms import rot_x, rot_y, rot_z
from dronetrack.sim.primitives import BOX, CYLINDER, ELLIPSOID, PLANE, Primitives

__all__ = ["box", "cylinder", "ellipsoid", "ground", "oriented"]


def _one(
    kind: int,
    center: ArrayLike,
    half: ArrayLike,
    reflectivity: float,
    rotation: ArrayLike | None = None,
) -> Primitives:
    R = np.eye(3) if rotation is None else np.asarray(rotation, dtype=np.float64)
    return Primitives(
        kind=np.array([kind], dtype=np.int64),
        center=np.asarray(center, dtype=np.float64).reshape(1, 3),
        rotation=R.reshape(1, 3, 3),
        half=np.asarray(half, dtype=np.float64).reshape(1, 3),
        reflectivity=np.array([reflectivity], dtype=np.float64),
    )


def oriented(yaw: float = 0.0, pitch: float = 0.0, roll: float = 0.0) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll)."""
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def box(
    center: ArrayLike,
    size: ArrayLike,
    reflectivity: float,
    yaw: float = 0.0,
    rotation: ArrayLike | None = None,
) -> Primitives:
    """A box of full size (lx, ly, lz) [m], turned by ``yaw`` about z or by ``rotation``."""
    R = rotation if rotation is not None else oriented(yaw)
    return _one(BOX, center, 0.5 * np.asarray(size, dtype=np.float64), reflectivity, R)


def cylinder(
    center: ArrayLike,
    radius: float,
    length: float,
    reflectivity: float,
    rotation: ArrayLike | None = None,
) -> Primitives:
    """A capped cylinder; its axis is z unless ``rotation`` turns it."""
    return _one(CYLINDER, center, (radius, radius, 0.5 * length), reflectivity, rotation)


def ellipsoid(
    center: ArrayLike, semi_axes: ArrayLike, reflectivity: float, rotation: ArrayLike | None = None
) -> Primitives:
    """An ellipsoid with semi-axes (a, b, c) [m]."""
    return _one(ELLIPSOID, center, semi_axes, reflectivity, rotation)


def ground(reflectivity: float, height: float = 0.0) -> Primitives:
    """The infinite horizontal plane z = height."""
    return _one(PLANE, (0.0, 0.0, height), (0.0, 0.0, 0.0), reflectivity)
