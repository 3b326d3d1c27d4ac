"""The ground's height under the field: the lowest return seen in each cell of a
horizontal grid, learnt from every frame.

The crop box's floor keeps the ground out of the foreground, so the height of an
object above the ground, which tells a drone in the air from a car, a person or a
bush standing on it, needs the ground from the returns the crop drops.  Each frame
a sample of its world points updates, per cell of ``cell_m`` (5 m),

    g(i, j) ← min(g(i, j), min z over the points in the cell)

and the ground under a point is the lowest g over its cell and the 8 around it (a
cell under a tree or a drone may hold no ground return of its own).  Cells never
seen give NaN: no height is known there.  A return below the ground does not occur
in a LiDAR's first returns (the random false alarms lie in front of the surface a
pulse reaches, so above it).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.preprocess.crop import finite_mask

__all__ = ["GroundGrid", "cell_keys"]

_BITS = 31
_OFFSET = 1 << (_BITS - 1)
IntArray = NDArray[np.int64]
_DX, _DY = (a.ravel() for a in np.meshgrid([-1, 0, 1], [-1, 0, 1], indexing="ij"))


def cell_keys(ix: IntArray, iy: IntArray) -> IntArray:
    """One int64 key per horizontal cell (i, j), ordered by i then j."""
    return ((ix + _OFFSET) << _BITS) | (iy + _OFFSET)


class GroundGrid:
    """The lowest return per horizontal cell (see the module docstring).  ``stride``:
    every stride-th point of a frame is taken (a frame's 24,000 returns hold the
    same ground many times over)."""

    def __init__(self, cell_m: float = 5.0, stride: int = 8) -> None:
        if not cell_m > 0 or stride < 1:
            raise InputError(f"ground grid: need cell_m > 0 and stride ≥ 1, got {cell_m}, {stride}")
        self.cell_m = float(cell_m)
        self.stride = int(stride)
        self.keys = np.empty(0, dtype=np.int64)  # sorted
        self.low = np.empty(0)  # g per key [m]

    def __len__(self) -> int:
        return len(self.keys)

    def _index(self, xy: FloatArray) -> tuple[IntArray, IntArray]:
        idx = np.floor(xy / self.cell_m).astype(np.int64)
        if len(idx) and np.abs(idx).max() >= _OFFSET:
            raise InputError("ground grid: a point lies beyond the grid's reach")
        return idx[:, 0], idx[:, 1]

    def insert(self, points: FloatArray, stride: int | None = None) -> None:
        """Take a frame's world points (N, 3): g ← min(g, z) per cell, over every
        ``stride``-th point (default: the grid's)."""
        pts = points[:: self.stride if stride is None else stride]
        pts = pts[finite_mask(pts)]
        if len(pts) == 0:
            return
        keys = cell_keys(*self._index(pts[:, :2]))
        order = np.argsort(keys, kind="stable")
        keys, z = keys[order], pts[order, 2]
        starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
        new_keys, new_low = keys[starts], np.minimum.reduceat(z, starts)
        at = np.searchsorted(self.keys, new_keys)
        known = at < len(self.keys)
        known[known] = self.keys[at[known]] == new_keys[known]
        self.low[at[known]] = np.minimum(self.low[at[known]], new_low[known])
        fresh = ~known
        if fresh.any():
            self.keys = np.insert(self.keys, at[fresh], new_keys[fresh])
            self.low = np.insert(self.low, at[fresh], new_low[fresh])

    def height(self, xy: FloatArray) -> FloatArray:
        """The ground's height under each point (K, 2) [m]: the lowest g over its cell and
        the 8 around it; NaN where none of them was seen."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        if len(xy) == 0 or len(self.keys) == 0:
            return np.full(len(xy), np.nan)
        ix, iy = self._index(xy)
        # the 3 × 3 cells around each point, (K, 9), looked up at once
        keys = cell_keys(ix[:, None] + _DX, iy[:, None] + _DY)
        at = np.minimum(np.searchsorted(self.keys, keys), len(self.keys) - 1)
        low = np.where(self.keys[at] == keys, self.low[at], np.inf)
        out: FloatArray = low.min(axis=1)
        out[~np.isfinite(out)] = np.nan
        return out
