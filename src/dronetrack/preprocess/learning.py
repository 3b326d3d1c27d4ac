"""A background that keeps learning: each voxel's occupancy over the last T seconds.

The scanned map (``preprocess.background``) holds what stood still while the turret
scanned.  A real site changes after that: a car parks, a tent goes up, and a sensor
switched on with the drone in view has no clean scan at all.  This map learns online,
wherever the sensor looks, from the points the scanned map does not hold.

Time is cut into windows of Δw = max(T / 64, frame period).  Each voxel of edge r
that any return has hit keeps two 64-bit masks over the last W = ⌈T / Δw⌉ windows in
which it was looked at (T seconds of a voxel in view; a voxel out of view keeps its
history, so what the turret turns away from is still known when it turns back):

- L, the windows in which it was *looked at*: in the window's first frame, a return
  came from its direction (cells of about 1° around the sensor: a cube map, 90 × 90
  cells a face, so no trigonometry per return) at its range or beyond (the
  beam reached it), or no return came from its direction although the sensor samples
  that direction (the open sky: the direction's cell in the sensor's own frame has
  returned something before); a nearer return hides it, and that is no look;
- H, the windows in which a return fell in it (hits imply a look).

With n_L = popcount(L) and n_H = popcount(H), a voxel enters the map when it was
occupied long enough, and in a share s of its looks:

    n_H ≥ L_min  and  n_H ≥ s · n_L

and leaves it when n_H < s/2 · n_L (hysteresis: a sparsely sampled far wall does not
flicker), or when it was looked at in at least half of its last L_min windows in view
and hit in none of them.  A car that drives away is looked through (the ground behind
it returns), so its voxels fade within L_min windows, as fast as they were learnt.  A
voxel not in the map that nothing has hit for T seconds is forgotten: the memory holds
the map (the static world's surface, sparse) and what the last T seconds hit.

What a drone's track holds must never become background: the caller names *protected*
balls (``pipeline.protect``: every track that may be a drone, classed drone or neither
static nor with p_drone below the least a track worth a look has, and the turret's
target), and the returns in them are no hits.  Their voxels are still looked at, so a drone's voxels
cannot enter and fade if they had.  A track the classes hold unlikely (grounded,
joined, propped, crowded: part of the world) is learnt like the rest of the world:
on ``outdoor-unscanned`` (seeds 0-9), where every track not classed static was
protected, the fragments of an unmapped tree line were never learnt, and the tracks
on them gave 3,200 false positives a run (motmetrics' count of frames; 170 with this
rule).  Lookups are at voxel resolution, dilated by ``inflate`` voxels
over the 26-neighbourhood (no coarser cells: what is learnt was seen many times).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.preprocess.crop import ball_mask
from dronetrack.preprocess.voxel import (
    KeySet,
    dilate_keys,
    key_centres,
    unique_keys,
    voxel_keys,
)

__all__ = [
    "LearningBackground",
    "LearningSettings",
    "look_cells",
    "looked_at",
    "window_update",
]

IntArray = NDArray[np.int64]
MaskArray = NDArray[np.uint64]
N_FACE = 90  # cells along a cube-map face's edge: 1.3° at its centre, 0.6° at a corner
N_CELLS = 6 * N_FACE * N_FACE
COVERAGE_STRIDE = 4  # every 4th return marks the sensor's sampled directions
MAX_WINDOWS = 64  # the bits of a mask


@dataclass(frozen=True, slots=True)
class LearningSettings:
    """T [s], the share s, how long a voxel must have been occupied before it may enter
    [s], the voxel size r [m] and the lookup dilation [voxels]."""

    memory_s: float = 20.0
    share: float = 0.5
    min_occupied_s: float = 5.0
    resolution: float = 1.0
    inflate: int = 1

    def __post_init__(self) -> None:
        if not self.memory_s > 0:
            raise InputError(f"background learning time must be > 0 s, got {self.memory_s:g}")
        if not 0 < self.share <= 1:
            raise InputError(f"background learning share must be in (0, 1], got {self.share:g}")
        if not 0 <= self.min_occupied_s <= self.memory_s:
            raise InputError(
                f"background minimum occupied time must be 0-{self.memory_s:g} s (the learning "
                f"time), got {self.min_occupied_s:g}"
            )
        if self.resolution <= 0 or self.inflate < 0:
            raise InputError("background learning: resolution > 0 and inflate ≥ 0")


@nb.njit(cache=True, inline="always")
def _face_uv(x: float, y: float, z: float) -> tuple[int, int, int]:
    """The cube-map face of the direction (x, y, z) ≠ 0 and its cell (i, j) there: the
    face of the largest |component| m, and (u, v) = the other two components / |m| in
    [−1, 1], i = ⌊(u + 1) N / 2⌋."""
    ax, ay, az = abs(x), abs(y), abs(z)
    if ax >= ay and ax >= az:
        face, m, u, v = (0 if x > 0 else 1), ax, y, z
    elif ay >= az:
        face, m, u, v = (2 if y > 0 else 3), ay, x, z
    else:
        face, m, u, v = (4 if z > 0 else 5), az, x, y
    i = min(int((u / m + 1.0) * 0.5 * N_FACE), N_FACE - 1)
    j = min(int((v / m + 1.0) * 0.5 * N_FACE), N_FACE - 1)
    return face, i, j


@nb.njit(cache=True, inline="always")
def _cell(x: float, y: float, z: float) -> int:
    """The direction cell of the vector (x, y, z) ≠ 0, an index into N_CELLS."""
    face, i, j = _face_uv(x, y, z)
    return (face * N_FACE + i) * N_FACE + j


@nb.njit(cache=True)
def look_cells(rel: FloatArray) -> NDArray[np.float32]:
    """(N_CELLS,) the farthest return per direction cell, of vectors ``rel`` (N, 3) from
    the sensor; −1 where none came (non-finite vectors are skipped)."""
    out = np.full(N_CELLS, -1.0, dtype=np.float32)
    for j in range(rel.shape[0]):
        x, y, z = rel[j, 0], rel[j, 1], rel[j, 2]
        if not (np.isfinite(x) and np.isfinite(y) and np.isfinite(z)):
            continue
        r = np.sqrt(x * x + y * y + z * z)
        if r <= 0.0:
            continue
        c = _cell(x, y, z)
        if r > out[c]:
            out[c] = r
    return out


@nb.njit(cache=True)
def _sample(points: FloatArray, covered: NDArray[np.bool_], stride: int) -> None:
    """Mark the cells of every ``stride``-th of ``points`` (N, 3), in the sensor frame,
    as sampled (what the sensor samples is learnt over many frames)."""
    for j in range(0, points.shape[0], stride):
        x, y, z = points[j, 0], points[j, 1], points[j, 2]
        if np.isfinite(x) and np.isfinite(y) and np.isfinite(z) and x * x + y * y + z * z > 0:
            covered[_cell(x, y, z)] = True


@nb.njit(cache=True, inline="always")
def _near_covered(covered: NDArray[np.bool_], x: float, y: float, z: float) -> bool:
    """Whether the sensor samples the direction (x, y, z)'s cell or one beside it on its
    face: a voxel's centre and the returns from it may fall in neighbouring cells."""
    face, i, j = _face_uv(x, y, z)
    for di in range(-1, 2):
        ii = i + di
        if 0 <= ii < N_FACE:
            for dj in range(-1, 2):
                jj = j + dj
                if 0 <= jj < N_FACE and covered[(face * N_FACE + ii) * N_FACE + jj]:
                    return True
    return False


