"""Integer voxel keys and a hash set of them (numba).

A point p falls in voxel i = ⌊p / s⌋ per axis; the three indices are packed
into one int64 with 21 bits each (offset 2^20, so ±1,048,576 voxels per axis:
±105 km at 0.1 m).  A voxel k levels coarser has index i >> k (arithmetic
shift: floor division by 2^k), as in an octree.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray

__all__ = [
    "KeySet",
    "coarsen_keys",
    "dilate_keys",
    "key_centres",
    "key_indices",
    "neighbour_counts",
    "shifted_keys",
    "unique_keys",
    "voxel_components",
    "voxel_keys",
]

BITS = 21
OFFSET = 1 << (BITS - 1)
MASK = (1 << BITS) - 1
IntArray = NDArray[np.int64]


@nb.njit(cache=True)
def pack(ix: int, iy: int, iz: int) -> int:
    """One int64 key from three signed voxel indices."""
    return ((ix + OFFSET) << (2 * BITS)) | ((iy + OFFSET) << BITS) | (iz + OFFSET)


def _unpack(keys: IntArray) -> tuple[IntArray, IntArray, IntArray]:
    return (
        ((keys >> (2 * BITS)) & MASK) - OFFSET,
        ((keys >> BITS) & MASK) - OFFSET,
        (keys & MASK) - OFFSET,
    )


def _pack_array(ix: IntArray, iy: IntArray, iz: IntArray) -> IntArray:
    return ((ix + OFFSET) << (2 * BITS)) | ((iy + OFFSET) << BITS) | (iz + OFFSET)


def key_indices(keys: IntArray) -> tuple[IntArray, IntArray, IntArray]:
    """The voxel indices (i, j, k) of each key (the voxel's corner over its edge)."""
    return _unpack(np.asarray(keys, dtype=np.int64))


def shifted_keys(keys: IntArray, dx: int, dy: int, dz: int) -> IntArray:
    """The keys of the voxels (dx, dy, dz) voxels from each of ``keys``."""
    ix, iy, iz = _unpack(np.asarray(keys, dtype=np.int64))
    return _pack_array(ix + dx, iy + dy, iz + dz)


def voxel_keys(points: FloatArray, size: float) -> IntArray:
    """Keys of the voxels of edge ``size`` that hold ``points`` (N, 3) (finite points only)."""
    idx = np.floor(points / size).astype(np.int64)
    if len(idx) and (np.abs(idx).max() >= OFFSET):
        raise InputError(f"points beyond ±{OFFSET * size:g} m do not fit the voxel keys")
    return _pack_array(idx[:, 0], idx[:, 1], idx[:, 2])


def key_centres(keys: IntArray, size: float) -> FloatArray:
    """(N, 3) the centres of the voxels of edge ``size`` with these keys [m]."""
    ix, iy, iz = _unpack(np.asarray(keys, dtype=np.int64))
    return (np.column_stack([ix, iy, iz]).astype(np.float64) + 0.5) * size


def unique_keys(keys: IntArray) -> IntArray:
    """Sorted distinct keys (sort and compare: numpy's hash-based unique is slower here)."""
    s = np.sort(keys)
    if len(s) == 0:
        return s
    keep = np.empty(len(s), dtype=bool)
    keep[0] = True
    np.not_equal(s[1:], s[:-1], out=keep[1:])
    return s[keep]


def _offsets(k: int) -> tuple[IntArray, IntArray, IntArray]:
    """The (2k + 1)³ offsets within Chebyshev distance k, the zero offset included."""
    r = np.arange(-k, k + 1)
    dx, dy, dz = (a.ravel() for a in np.meshgrid(r, r, r, indexing="ij"))
    return dx, dy, dz


def dilate_keys(keys: IntArray, k: int) -> IntArray:
    """Every voxel within Chebyshev distance k of a key (the 26-neighbourhood, k times)."""
    if k <= 0 or len(keys) == 0:
        return unique_keys(keys)
    dx, dy, dz = _offsets(k)
    ix, iy, iz = _unpack(keys)
    grown = _pack_array(
        (ix[:, None] + dx).ravel(), (iy[:, None] + dy).ravel(), (iz[:, None] + dz).ravel()
    )
    return unique_keys(grown)


def neighbour_counts(keys: IntArray, support: IntArray) -> IntArray:
    """How many of each key's 26 neighbours are in ``support`` (sorted distinct keys)."""
    ix, iy, iz = _unpack(keys)
    counts = np.zeros(len(keys), dtype=np.int64)
    if len(support) == 0:
        return counts
    for ox, oy, oz in zip(*_offsets(1), strict=True):
        if ox == oy == oz == 0:
            continue
        neighbour = _pack_array(ix + ox, iy + oy, iz + oz)
        at = np.minimum(np.searchsorted(support, neighbour), len(support) - 1)
        counts += support[at] == neighbour
    return counts


def voxel_components(keys: IntArray, reach: int = 1) -> IntArray:
    """(N,) a label per voxel of ``keys`` (sorted, distinct): voxels within Chebyshev
    distance ``reach`` of each other (1: the 26-neighbourhood), directly or through
    others, share one (scipy's graph components)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = len(keys)
    if n == 0:
        return np.empty(0, dtype=np.int64)
    ix, iy, iz = _unpack(keys)
    rows, cols = [], []
    for ox, oy, oz in zip(*_offsets(reach), strict=True):
        if (ox, oy, oz) <= (0, 0, 0):  # each pair once
            continue
        neighbour = _pack_array(ix + ox, iy + oy, iz + oz)
        at = np.minimum(np.searchsorted(keys, neighbour), n - 1)
        hit = np.flatnonzero(keys[at] == neighbour)
        rows.append(hit)
        cols.append(at[hit])
    r, c = np.concatenate(rows), np.concatenate(cols)
    graph = coo_matrix((np.ones(len(r), dtype=np.int8), (r, c)), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return np.asarray(labels, dtype=np.int64)


def coarsen_keys(keys: IntArray, depth: int) -> IntArray:
    """Keys of the voxels 2^depth times larger that hold the given voxels."""
    if depth <= 0:
        return unique_keys(keys)
    ix, iy, iz = _unpack(keys)
    return unique_keys(_pack_array(ix >> depth, iy >> depth, iz >> depth))


@nb.njit(cache=True)
def _slot(key: int, shift: int) -> np.int64:
    # Fibonacci hashing: the top bits of key · 2^64/φ (mod 2^64).
    h = np.uint64(key) * np.uint64(0x9E3779B97F4A7C15)
    return np.int64(h >> np.uint64(shift))


@nb.njit(cache=True)
def table_contains(table: IntArray, shift: int, key: int) -> bool:
    """Whether ``key`` is in the open-addressing table (empty slots hold -1)."""
    mask = table.shape[0] - 1
    i = _slot(key, shift)
    while True:
        k = table[i]
        if k == key:
            return True
        if k == -1:
            return False
        i = (i + 1) & mask


@nb.njit(cache=True)
def _build_table(keys: IntArray, size: int, shift: int) -> IntArray:
    table = np.full(size, -1, dtype=np.int64)
    mask = size - 1
    for key in keys:
        i = _slot(key, shift)
        while table[i] != -1 and table[i] != key:
            i = (i + 1) & mask
        table[i] = key
    return table


@nb.njit(cache=True, inline="always")
def occupied(
    ix: int,
    iy: int,
    iz: int,
    grid: NDArray[np.uint8],
    origin: IntArray,
    table: IntArray,
    shift: int,
) -> bool:
    """Whether voxel (ix, iy, iz) is in the set: the dense grid if there is one, else the hash."""
    if grid.shape[0] > 0:
        gx, gy, gz = ix - origin[0], iy - origin[1], iz - origin[2]
        if gx < 0 or gy < 0 or gz < 0:
            return False
        if gx >= grid.shape[0] or gy >= grid.shape[1] or gz >= grid.shape[2]:
            return False
        return bool(grid[gx, gy, gz] != 0)
    if abs(ix) >= OFFSET or abs(iy) >= OFFSET or abs(iz) >= OFFSET:
        return False
    return table_contains(table, shift, pack(ix, iy, iz))


@nb.njit(cache=True)
def _contains_many(
    grid: NDArray[np.uint8], origin: IntArray, table: IntArray, shift: int, idx: IntArray
) -> NDArray[np.bool_]:
    out = np.empty(idx.shape[0], dtype=np.bool_)
    for j in range(idx.shape[0]):
        out[j] = occupied(idx[j, 0], idx[j, 1], idx[j, 2], grid, origin, table, shift)
    return out


DENSE_MAX_CELLS = 1 << 24  # a dense grid up to 16 M voxels (16 MB), else the hash alone


@dataclass(frozen=True, slots=True)
class KeySet:
    """A set of voxels with O(1) membership tests.

    A dense occupancy grid over the set's bounding box when that box is small
    enough (cache-friendly for points that arrive in scan order), and always an
    open-addressing hash table of the keys (linear probing, load ≤ ½).
    """

    keys: IntArray  # sorted distinct keys
    table: IntArray
    shift: int
    grid: NDArray[np.uint8]  # (nx, ny, nz), or (0, 0, 0) without a dense grid
    origin: IntArray  # (3,) voxel index of grid[0, 0, 0]

    @staticmethod
    def of(keys: IntArray) -> KeySet:
        distinct = unique_keys(np.asarray(keys, dtype=np.int64))
        bits = max(4, int(np.ceil(np.log2(max(2 * len(distinct), 1)))) + 1)
        shift = 64 - bits
        table = _build_table(distinct, 1 << bits, shift)
        grid = np.zeros((0, 0, 0), dtype=np.uint8)
        origin = np.zeros(3, dtype=np.int64)
        if len(distinct):
            idx = np.column_stack(_unpack(distinct))
            origin = idx.min(axis=0)
            shape = idx.max(axis=0) - origin + 1
            if int(np.prod(shape)) <= DENSE_MAX_CELLS:
                grid = np.zeros(tuple(int(v) for v in shape), dtype=np.uint8)
                rel = idx - origin
                grid[rel[:, 0], rel[:, 1], rel[:, 2]] = 1
        return KeySet(distinct, table, shift, grid, origin)

    def __len__(self) -> int:
        return len(self.keys)

    def contains(self, keys: IntArray) -> NDArray[np.bool_]:
        """Membership of each key."""
        idx = np.column_stack(_unpack(np.asarray(keys, dtype=np.int64)))
        return self.contains_index(idx)

    def contains_points(self, points: FloatArray, size: float) -> NDArray[np.bool_]:
        """Membership of the voxels of edge ``size`` [m] that hold each world point (N, 3),
        i = ⌊p / size⌋; non-finite points: False."""
        out = np.zeros(len(points), dtype=bool)
        ok = np.all(np.isfinite(points), axis=1)
        out[ok] = self.contains_index(np.floor(points[ok] / size).astype(np.int64))
        return out

    def contains_index(self, idx: IntArray) -> NDArray[np.bool_]:
        """Membership of voxels given by their integer indices (N, 3)."""
        return _contains_many(
            self.grid,
            self.origin,
            self.table,
            self.shift,
            np.ascontiguousarray(idx, dtype=np.int64),
        )
