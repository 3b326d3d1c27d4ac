"""The background model: a voxel occupancy map of the static scene, and its subtraction.

Seed 000 builds an OctoMap of the scene while the turret scans, inflates it by
one voxel, and drops every new point that falls in an occupied cell, looked up
two octree levels above the leaves (reference: 1 m voxels looked up in 4 m
cells outdoors, 0.1 m in 0.4 m indoors).  Here the map is the set of voxel keys
hit at least ``min_hits`` times, dilated by ``inflate`` voxels over the
26-neighbourhood, then coarsened by ``lookup_depth`` levels.  Free space is not
modelled: OctoMap's ray clearing matters for moving scenes, and the seed assumes
a static one.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.preprocess.crop import finite_mask
from dronetrack.preprocess.voxel import (
    KeySet,
    coarsen_keys,
    dilate_keys,
    unique_keys,
    voxel_keys,
)

__all__ = ["VoxelBackground"]


class VoxelBackground:
    """Accumulates scan points, then answers "is this point background?"."""

    def __init__(
        self, resolution: float, inflate: int = 1, lookup_depth: int = 0, min_hits: int = 1
    ) -> None:
        if resolution <= 0 or inflate < 0 or lookup_depth < 0 or min_hits < 1:
            raise InputError("background: resolution > 0, inflate ≥ 0, depth ≥ 0, min_hits ≥ 1")
        self.resolution = float(resolution)
        self.inflate = int(inflate)
        self.lookup_depth = int(lookup_depth)
        self.min_hits = int(min_hits)
        self._chunks: list[NDArray[np.int64]] = []
        self._cells: KeySet | None = None

    @property
    def cell_size(self) -> float:
        """Edge of the lookup cells [m]: resolution · 2^depth."""
        return self.resolution * float(2**self.lookup_depth)

    @property
    def ready(self) -> bool:
        return self._cells is not None

    @property
    def cells(self) -> KeySet:
        if self._cells is None:
            raise InputError("the background model has not been built yet")
        return self._cells

    def insert(self, points: FloatArray) -> None:
        """Add world points (N, 3) seen while scanning."""
        if self._cells is not None:
            raise InputError("the background model is already built")
        pts = points[finite_mask(points)]
        if len(pts):
            self._chunks.append(voxel_keys(pts, self.resolution))

    def build(self) -> None:
        """Turn the accumulated points into the lookup map."""
        keys = np.concatenate(self._chunks) if self._chunks else np.empty(0, dtype=np.int64)
        self._chunks = []
        if self.min_hits > 1 and len(keys):
            keys = np.sort(keys)
            starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
            counts = np.diff(np.r_[starts, len(keys)])
            keys = keys[starts[counts >= self.min_hits]]
        occupied = dilate_keys(unique_keys(keys), self.inflate)
        self._cells = KeySet.of(coarsen_keys(occupied, self.lookup_depth))

    @classmethod
    def from_cells(
        cls,
        cells: NDArray[np.int64],
        resolution: float,
        inflate: int,
        lookup_depth: int,
        min_hits: int = 1,
    ) -> VoxelBackground:
        """A built model from its lookup-cell keys (as saved)."""
        model = cls(resolution, inflate, lookup_depth, min_hits)
        model._cells = KeySet.of(np.asarray(cells, dtype=np.int64))
        return model

    def is_background(self, points: FloatArray) -> NDArray[np.bool_]:
        """Whether each world point (N, 3) falls in an occupied cell (non-finite: False)."""
        out = np.zeros(len(points), dtype=bool)
        ok = finite_mask(points)
        idx = np.floor(points[ok] / self.cell_size).astype(np.int64)
        out[ok] = self.cells.contains_index(idx)
        return out

    def __len__(self) -> int:
        """Occupied lookup cells (0 before ``build``)."""
        return len(self._cells) if self._cells is not None else 0
