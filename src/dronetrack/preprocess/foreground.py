"""Frame to foreground points in one pass: world transform, crop, background subtraction.

The same result as ``Frame.world_points`` → ``finite_mask`` → ``box_mask`` →
``VoxelBackground.is_background``: one vectorised transform, then one pass that
classifies each point, so a 24,000-point frame costs well under a millisecond.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from dronetrack.geometry.transforms import FloatArray, transform_at_times
from dronetrack.preprocess.background import VoxelBackground
from dronetrack.preprocess.voxel import occupied
from dronetrack.types import Frame

__all__ = ["Foreground", "extract_foreground"]


@dataclass(frozen=True, slots=True)
class Foreground:
    """The points of a frame that may belong to a target, and what was dropped."""

    points: FloatArray  # (M, 3) world frame [m]
    index: NDArray[np.int64]  # (M,) rows of the frame they came from
    n_nonfinite: int
    n_outside: int  # outside the crop box
    n_background: int
    world: FloatArray = field(default_factory=lambda: np.empty((0, 3)))  # (N, 3) every point


KEEP, NONFINITE, OUTSIDE, BACKGROUND = 0, 1, 2, 3


def extract_foreground(
    frame: Frame, lo: ArrayLike, hi: ArrayLike, background: VoxelBackground | None = None
) -> Foreground:
    """World points of ``frame`` inside the box [lo, hi) and not in the background."""
    world = transform_at_times(frame.pose_t, frame.poses, frame.t, frame.points)
    if background is not None and background.ready:
        cells = background.cells
        grid, origin, table, shift = cells.grid, cells.origin, cells.table, cells.shift
        cell = background.cell_size
    else:
        grid, origin = np.zeros((0, 0, 0), dtype=np.uint8), np.zeros(3, dtype=np.int64)
        table, shift, cell = np.full(1, -1, dtype=np.int64), 63, 0.0
    verdict = _classify(
        world,
        np.asarray(lo, dtype=np.float64),
        np.asarray(hi, dtype=np.float64),
        grid,
        origin,
        table,
        shift,
        cell,
    )
    if background is not None and background.ready and background.near_m > 0:
        # near the sensor, what the coarse cells call background is looked up in finer ones
        sensor = frame.poses[-1, :3, 3]
        bg = verdict == BACKGROUND
        verdict[bg & ~background.near(world, bg, sensor)] = KEEP
    counts = np.bincount(verdict, minlength=4)
    index = np.flatnonzero(verdict == KEEP)
    return Foreground(
        world[index],
        index,
        int(counts[NONFINITE]),
        int(counts[OUTSIDE]),
        int(counts[BACKGROUND]),
        world,
    )


@nb.njit(cache=True)
def _classify(
    W: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    grid: NDArray[np.uint8],
    origin: NDArray[np.int64],
    table: NDArray[np.int64],
    shift: int,
    cell: float,
) -> NDArray[np.uint8]:
    """Per point: KEEP, NONFINITE, OUTSIDE the box [lo, hi), or in the BACKGROUND.

    The dense-grid and the hash lookups run in separate loops: a loop that holds
    both compiles to much slower code.  Cell index i = ⌊x / cell⌋, divided as in
    VoxelBackground.is_background so a point on a cell boundary gets the same cell.
    """
    n = W.shape[0]
    out = np.empty(n, dtype=np.uint8)
    use_grid = grid.shape[0] > 0
    nx, ny, nz = grid.shape
    for j in range(n):
        x, y, z = W[j, 0], W[j, 1], W[j, 2]
        if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
            out[j] = NONFINITE
        elif not (lo[0] <= x < hi[0] and lo[1] <= y < hi[1] and lo[2] <= z < hi[2]):
            out[j] = OUTSIDE
        else:
            out[j] = KEEP
    if cell <= 0.0:  # no background model
        return out
    if use_grid:
        for j in range(n):
            if out[j] == KEEP:
                gx = int(np.floor(W[j, 0] / cell)) - origin[0]
                gy = int(np.floor(W[j, 1] / cell)) - origin[1]
                gz = int(np.floor(W[j, 2] / cell)) - origin[2]
                if 0 <= gx < nx and 0 <= gy < ny and 0 <= gz < nz and grid[gx, gy, gz] != 0:
                    out[j] = BACKGROUND
    else:
        for j in range(n):
            if out[j] == KEEP:
                ix = int(np.floor(W[j, 0] / cell))
                iy = int(np.floor(W[j, 1] / cell))
                iz = int(np.floor(W[j, 2] / cell))
                if occupied(ix, iy, iz, grid, origin, table, shift):
                    out[j] = BACKGROUND
    return out
