"""A cube-map index of a static scene: which primitives each direction can meet.

Seen from a point, every primitive lies inside a cone around the direction to
its centre, sin(half angle) = (r + slack) / distance, where r bounds the shape
and ``slack`` allows the ray origins to wander that far from the point (a
turret moves its sensor by centimetres).  Directions are binned on the six
faces of a cube, n × n cells each: face f = 2a + (d_a < 0) for the dominant
axis a, and cell (i, j) from u = d_b / |d_a|, v = d_c / |d_a|.  A primitive is
listed in every cell whose own cone (centre direction, radius to its farthest
corner) overlaps its cone; a ray then tests only its cell's list and the
primitives seen from everywhere (planes, and shapes that hold the point).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray, unit
from dronetrack.sim.primitives import PLANE, Primitives

__all__ = ["CubeMapIndex", "build_cube_map", "cube_cells"]


@dataclass(frozen=True, slots=True)
class CubeMapIndex:
    """Primitive lists per direction cell, valid for ray origins within ``slack`` of ``origin``."""

    origin: FloatArray  # (3,)
    slack: float  # [m]
    n: int  # cells per face side
    start: NDArray[np.int64]  # (6 n² + 1,) CSR offsets into items
    items: NDArray[np.int64]  # primitive indices, cell by cell
    always: NDArray[np.int64]  # primitives every ray tests

    def covers(self, origin: FloatArray, slack: float) -> bool:
        """Whether rays from within ``slack`` of ``origin`` may use this index."""
        return float(np.linalg.norm(origin - self.origin)) + slack <= self.slack


def _face_axes(face: int) -> tuple[int, float, int, int]:
    a = face // 2
    return a, (1.0 if face % 2 == 0 else -1.0), (a + 1) % 3, (a + 2) % 3


def cube_cells(n: int) -> tuple[FloatArray, FloatArray]:
    """Centre directions (6 n², 3) of the cells and each cell's angular radius (6 n²,) [rad]."""
    edges = np.linspace(-1.0, 1.0, n + 1)
    mids = 0.5 * (edges[:-1] + edges[1:])
    centres = np.empty((6, n, n, 3))
    radius = np.empty((6, n, n))
    for face in range(6):
        a, sign, b, c = _face_axes(face)

        def on_face(
            u: FloatArray, v: FloatArray, a: int = a, sign: float = sign, b: int = b, c: int = c
        ) -> FloatArray:
            d = np.zeros((*np.shape(u), 3))
            d[..., a] = sign
            d[..., b] = u
            d[..., c] = v
            return unit(d)

        U, V = np.meshgrid(mids, mids, indexing="ij")
        centre = on_face(U, V)
        centres[face] = centre
        # The farthest point of a cell from its centre is one of its corners.
        worst = np.zeros((n, n))
        for du in (0, 1):
            for dv in (0, 1):
                Uc, Vc = np.meshgrid(edges[du : du + n], edges[dv : dv + n], indexing="ij")
                cos = np.clip(np.sum(on_face(Uc, Vc) * centre, axis=-1), -1.0, 1.0)
                worst = np.maximum(worst, np.arccos(cos))
        radius[face] = worst
    return centres.reshape(-1, 3), radius.reshape(-1)


def build_cube_map(
    prims: Primitives,
    origin: FloatArray,
    slack: float,
    t_max: float = np.inf,
    n: int = 32,
    margin: FloatArray | None = None,
) -> CubeMapIndex:
    """Index ``prims`` for rays from within ``slack`` of ``origin`` and no longer than ``t_max``.

    ``margin`` (P,): how far each primitive may move from where it is [m] (swaying
    crowns); the index then holds for the primitives anywhere within it.
    """
    o = np.asarray(origin, dtype=np.float64)
    v = prims.center - o
    dist = np.linalg.norm(v, axis=1)
    r = prims.bound_radius + slack
    if margin is not None:
        r = r + margin
    plane = prims.kind == PLANE
    holds = ~plane & (dist <= r)
    reachable = dist - r <= t_max
    always = np.flatnonzero((plane | holds) & reachable)
    cone = np.flatnonzero(~plane & ~holds & reachable)
    centres, cell_radius = cube_cells(n)
    if len(cone):
        half = np.arcsin(np.clip(r[cone] / dist[cone], 0.0, 1.0))
        axis = v[cone] / dist[cone, None]
        # Overlap when angle(cell centre, axis) ≤ half angle + cell radius.
        limit = np.cos(np.minimum(half[:, None] + cell_radius[None, :], np.pi))
        prim_idx, cell_idx = np.nonzero(axis @ centres.T >= limit)
    else:
        prim_idx = cell_idx = np.empty(0, dtype=np.int64)
    order = np.argsort(cell_idx, kind="stable")
    counts = np.bincount(cell_idx, minlength=6 * n * n)
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    return CubeMapIndex(
        origin=o.copy(),
        slack=float(slack),
        n=n,
        start=start,
        items=cone[prim_idx[order]].astype(np.int64),
        always=always.astype(np.int64),
    )
