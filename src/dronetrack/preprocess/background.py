"""The background model: a voxel occupancy map of the static scene, and its subtraction.

Seed 000 builds an OctoMap of the scene while the turret scans, inflates it by
one voxel, and drops every new point that falls in an occupied cell, looked up
two octree levels above the leaves (reference: 1 m voxels looked up in 4 m
cells outdoors, 0.1 m in 0.4 m indoors).  Here the map is the set of voxel keys
hit at least ``min_hits`` times, dilated by ``inflate`` voxels over the
26-neighbourhood, then coarsened by ``lookup_depth`` levels.  With
``min_neighbours`` > 0 a voxel also needs that many of its 26 neighbours hit
during the scan: a real surface returns from neighbouring voxels, while one of the
sensor's random false alarms (about 10⁻⁴ per pulse, a few hundred in a scan) stands
alone in the sky, where it would hide a drone in its whole lookup cell (4 m
outdoors) for as long as it takes to fly through.  Free space is not
modelled: OctoMap's ray clearing matters for moving scenes, and the seed assumes
a static one.

With ``free_object_m`` set, a part of the scan that stands free (a component of
occupied voxels with at least two empty voxels between it and any other: a short
scan's sparse returns leave one-voxel holes in a wall) and is no larger than that
(its bounding box's longest edge) is left out of the map: a drone hovering in view
while the sensor scans (a sensor switched on with the drone up) would otherwise be
background for good.  What is left out is foreground like anything new: the track
layer tracks it, the classes tell a hovering drone from an object on a pole, and the
learning map (``preprocess.learning``) learns what is static.
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
    key_centres,
    neighbour_counts,
    voxel_components,
    voxel_keys,
)

__all__ = ["VoxelBackground", "free_objects", "occupied_voxels"]


def occupied_voxels(
    keys: NDArray[np.int64], min_hits: int, min_neighbours: int
) -> NDArray[np.int64]:
    """The distinct voxels hit at least ``min_hits`` times, of which at least
    ``min_neighbours`` of the 26 neighbours were hit too (``keys``: one per return)."""
    s = np.sort(keys)
    starts = np.flatnonzero(np.r_[True, s[1:] != s[:-1]]) if len(s) else np.empty(0, np.int64)
    hit: NDArray[np.int64] = s[starts]  # every voxel hit at least once, sorted
    counts = np.diff(np.r_[starts, len(s)])
    voxels: NDArray[np.int64] = hit[counts >= min_hits]
    if min_neighbours > 0:
        voxels = voxels[neighbour_counts(voxels, hit) >= min_neighbours]
    return voxels


FREE_GAP = 2  # empty voxels around a free-standing object


def free_objects(voxels: NDArray[np.int64], resolution: float, largest: float) -> NDArray[np.bool_]:
    """(N,) the voxels (sorted, distinct keys of edge ``resolution``) of the components
    with ``FREE_GAP`` empty voxels or more around them and whose bounding box's longest
    edge is at most ``largest`` [m]."""
    if len(voxels) == 0:
        return np.zeros(0, dtype=bool)
    labels = voxel_components(voxels, reach=FREE_GAP + 1)
    centres = key_centres(voxels, resolution)
    k = int(labels.max()) + 1
    lo = np.full((k, 3), np.inf)
    hi = np.full((k, 3), -np.inf)
    np.minimum.at(lo, labels, centres)
    np.maximum.at(hi, labels, centres)
    edge = (hi - lo).max(axis=1) + resolution  # the voxels' extent, end to end
    small: NDArray[np.bool_] = edge[labels] <= largest + 1e-9
    return small


class VoxelBackground:
    """Accumulates scan points, then answers "is this point background?"."""

    def __init__(
        self,
        resolution: float,
        inflate: int = 1,
        lookup_depth: int = 0,
        min_hits: int = 1,
        min_neighbours: int = 0,
        free_object_m: float | None = None,
    ) -> None:
        if free_object_m is not None and not free_object_m > 0:
            raise InputError("background: free_object_m must be positive (or unset)")
        if resolution <= 0 or inflate < 0 or lookup_depth < 0 or min_hits < 1:
            raise InputError("background: resolution > 0, inflate ≥ 0, depth ≥ 0, min_hits ≥ 1")
        if not 0 <= min_neighbours <= 26:
            raise InputError("background: min_neighbours must be 0-26 (of a voxel's 26)")
        self.resolution = float(resolution)
        self.inflate = int(inflate)
        self.lookup_depth = int(lookup_depth)
        self.min_hits = int(min_hits)
        self.min_neighbours = int(min_neighbours)
        self.free_object_m = free_object_m
        self.left_out = 0  # voxels of free-standing small objects left out of the map
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
        voxels = occupied_voxels(keys, self.min_hits, self.min_neighbours)
        if self.free_object_m is not None:
            free = free_objects(voxels, self.resolution, self.free_object_m)
            self.left_out = int(np.count_nonzero(free))
            voxels = voxels[~free]
        grown = dilate_keys(voxels, self.inflate)
        self._cells = KeySet.of(coarsen_keys(grown, self.lookup_depth))

    @classmethod
    def from_cells(
        cls,
        cells: NDArray[np.int64],
        resolution: float,
        inflate: int,
        lookup_depth: int,
        min_hits: int = 1,
        min_neighbours: int = 0,
    ) -> VoxelBackground:
        """A built model from its lookup-cell keys (as saved)."""
        model = cls(resolution, inflate, lookup_depth, min_hits, min_neighbours)
        model._cells = KeySet.of(np.asarray(cells, dtype=np.int64))
        return model

    def is_background(self, points: FloatArray) -> NDArray[np.bool_]:
        """Whether each world point (N, 3) falls in an occupied cell (non-finite: False)."""
        return self.cells.contains_points(points, self.cell_size)

    def __len__(self) -> int:
        """Occupied lookup cells (0 before ``build``)."""
        return len(self._cells) if self._cells is not None else 0