@nb.njit(cache=True)
def looked_at(
    centres: FloatArray,
    sensor: FloatArray,
    to_sensor: FloatArray,
    farthest: NDArray[np.float32],
    covered: NDArray[np.bool_],
    margin: float,
) -> NDArray[np.bool_]:
    """(K,) whether the beam reached each voxel centre (K, 3) this frame: the farthest
    return of its direction is at its range − ``margin`` or beyond, or none came from
    a direction the sensor samples (``covered``, in the sensor frame, that cell or one
    beside it: ``to_sensor`` is the 3 × 3 rotation world → sensor, ``sensor`` the
    sensor's world position)."""
    out = np.zeros(centres.shape[0], dtype=np.bool_)
    for k in range(centres.shape[0]):
        x = centres[k, 0] - sensor[0]
        y = centres[k, 1] - sensor[1]
        z = centres[k, 2] - sensor[2]
        r = np.sqrt(x * x + y * y + z * z)
        if r <= 0.0:
            continue
        far = farthest[_cell(x, y, z)]
        if far >= 0.0:
            out[k] = far >= r - margin  # reached it, or passed through it
        else:  # no return that way: the open sky, if the sensor samples it
            sx = to_sensor[0, 0] * x + to_sensor[0, 1] * y + to_sensor[0, 2] * z
            sy = to_sensor[1, 0] * x + to_sensor[1, 1] * y + to_sensor[1, 2] * z
            sz = to_sensor[2, 0] * x + to_sensor[2, 1] * y + to_sensor[2, 2] * z
            out[k] = _near_covered(covered, sx, sy, sz)
    return out


