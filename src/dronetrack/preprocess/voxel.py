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
from dronetrack.geometry import FloatArray

__all__ = ["KeySet", "coarsen_keys", "dilate_keys", "unique_keys", "voxel_keys"]

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


def voxel_keys(points: FloatArray, size: float) -> IntArray:
    """Keys of the voxels of edge ``size`` that hold ``points`` (N, 3) (finite points only)."""
    idx = np.floor(points / size).astype(np.int64)
    if len(idx) and (np.abs(idx).max() >= OFFSET):
        raise InputError(f"points beyond ±{OFFSET * size:g} m do not fit the voxel keys")
    return _pack_array(idx[:, 0], idx[:, 1], idx[:, 2])


def unique_keys(keys: IntArray) -> IntArray:
    """Sorted distinct keys (sort and compare: numpy's hash-based unique is slower here)."""
    s = np.sort(keys)
    if len(s) == 0:
        return s
    keep = np.empty(len(s), dtype=bool)
    keep[0] = True
    np.not_equal(s[1:], s[:-1], out=keep[1:])
    return s[keep]


def dilate_keys(keys: IntArray, k: int) -> IntArray:
    """Every voxel within Chebyshev distance k of a key (the 26-neighbourhood, k times)."""
    if k <= 0 or len(keys) == 0:
        return unique_keys(keys)
    r = np.arange(-k, k + 1)
    dx, dy, dz = (a.ravel() for a in np.meshgrid(r, r, r, indexing="ij"))
    ix, iy, iz = _unpack(keys)
    grown = _pack_array(
        (ix[:, None] + dx).ravel(), (iy[:, None] + dy).ravel(), (iz[:, None] + dz).ravel()
    )
    return unique_keys(grown)


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


@nb.njit(cache=True)
def _contains_many(table: IntArray, shift: int, keys: IntArray) -> NDArray[np.bool_]:
    out = np.empty(keys.shape[0], dtype=np.bool_)
    for j in range(keys.shape[0]):
        out[j] = table_contains(table, shift, keys[j])
    return out


@dataclass(frozen=True, slots=True)
class KeySet:
    """A set of voxel keys with O(1) membership tests (linear probing, load ≤ ½)."""

    keys: IntArray  # sorted distinct keys
    table: IntArray
    shift: int

    @staticmethod
    def of(keys: IntArray) -> KeySet:
        distinct = unique_keys(np.asarray(keys, dtype=np.int64))
        bits = max(4, int(np.ceil(np.log2(max(2 * len(distinct), 1)))) + 1)
        shift = 64 - bits
        return KeySet(distinct, _build_table(distinct, 1 << bits, shift), shift)

    def __len__(self) -> int:
        return len(self.keys)

    def contains(self, keys: IntArray) -> NDArray[np.bool_]:
        """Membership of each key."""
        return _contains_many(self.table, self.shift, np.ascontiguousarray(keys, dtype=np.int64))
