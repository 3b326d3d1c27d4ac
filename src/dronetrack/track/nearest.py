"""Distance from each query point to its nearest neighbour in a small point set."""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from dronetrack.geometry.transforms import FloatArray

__all__ = ["nearest_distances"]

# A direct scan costs ~0.75 ns per query-point pair on one core, a k-d tree query
# (with the build shared out) 1-2.5 µs, so the scan wins up to about 1000 points
# whatever the number of queries (measured at 5000 and 100 000 queries).
BRUTE_FORCE_MAX_POINTS = 1000


def nearest_distances(queries: FloatArray, points: FloatArray) -> FloatArray:
    """min_j ‖q_i − p_j‖ for queries (N, 3) against points (M ≥ 1, 3)."""
    if len(points) <= BRUTE_FORCE_MAX_POINTS:
        # Single precision relative to a point of the set: 0.1 mm resolution within
        # 1 km, and twice the throughput of doubles.
        ref = points[0]
        return _brute_force(
            np.ascontiguousarray(queries - ref, dtype=np.float32),
            np.ascontiguousarray(points - ref, dtype=np.float32),
        )
    dist, _ = cKDTree(points).query(queries, k=1)
    out: FloatArray = np.asarray(dist, dtype=np.float64)
    return out


@nb.njit(cache=True, fastmath=True)
def _brute_force(Q: NDArray[np.float32], P: NDArray[np.float32]) -> FloatArray:
    n, m = Q.shape[0], P.shape[0]
    out = np.empty(n)
    for i in range(n):
        best = np.float32(np.inf)
        for j in range(m):
            dx = Q[i, 0] - P[j, 0]
            dy = Q[i, 1] - P[j, 1]
            dz = Q[i, 2] - P[j, 2]
            best = min(best, dx * dx + dy * dy + dz * dz)
        out[i] = np.sqrt(best)
    return out
