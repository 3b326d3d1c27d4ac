"""Analytic ray casting against primitives (numba).

A ray is o + t·d with unit d; the caster returns the smallest t > 0, the index of
the primitive hit and |cos θ_inc| = |n·d| at the hit, from the surface normal n.
Each ray tests every primitive, or with a ``CubeMapIndex`` only those listed for
its direction.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.cubemap import CubeMapIndex
from dronetrack.sim.primitives import BOX, CYLINDER, ELLIPSOID, PLANE, Primitives

__all__ = ["BOX", "CYLINDER", "ELLIPSOID", "PLANE", "Primitives", "cast_rays"]

_T_MIN = 1e-9
# Fast-math without the no-NaN/no-Inf assumptions: misses are carried as inf.
_FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}


def cast_rays(
    prims: Primitives,
    origins: FloatArray,
    dirs: FloatArray,
    t_max: float = np.inf,
    index: CubeMapIndex | None = None,
) -> tuple[FloatArray, NDArray[np.int64], FloatArray]:
    """First hit of each ray o + t·d against the primitives.

    origins: (N, 3) or (3,); dirs: (N, 3) unit directions; index: built for
    these primitives, covering the ray origins (``CubeMapIndex.covers``).
    Returns range t (N,) (inf where nothing is hit before t_max), the index of the
    primitive hit (N,) (-1 for none) and |cos θ_inc| (N,).
    """
    D = np.ascontiguousarray(dirs, dtype=np.float64)
    if D.ndim != 2 or D.shape[1] != 3:
        raise InputError(f"ray directions must have shape (N, 3), got {D.shape}")
    orig = np.ascontiguousarray(np.broadcast_to(origins, D.shape), dtype=np.float64)
    if index is None:
        n_side, start = 0, np.zeros(1, dtype=np.int64)
        items, always = np.empty(0, dtype=np.int64), np.arange(len(prims), dtype=np.int64)
    else:
        n_side, start, items, always = index.n, index.start, index.items, index.always
    local_R_world = np.ascontiguousarray(np.transpose(prims.rotation, (0, 2, 1)))
    return _cast(
        orig,
        D,
        prims.kind,
        np.ascontiguousarray(prims.center),
        local_R_world,
        np.ascontiguousarray(prims.half),
        n_side,
        start,
        items,
        always,
        float(t_max),
    )


@nb.njit(cache=True, fastmath=_FAST)
def _hit_box(
    ox: float,
    oy: float,
    oz: float,
    dx: float,
    dy: float,
    dz: float,
    hx: float,
    hy: float,
    hz: float,
) -> tuple[float, float]:
    """Slab test: entry (or exit, from inside) distance and |cos| with the face normal."""
    t_near = -np.inf
    t_far = np.inf
    cos_near = 0.0
    cos_far = 0.0
    for o, d, h in ((ox, dx, hx), (oy, dy, hy), (oz, dz, hz)):
        if d == 0.0:
            if o < -h or o > h:
                return np.inf, 0.0
            continue
        # Slab -h ≤ o + t d ≤ h  ⇒  t ∈ [(-h - o)/d, (h - o)/d]
        t1 = (-h - o) / d
        t2 = (h - o) / d
        if t1 > t2:
            t1, t2 = t2, t1
        if t1 > t_near:
            t_near = t1
            cos_near = abs(d)
        if t2 < t_far:
            t_far = t2
            cos_far = abs(d)
    if t_far < t_near or t_far <= _T_MIN:
        return np.inf, 0.0
    if t_near > _T_MIN:
        return t_near, cos_near
    return t_far, cos_far


@nb.njit(cache=True, fastmath=_FAST)
def _smallest_root(a: float, b: float, c: float) -> float:
    """Smallest t > 0 solving a t² + 2 b t + c = 0, or inf."""
    if a <= 0.0:
        return np.inf
    disc = b * b - a * c
    if disc < 0.0:
        return np.inf
    s = math.sqrt(disc)
    t = (-b - s) / a
    if t > _T_MIN:
        return t
    t = (-b + s) / a
    if t > _T_MIN:
        return t
    return np.inf


@nb.njit(cache=True, fastmath=_FAST)
def _hit_ellipsoid(
    ox: float,
    oy: float,
    oz: float,
    dx: float,
    dy: float,
    dz: float,
    hx: float,
    hy: float,
    hz: float,
) -> tuple[float, float]:
    # In scaled coordinates q = o/h, e = d/h the ellipsoid is the unit sphere:
    # |q + t e|² = 1  ⇒  (e·e) t² + 2 (q·e) t + (q·q − 1) = 0
    qx, qy, qz = ox / hx, oy / hy, oz / hz
    ex, ey, ez = dx / hx, dy / hy, dz / hz
    t = _smallest_root(
        ex * ex + ey * ey + ez * ez, qx * ex + qy * ey + qz * ez, qx * qx + qy * qy + qz * qz - 1.0
    )
    if not np.isfinite(t):
        return np.inf, 0.0
    # Normal ∝ ∇((x/hx)² + (y/hy)² + (z/hz)²) = (x/hx², y/hy², z/hz²)
    nx = (ox + t * dx) / (hx * hx)
    ny = (oy + t * dy) / (hy * hy)
    nz = (oz + t * dz) / (hz * hz)
    norm = np.sqrt(nx * nx + ny * ny + nz * nz)
    return t, abs(nx * dx + ny * dy + nz * dz) / norm


@nb.njit(cache=True, fastmath=_FAST)
def _hit_cylinder(
    ox: float,
    oy: float,
    oz: float,
    dx: float,
    dy: float,
    dz: float,
    hx: float,
    hy: float,
    hz: float,
) -> tuple[float, float]:
    best = np.inf
    cos = 0.0
    # Side: (x/hx)² + (y/hy)² = 1 with |z| ≤ hz
    qx, qy = ox / hx, oy / hy
    ex, ey = dx / hx, dy / hy
    a = ex * ex + ey * ey
    b = qx * ex + qy * ey
    c = qx * qx + qy * qy - 1.0
    if a > 0.0:
        disc = b * b - a * c
        if disc >= 0.0:
            s = math.sqrt(disc)
            for t in ((-b - s) / a, (-b + s) / a):
                if _T_MIN < t < best and abs(oz + t * dz) <= hz:
                    best = t
                    nx = (ox + t * dx) / (hx * hx)
                    ny = (oy + t * dy) / (hy * hy)
                    cos = abs(nx * dx + ny * dy) / np.sqrt(nx * nx + ny * ny)
    # Caps: z = ±hz with (x/hx)² + (y/hy)² ≤ 1
    if dz != 0.0:
        for zc in (-hz, hz):
            t = (zc - oz) / dz
            if _T_MIN < t < best:
                x = (ox + t * dx) / hx
                y = (oy + t * dy) / hy
                if x * x + y * y <= 1.0:
                    best = t
                    cos = abs(dz)
    return best, cos


@nb.njit(cache=True, fastmath=_FAST)
def _hit(
    k: int,
    px: float,
    py: float,
    pz: float,
    dwx: float,
    dwy: float,
    dwz: float,
    kind: NDArray[np.int64],
    center: FloatArray,
    local_R_world: FloatArray,
    half: FloatArray,
) -> tuple[float, float]:
    """Distance and |cos θ_inc| of the ray (p, d) on primitive k, or (inf, 0)."""
    if kind[k] == PLANE:
        if dwz == 0.0:
            return math.inf, 0.0
        # z(t) = p_z + t d_z = c_z
        t = (center[k, 2] - pz) / dwz
        if t > _T_MIN:
            return t, abs(dwz)
        return math.inf, 0.0
    # Ray in the primitive frame: o' = Rᵀ (o − c), d' = Rᵀ d
    rx = px - center[k, 0]
    ry = py - center[k, 1]
    rz = pz - center[k, 2]
    M = local_R_world[k]
    ox = M[0, 0] * rx + M[0, 1] * ry + M[0, 2] * rz
    oy = M[1, 0] * rx + M[1, 1] * ry + M[1, 2] * rz
    oz = M[2, 0] * rx + M[2, 1] * ry + M[2, 2] * rz
    dx = M[0, 0] * dwx + M[0, 1] * dwy + M[0, 2] * dwz
    dy = M[1, 0] * dwx + M[1, 1] * dwy + M[1, 2] * dwz
    dz = M[2, 0] * dwx + M[2, 1] * dwy + M[2, 2] * dwz
    hx, hy, hz = half[k, 0], half[k, 1], half[k, 2]
    if kind[k] == BOX:
        return _hit_box(ox, oy, oz, dx, dy, dz, hx, hy, hz)
    if kind[k] == ELLIPSOID:
        return _hit_ellipsoid(ox, oy, oz, dx, dy, dz, hx, hy, hz)
    return _hit_cylinder(ox, oy, oz, dx, dy, dz, hx, hy, hz)


@nb.njit(cache=True, fastmath=_FAST)
def _cube_cell(dx: float, dy: float, dz: float, n: int) -> int:
    """Cube-map cell of direction d (see ``cubemap``)."""
    ax, ay, az = abs(dx), abs(dy), abs(dz)
    if ax >= ay and ax >= az:
        face, m, u, v = (0 if dx > 0 else 1), ax, dy, dz
    elif ay >= az:
        face, m, u, v = (2 if dy > 0 else 3), ay, dz, dx
    else:
        face, m, u, v = (4 if dz > 0 else 5), az, dx, dy
    i = min(max(int((u / m + 1.0) * 0.5 * n), 0), n - 1)
    j = min(max(int((v / m + 1.0) * 0.5 * n), 0), n - 1)
    return face * n * n + i * n + j


@nb.njit(cache=True, fastmath=_FAST)
def _cast(
    orig: FloatArray,
    D: FloatArray,
    kind: NDArray[np.int64],
    center: FloatArray,
    local_R_world: FloatArray,
    half: FloatArray,
    n_side: int,
    start: NDArray[np.int64],
    items: NDArray[np.int64],
    always: NDArray[np.int64],
    t_max: float,
) -> tuple[FloatArray, NDArray[np.int64], FloatArray]:
    n = D.shape[0]
    T = np.full(n, np.inf)
    H = np.full(n, -1, dtype=np.int64)
    C = np.zeros(n)
    for i in range(n):
        px, py, pz = orig[i, 0], orig[i, 1], orig[i, 2]
        dx, dy, dz = D[i, 0], D[i, 1], D[i, 2]
        best = t_max
        hit = -1
        cos_best = 0.0
        for m in range(always.shape[0]):
            k = always[m]
            t, c = _hit(k, px, py, pz, dx, dy, dz, kind, center, local_R_world, half)
            if t < best:
                best, hit, cos_best = t, k, c
        if n_side > 0:
            cell = _cube_cell(dx, dy, dz, n_side)
            for m in range(start[cell], start[cell + 1]):
                k = items[m]
                t, c = _hit(k, px, py, pz, dx, dy, dz, kind, center, local_R_world, half)
                if t < best:
                    best, hit, cos_best = t, k, c
        if hit >= 0:
            T[i] = best
            H[i] = hit
            C[i] = cos_best
    return T, H, C
