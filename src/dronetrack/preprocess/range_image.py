"""The background scan as a range image: the nearest return seen in each direction.

The voxel map (``preprocess/background.py``) looks points up in coarse cells (4 m
outdoors) grown by a voxel, so a drone that passes within a few metres of a wall or a
roof edge has its returns dropped with the wall's.  Near a locked target the pipeline
asks a finer question of those points: is the point clearly in front of everything
the scan saw in its direction?  A point is *in front* when

    r < min r_bg(b') − m,   b' over the 3 × 3 bins around its bin b

with r its range from the turret base, r_bg the nearest scan return per bin of
``step`` (0.25°: 0.3 m at 70 m) in azimuth and elevation, and m a margin (the map's
voxel).  A drone skimming the barn's corner is in front of the barn's wall and of the
ground behind it; the wall itself, or anything behind it, is not.  A direction where
the scan saw nothing (the sky) has r_bg = ∞.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.preprocess.crop import finite_mask

__all__ = ["RANGE_STEP_RAD", "RangeImage", "direction_bins", "grid_shape", "neighbourhood_min"]

RANGE_STEP_RAD = float(np.radians(0.25))
IntArray = NDArray[np.int64]


@nb.njit(cache=True)
def grid_shape(step: float) -> tuple[int, int]:
    """Bins in azimuth (a full turn) and in elevation (pole to pole) for ``step`` [rad]."""
    return int(np.ceil(2.0 * np.pi / step)), int(np.ceil(np.pi / step)) + 1


@nb.njit(cache=True)
def direction_bins(
    points: FloatArray, origin: FloatArray, step: float
) -> tuple[IntArray, IntArray, FloatArray]:
    """Per point (N, 3): its azimuth bin i, elevation bin j and range r from ``origin``.

    α = atan2(y, x) ∈ [−π, π],  ε = asin(z / r) ∈ [−π/2, π/2]
    i = ⌊(α + π) / step⌋ mod n_α,  j = min(⌊(ε + π/2) / step⌋, n_ε − 1)
    """
    n_az, n_el = grid_shape(step)
    n = points.shape[0]
    i = np.empty(n, dtype=np.int64)
    j = np.empty(n, dtype=np.int64)
    r = np.empty(n, dtype=np.float64)
    for k in range(n):
        dx = points[k, 0] - origin[0]
        dy = points[k, 1] - origin[1]
        dz = points[k, 2] - origin[2]
        rk = np.sqrt(dx * dx + dy * dy + dz * dz)
        az = np.arctan2(dy, dx)
        el = np.arcsin(min(max(dz / max(rk, 1e-12), -1.0), 1.0))
        i[k] = int(np.floor((az + np.pi) / step)) % n_az
        j[k] = min(int(np.floor((el + 0.5 * np.pi) / step)), n_el - 1)
        r[k] = rk
    return i, j, r


@nb.njit(cache=True)
def _lower(grid: NDArray[np.float32], i: IntArray, j: IntArray, r: FloatArray) -> None:
    """grid[i, j] ← min(grid[i, j], r) for every point (np.minimum.at, in one pass)."""
    for k in range(len(r)):
        if r[k] < grid[i[k], j[k]]:
            grid[i[k], j[k]] = r[k]


def neighbourhood_min(grid: NDArray[np.float32]) -> NDArray[np.float32]:
    """The minimum over each bin's 3 × 3 neighbourhood; azimuth wraps round, elevation
    stops at the poles."""
    padded = np.pad(grid, ((1, 1), (1, 1)), mode="edge")
    padded[0, :] = np.pad(grid[-1], 1, mode="edge")  # azimuth wraps: −π next to π
    padded[-1, :] = np.pad(grid[0], 1, mode="edge")
    n, m = grid.shape
    out = grid.copy()
    for di in range(3):
        for dj in range(3):
            np.minimum(out, padded[di : di + n, dj : dj + m], out=out)
    return out


class RangeImage:
    """Accumulates the scan's world points seen from ``origin``, then answers "is this
    point clearly in front of the background?"."""

    def __init__(self, origin: FloatArray, step: float = RANGE_STEP_RAD) -> None:
        if not step > 0:
            raise InputError("range image: the bin step must be positive")
        self.origin = np.asarray(origin, dtype=np.float64).reshape(3)
        self.step = float(step)
        self._nearest = np.full(grid_shape(self.step), np.inf, dtype=np.float32)
        self._around: NDArray[np.float32] | None = None

    @property
    def ready(self) -> bool:
        return self._around is not None

    def insert(self, points: FloatArray) -> None:
        """Add world points (N, 3) seen while scanning."""
        if self._around is not None:
            raise InputError("the range image is already built")
        pts = points[finite_mask(points)]
        if len(pts):
            i, j, r = direction_bins(pts, self.origin, self.step)
            _lower(self._nearest, i, j, r)  # r_bg(b) = min r over the returns in b

    def build(self) -> None:
        """Fix the image: each bin's nearest return over its 3 × 3 neighbourhood."""
        self._around = neighbourhood_min(self._nearest)

    def in_front(self, points: FloatArray, margin: float) -> NDArray[np.bool_]:
        """(N,) whether each world point is more than ``margin`` [m] nearer than every
        scan return in the bins around its direction (non-finite: False)."""
        if self._around is None:
            raise InputError("the range image has not been built yet")
        out = np.zeros(len(points), dtype=bool)
        ok = finite_mask(points)
        if ok.any():
            i, j, r = direction_bins(points[ok], self.origin, self.step)
            out[ok] = r < self._around[i, j] - margin
        return out