def window_update(
    looks: MaskArray,
    hits: MaskArray,
    looked: NDArray[np.bool_],
    hit: NDArray[np.bool_],
    windows: int,
) -> tuple[MaskArray, MaskArray]:
    """The masks after a window that looked at and hit the voxels as given (a hit is a
    look): where it looked, L ← (L ≪ 1) | 1 and H ← (H ≪ 1) | h, kept to the last
    ``windows`` bits; elsewhere unchanged (out of view, the history waits)."""
    keep = np.uint64((1 << windows) - 1) if windows < MAX_WINDOWS else np.uint64(2**64 - 1)
    seen = looked | hit
    one = np.uint64(1)
    looks = np.where(seen, ((looks << one) | one) & keep, looks)
    hits = np.where(seen, ((hits << one) | hit.astype(np.uint64)) & keep, hits)
    return looks, hits


def learnt_now(
    learnt: NDArray[np.bool_],
    looks: MaskArray,
    hits: MaskArray,
    share: float,
    min_looks: int,
) -> NDArray[np.bool_]:
    """Which voxels are background after a window: enter when n_H ≥ L_min and
    n_H ≥ s n_L; leave when n_H < s/2 n_L, or its last L_min windows in view looked at
    it at least L_min / 2 times and never hit it."""
    n_l = np.bitwise_count(looks).astype(np.int64)
    n_h = np.bitwise_count(hits).astype(np.int64)
    recent = np.uint64((1 << min(max(min_looks, 1), MAX_WINDOWS - 1)) - 1)
    cleared = (2 * np.bitwise_count(looks & recent) >= max(min_looks, 1)) & ((hits & recent) == 0)
    enter = (n_h >= min_looks) & (n_h >= share * n_l)
    leave = (n_h < 0.5 * share * n_l) | cleared
    return np.asarray((learnt | enter) & ~leave, dtype=bool)


def _outside_balls(points: FloatArray, centres: FloatArray, radii: FloatArray) -> NDArray[np.bool_]:
    """(N,) the points outside every ball (centres (B, 3), radii (B,))."""
    keep = np.ones(len(points), dtype=bool)
    for c, rad in zip(centres, radii, strict=True):
        keep &= ~ball_mask(points, c, float(rad))
    return keep


