"""Distance from each query point to its nearest neighbour in a small point set."""

from __future__ import annotations

import numba as nb
import numpy as np
from scipy.spatial import cKDTree

from dronetrack.geometry import FloatArray

__all__ = ["nearest_distances"]

BRUTE_FORCE_MAX = 64  # up to this many points a direct scan beats building a k-d tree


def nearest_distances(queries: FloatArray, points: FloatArray) -> FloatArray:
    """min_j ‖q_i − p_j‖ for queries (N, 3) against points (M ≥ 1, 3)."""
    if len(points) <= BRUTE_FORCE_MAX:
        return _brute_force(
            np.ascontiguousarray(queries, dtype=np.float64),
            np.ascontiguousarray(points, dtype=np.float64),
        )
    dist, _ = cKDTree(points).query(queries, k=1)
    out: FloatArray = np.asarray(dist, dtype=np.float64)
    return out


@nb.njit(cache=True, fastmath=True)
def _brute_force(Q: FloatArray, P: FloatArray) -> FloatArray:
    n, m = Q.shape[0], P.shape[0]
    out = np.empty(n)
    for i in range(n):
        best = np.inf
        for j in range(m):
            dx = Q[i, 0] - P[j, 0]
            dy = Q[i, 1] - P[j, 1]
            dz = Q[i, 2] - P[j, 2]
            d2 = dx * dx + dy * dy + dz * dz
            if d2 < best:
                best = d2
        out[i] = np.sqrt(best)
    return out
