"""Outlier removal on the (few) foreground points, as PCL's filters do it.

Radius: keep a point with at least ``min_neighbors`` other points within ``radius``.
Statistical: keep a point whose mean distance to its ``k`` nearest neighbours is
at most mean + ``std_mul`` · std of that statistic over all points.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from dronetrack.geometry.transforms import FloatArray

__all__ = ["radius_outlier_mask", "statistical_outlier_mask"]


def radius_outlier_mask(points: FloatArray, radius: float, min_neighbors: int) -> NDArray[np.bool_]:
    """Points (N, 3) to keep: those with ≥ ``min_neighbors`` others within ``radius``."""
    if len(points) == 0:
        return np.zeros(0, dtype=bool)
    counts = cKDTree(points).query_ball_point(points, radius, return_length=True)
    mask: NDArray[np.bool_] = (np.asarray(counts) - 1) >= min_neighbors
    return mask


def statistical_outlier_mask(points: FloatArray, k: int, std_mul: float) -> NDArray[np.bool_]:
    """Points (N, 3) to keep: mean k-NN distance d̄_i ≤ mean(d̄) + std_mul · std(d̄)."""
    n = len(points)
    if n <= k:
        return np.ones(n, dtype=bool)
    dist, _ = cKDTree(points).query(points, k=k + 1)  # the first neighbour is the point itself
    mean_d = dist[:, 1:].mean(axis=1)
    mask: NDArray[np.bool_] = mean_d <= mean_d.mean() + std_mul * mean_d.std()
    return mask