class LearningBackground:
    """The online map (see the module docstring): ``observe`` each frame, then ask
    ``is_background``."""

    def __init__(self, settings: LearningSettings, period: float) -> None:
        self.settings = settings
        self.window_s = max(settings.memory_s / MAX_WINDOWS, float(period))
        self.windows = min(MAX_WINDOWS, max(1, int(np.ceil(settings.memory_s / self.window_s))))
        self.min_hits = int(np.ceil(settings.min_occupied_s / self.window_s - 1e-9))
        self.keys: IntArray = np.empty(0, dtype=np.int64)  # sorted voxel keys
        self.looks: MaskArray = np.empty(0, dtype=np.uint64)
        self.hits: MaskArray = np.empty(0, dtype=np.uint64)
        self.learnt: NDArray[np.bool_] = np.empty(0, dtype=bool)
        self.last_hit: IntArray = np.empty(0, dtype=np.int64)  # the window that last hit it
        self.covered = np.zeros(N_CELLS, dtype=bool)  # sampled directions, sensor frame
        self._window: int | None = None  # the open window's index
        self._looked = np.empty(0, dtype=bool)  # of ``keys``, in the open window
        self._hit_chunks: list[IntArray] = []
        self._cells = KeySet.of(np.empty(0, dtype=np.int64))
        self.rebuilds = 0

    def __len__(self) -> int:
        """Voxels in the map now."""
        return int(np.count_nonzero(self.learnt))

    @property
    def voxels(self) -> int:
        """Voxels with a history: in the map, or hit in the last T."""
        return len(self.keys)

    @property
    def nbytes(self) -> int:
        """Memory the map holds [bytes]."""
        c = self._cells
        held = (
            self.keys,
            self.looks,
            self.hits,
            self.learnt,
            self.last_hit,
            self._looked,
            self.covered,
        )
        return sum(a.nbytes for a in held) + c.keys.nbytes + c.table.nbytes + c.grid.nbytes

    def learnt_keys(self) -> IntArray:
        """The keys of the voxels in the map (sorted)."""
        return self.keys[self.learnt]

    def seed(self, keys: IntArray) -> None:
        """Start from these voxels as background, looked at and hit in every window of the
        last T (a saved map): they fade like any other once looked through."""
        new = unique_keys(np.asarray(keys, dtype=np.int64))
        full = np.uint64((1 << self.windows) - 1 if self.windows < MAX_WINDOWS else 2**64 - 1)
        self._merge(new)
        at = np.searchsorted(self.keys, new)
        self.looks[at] = full
        self.hits[at] = full
        self.learnt[at] = True
        self.last_hit[at] = self._window if self._window is not None else 0
        self._rebuild()

    def resume(self, keys: IntArray, resolution: float) -> int:
        """Start from a saved map's learnt voxels (keys at ``resolution`` m, their centres
        taken to this map's voxel size); the number of voxels it starts with."""
        size = self.settings.resolution
        if len(keys) and resolution != size:
            keys = unique_keys(voxel_keys(key_centres(keys, resolution), size))
        self.seed(keys)
        return len(self)

    def is_background(self, points: FloatArray) -> NDArray[np.bool_]:
        """(N,) whether each world point falls in (or beside) a learnt voxel."""
        if len(self._cells) == 0:
            return np.zeros(len(points), dtype=bool)
        return self._cells.contains_points(points, self.settings.resolution)

    def is_structure(
        self, points: FloatArray, recent: int = 8, min_hits: int = 2
    ) -> NDArray[np.bool_]:
        """(N,) whether each world point's voxel is learnt, or was hit in ``min_hits`` of
        the last ``recent`` windows by what no track holds (protected returns are no
        hits): the rest of a wall the map has not learnt yet, beside a fragment of it."""
        out = self.is_background(points)
        if len(self.keys) == 0 or len(points) == 0:
            return out
        ok = np.flatnonzero(np.all(np.isfinite(points), axis=1) & ~out)
        keys = voxel_keys(points[ok], self.settings.resolution)
        at = np.minimum(np.searchsorted(self.keys, keys), len(self.keys) - 1)
        held = self.keys[at] == keys
        last = np.uint64((1 << min(recent, MAX_WINDOWS - 1)) - 1)
        often = np.bitwise_count(self.hits[at] & last) >= min_hits
        out[ok] = held & often
        return out

    def observe(
        self,
        t: float,
        world: FloatArray,
        sensor_points: FloatArray,
        pose: FloatArray,
        candidates: FloatArray,
        protect_centres: FloatArray,
        protect_radii: FloatArray,
    ) -> bool:
        """Take a frame ending at ``t``: ``world`` (N, 3) all its returns in the world
        frame and ``sensor_points`` (N, 3) in the sensor's, ``pose`` (4, 4) the sensor's
        world pose at its end, ``candidates`` (M, 3) the returns the map may learn (not in
        the scanned map, inside the crop), and the protected balls.  Returns whether the
        map changed (a window closed and a voxel entered or left)."""
        w = int(np.floor(t / self.window_s))
        changed = False
        opened = self._window is None or w > self._window
        if self._window is not None and w > self._window:
            changed = self._close(self._window)
        self._window = w
        _sample(
            np.ascontiguousarray(sensor_points, dtype=np.float64), self.covered, COVERAGE_STRIDE
        )
        sensor = np.ascontiguousarray(pose[:3, 3], dtype=np.float64)
        if opened and len(self.keys):  # looks: a window's first frame (hits: all of them)
            farthest = look_cells(np.ascontiguousarray(world - sensor, dtype=np.float64))
            self._looked |= looked_at(
                key_centres(self.keys, self.settings.resolution),
                sensor,
                np.ascontiguousarray(pose[:3, :3].T, dtype=np.float64),
                farthest,
                self.covered,
                self.settings.resolution,
            )
        mine = candidates[np.all(np.isfinite(candidates), axis=1)]
        if len(protect_radii) and len(mine):
            mine = mine[_outside_balls(mine, protect_centres, protect_radii)]
        if len(mine):
            self._hit_chunks.append(unique_keys(voxel_keys(mine, self.settings.resolution)))
        return changed

    def _merge(self, new: IntArray) -> None:
        """Add the keys ``new`` (sorted, distinct) that are not yet held, with no history."""
        fresh = new[~np.isin(new, self.keys, assume_unique=True)]
        if len(fresh) == 0:
            return
        keys = np.concatenate([self.keys, fresh])
        order = np.argsort(keys, kind="stable")
        n = len(fresh)
        self.keys = keys[order]
        self.looks = np.concatenate([self.looks, np.zeros(n, dtype=np.uint64)])[order]
        self.hits = np.concatenate([self.hits, np.zeros(n, dtype=np.uint64)])[order]
        self.learnt = np.concatenate([self.learnt, np.zeros(n, dtype=bool)])[order]
        self.last_hit = np.concatenate([self.last_hit, np.zeros(n, dtype=np.int64)])[order]
        self._looked = np.concatenate([self._looked, np.zeros(n, dtype=bool)])[order]

    def _close(self, window: int) -> bool:
        """Close the open window (its index): fold its looks and hits into the masks,
        decide what is background, forget what is not and nothing hit for T."""
        hit_keys = (
            unique_keys(np.concatenate(self._hit_chunks))
            if self._hit_chunks
            else np.empty(0, dtype=np.int64)
        )
        self._hit_chunks = []
        self._merge(hit_keys)
        hit = np.zeros(len(self.keys), dtype=bool)
        hit[np.searchsorted(self.keys, hit_keys)] = True
        self.last_hit[hit] = window
        self.looks, self.hits = window_update(
            self.looks, self.hits, self._looked, hit, self.windows
        )
        before = self.learnt
        s = self.settings
        self.learnt = learnt_now(before, self.looks, self.hits, s.share, self.min_hits)
        changed = bool(np.any(before != self.learnt))
        alive = self.learnt | (self.last_hit > window - self.windows)
        if not np.all(alive):
            self.keys, self.looks, self.hits = self.keys[alive], self.looks[alive], self.hits[alive]
            self.learnt, self.last_hit = self.learnt[alive], self.last_hit[alive]
        self._looked = np.zeros(len(self.keys), dtype=bool)
        if changed:
            self._rebuild()
        return changed

    def _rebuild(self) -> None:
        self._cells = KeySet.of(dilate_keys(self.learnt_keys(), self.settings.inflate))
        self.rebuilds += 1
