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
outdoors) for as long as it takes to fly through.

Near the sensor the coarse cells are finer: a cell no wider than ``NEAR_ANGLE`` as
seen from the sensor, level ℓ(r) = clamp(⌊log₂(r θ / s)⌋, 0, depth) at range r (s the
voxel size, θ the angle).  The coarse lookup covers the holes a scan leaves, which grow
with range; at 2-3 m from a Mid-360 a 2 m cell (0.5 m voxels two levels up) hid a
drone hovering over whatever the scan saw below it, and there the scan is dense.
θ = 0.25 rad keeps seed 000's cells (4 m outdoors, 0.4 m indoors) from 16 m and 1.6 m
out, nearer than the seed tracks a drone.  A model loaded from a file has its coarse
cells only and looks up in them at every range.  Free space is not
modelled: OctoMap's ray clearing matters for moving scenes, and the seed assumes
a static one.

With ``free_object_m`` set, a part of the scan that stands free (a component of
occupied voxels with at least two empty voxels between it and any other: a short
scan's sparse returns leave one-voxel holes in a wall) and is no larger than that
(its bounding box's longest edge) is left out of the map: a drone hovering in view
while the sensor scans (a sensor switched on with the drone up) would otherwise be
background for good.  So is a small part in the air (``aloft_objects``): nothing
beneath it, nothing beside it at its level, and its bottom a metre or more above the
floor around it, even where it stands within that gap of something lower
(``mid360-static`` seed 6: during the 1 s scan the drone hovered 1 m beside and 0.5 m
above a person standing still; the two made one part 2.5 m long, and the map held the
drone for the rest of the run).  What is left out is foreground like anything new:
the track layer tracks it, the classes tell a hovering drone from an object on a
pole, and the learning map (``preprocess.learning``) learns what is static.  Such a
map is *provisional*: what it holds may have moved away since (the person), so the
classes do not take its cells for a structure beside a track.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.preprocess.crop import finite_mask
from dronetrack.preprocess.ground import GroundGrid
from dronetrack.preprocess.voxel import (
    KeySet,
    coarsen_keys,
    dilate_keys,
    key_centres,
    key_indices,
    neighbour_counts,
    shifted_keys,
    voxel_components,
    voxel_keys,
)

__all__ = [
    "VoxelBackground",
    "aloft_objects",
    "free_objects",
    "lookup_level",
    "occupied_voxels",
    "single_hits",
]


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
AIR_BELOW_M = 1.0  # d_a: nothing this far beneath an object in the air, nor the floor
FLOOR_CELL_M = 2.0  # the floor around a voxel: the lowest voxel in its cell and the 8 around
NEAR_ANGLE = 0.25  # θ [rad]: the widest a lookup cell may look from the sensor


def lookup_level(ranges: FloatArray, resolution: float, depth: int) -> NDArray[np.int64]:
    """(N,) the lookup level of a point at each range r [m]: the coarsest ℓ ≤ depth whose
    cells, s 2^ℓ wide, subtend at most θ: ℓ = clamp(⌊log₂(r θ / s)⌋, 0, depth)."""
    r = np.maximum(np.asarray(ranges, dtype=np.float64), 1e-9)
    level = np.floor(np.log2(r * NEAR_ANGLE / resolution))
    out: NDArray[np.int64] = np.clip(level, 0, depth).astype(np.int64)
    return out


def free_objects(
    voxels: NDArray[np.int64],
    resolution: float,
    largest: float,
    weak: NDArray[np.bool_] | None = None,
) -> NDArray[np.bool_]:
    """(N,) the voxels (sorted, distinct keys of edge ``resolution``) of the components
    with ``FREE_GAP`` empty voxels or more around them and whose bounding box's longest
    edge is at most ``largest`` [m].

    ``weak`` (N,) marks the voxels a single return hit: they never join the others
    (in a 1 s scan two false alarms side by side joined a hovering drone to the space
    beside the sensor, 2.5 m in all).  The others' components are measured without
    them; the weak ones form their own, and one of those is free if it is small and
    no voxel that stays lies within reach of it (a far wall sampled once per voxel
    stays whole)."""
    if weak is None or not weak.any():
        return _free_components(voxels, resolution, largest)
    free = np.zeros(len(voxels), dtype=bool)
    free[~weak] = _free_components(voxels[~weak], resolution, largest)
    free[weak] = _free_components(voxels[weak], resolution, largest)
    stays = ~weak & ~free
    rows = np.flatnonzero(stays | (weak & free))
    labels = voxel_components(voxels[rows], reach=FREE_GAP + 1)
    anchored = np.zeros(int(labels.max(initial=-1)) + 1, dtype=bool)
    anchored[labels[stays[rows]]] = True
    loose = weak[rows]
    free[rows[loose]] &= ~anchored[labels[loose]]
    return free


def aloft_objects(
    voxels: NDArray[np.int64], resolution: float, largest: float, depth_m: float = AIR_BELOW_M
) -> NDArray[np.bool_]:
    """(N,) the voxels (sorted, distinct keys of edge ``resolution``) of the small
    objects in the air: the parts of touching voxels (26-neighbourhood) whose bounding
    box's longest edge is at most ``largest`` [m], under none of whose voxels another
    part's voxel lies within d_a = ``depth_m`` in its column, beside none of whose
    voxels another part's lies at its level within ``FREE_GAP`` empty voxels (the
    free-standing gap, level by level), and whose bottom is d_a or more above the
    floor around it: the lowest voxel in its ``FLOOR_CELL_M`` cell and the eight beside
    it, found as ``preprocess.ground.GroundGrid`` finds the ground.  That is the ground,
    or the crop's floor where the crop cuts the ground off; the ground's own patches
    have nothing beneath them either.

    A drone hovering a metre beside a person, above the person's head, is one part of
    the scan with the person by ``free_objects``' gap, yet nothing lies beneath it or
    beside it at its level.  A person, a post or a mast's top stands on something; a
    short scan samples a wall sparsely, and its pieces have more of it beside them."""
    if len(voxels) == 0:
        return np.zeros(0, dtype=bool)
    labels = voxel_components(voxels, reach=1)
    parts = int(labels.max()) + 1
    n = len(voxels)
    held = np.zeros(parts, dtype=bool)  # another part's voxel beneath, or beside it
    depth = max(1, int(np.ceil(depth_m / resolution - 1e-9)))
    side = range(-FREE_GAP - 1, FREE_GAP + 2)
    offsets = [(0, 0, -d) for d in range(1, depth + 1)]
    offsets += [(dx, dy, 0) for dx in side for dy in side if (dx, dy) != (0, 0)]
    for dx, dy, dz in offsets:
        near = shifted_keys(voxels, dx, dy, dz)
        at = np.minimum(np.searchsorted(voxels, near), n - 1)
        hit = np.flatnonzero((voxels[at] == near) & (labels[at] != labels))
        held[labels[hit]] = True
    # each voxel's bottom corner; the floor under it as the ground grid finds the ground
    corners = np.column_stack(key_indices(voxels)).astype(np.float64) * resolution
    grid = GroundGrid(FLOOR_CELL_M, stride=1)
    grid.insert(corners)
    bottom = np.full(parts, np.inf)
    np.minimum.at(bottom, labels, corners[:, 2])
    floor = np.full(parts, np.inf)
    np.minimum.at(floor, labels, grid.height(corners[:, :2]))
    low = bottom - floor < depth_m - 1e-9  # z_bottom − z_floor < d_a
    out: NDArray[np.bool_] = _small(voxels, labels, resolution, largest) & ~(held | low)[labels]
    return out


def _small(
    voxels: NDArray[np.int64], labels: NDArray[np.int64], resolution: float, largest: float
) -> NDArray[np.bool_]:
    """(N,) whether each voxel's part (``labels``) is at most ``largest`` [m] along its
    bounding box's longest edge."""
    centres = key_centres(voxels, resolution)
    k = int(labels.max()) + 1
    lo = np.full((k, 3), np.inf)
    hi = np.full((k, 3), -np.inf)
    np.minimum.at(lo, labels, centres)
    np.maximum.at(hi, labels, centres)
    edge = (hi - lo).max(axis=1) + resolution  # the voxels' extent, end to end
    small: NDArray[np.bool_] = edge[labels] <= largest + 1e-9
    return small


def _free_components(
    voxels: NDArray[np.int64], resolution: float, largest: float
) -> NDArray[np.bool_]:
    """``free_objects`` of ``voxels`` taken alone (no weak ones among them)."""
    if len(voxels) == 0:
        return np.zeros(0, dtype=bool)
    return _small(voxels, voxel_components(voxels, reach=FREE_GAP + 1), resolution, largest)


def single_hits(keys: NDArray[np.int64], voxels: NDArray[np.int64]) -> NDArray[np.bool_]:
    """(N,) which of the ``voxels`` (sorted, distinct) exactly one return of ``keys``
    hit."""
    s = np.sort(keys)
    hits = np.searchsorted(s, voxels, side="right") - np.searchsorted(s, voxels, side="left")
    out: NDArray[np.bool_] = hits == 1
    return out


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
        self._finer: tuple[KeySet, ...] = ()  # levels 0 … depth − 1 (built models)

    @property
    def cell_size(self) -> float:
        """Edge of the lookup cells [m]: resolution · 2^depth."""
        return self.resolution * float(2**self.lookup_depth)

    @property
    def near_m(self) -> float:
        """The range [m] within which a built model looks up in finer cells (0: never)."""
        return self.cell_size / NEAR_ANGLE if self._finer else 0.0

    @property
    def provisional(self) -> bool:
        """Whether the map is a short scan's, too short to tell a hovering drone from
        the world (``free_object_m`` set): its cells say where something was, not that
        a structure stands there (see the module docstring)."""
        return self.free_object_m is not None

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
            free = free_objects(
                voxels, self.resolution, self.free_object_m, single_hits(keys, voxels)
            )
            free |= aloft_objects(voxels, self.resolution, self.free_object_m)
            self.left_out = int(np.count_nonzero(free))
            voxels = voxels[~free]
        grown = dilate_keys(voxels, self.inflate)
        self._cells = KeySet.of(coarsen_keys(grown, self.lookup_depth))
        self._finer = tuple(KeySet.of(coarsen_keys(grown, lv)) for lv in range(self.lookup_depth))

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

    def is_background(
        self, points: FloatArray, sensor: FloatArray | None = None
    ) -> NDArray[np.bool_]:
        """Whether each world point (N, 3) falls in an occupied cell (non-finite: False);
        with the ``sensor``'s position (3,), in finer cells near it (``near``)."""
        out = self.cells.contains_points(points, self.cell_size)
        return out if sensor is None else self.near(points, out, sensor)

    def near(
        self, points: FloatArray, background: NDArray[np.bool_], sensor: FloatArray
    ) -> NDArray[np.bool_]:
        """``background`` (N,), the coarse verdict on each world point (N, 3), with the
        points within ``near_m`` of the ``sensor`` (3,) looked up again at their level
        ℓ(r) (``lookup_level``): background only if that finer cell is occupied too."""
        out = np.array(background, dtype=bool)
        if not self._finer:
            return out
        at = np.flatnonzero(out)
        r = np.linalg.norm(points[at] - np.asarray(sensor, dtype=np.float64), axis=1)
        at, r = at[r < self.near_m], r[r < self.near_m]
        level = lookup_level(r, self.resolution, self.lookup_depth)
        for lv in np.unique(level[level < self.lookup_depth]):
            rows = at[level == lv]
            size = self.resolution * float(2 ** int(lv))
            out[rows] = self._finer[int(lv)].contains_points(points[rows], size)
        return out

    def __len__(self) -> int:
        """Occupied lookup cells (0 before ``build``)."""
        return len(self._cells) if self._cells is not None else 0
