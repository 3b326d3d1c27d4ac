"""The detect stage: a frame's foreground points in, candidate targets out.

``CandidateDetector`` is seed 002's Algorithm 1 plus a size check, built from the
cluster features of ``detect.clusters`` (voxel grid, cylindrical ROI, DBSCAN,
centroid, covariance, principal extents, planarity).  It returns ``Detections``;
which candidate to measure is the tracker's choice.  ``SEED002_DETECTOR`` and
``SEED003_DETECTOR`` are the two seeds' settings.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from dronetrack.detect.clusters import (
    Cluster,
    cluster_statistics,
    cylinder_mask,
    dbscan,
    voxel_centroids,
)
from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Detections

__all__ = ["SEED002_DETECTOR", "SEED003_DETECTOR", "CandidateDetector", "detections", "engulfed"]


def detections(clusters: list[Cluster]) -> Detections:
    """The clusters' statistics stacked, in their order."""
    if not clusters:
        return Detections.empty()
    return Detections(
        centroids=np.stack([c.centroid for c in clusters]),
        counts=np.array([c.n for c in clusters], dtype=np.int64),
        extents=np.stack([c.extent for c in clusters]),
        covariances=np.stack([c.covariance for c in clusters]),
        planarity=np.array([c.planarity for c in clusters], dtype=np.float64),
    )


@dataclass(frozen=True, slots=True)
class CandidateDetector:
    """Seed 002's Algorithm 1 plus a size check: voxel-grid centroids (skipped when
    ``voxel_size`` = 0), the cylindrical ROI √((x − cₓ)² + (y − c_y)²) < ``roi_radius``,
    ``z_min`` < z < ``z_max``, DBSCAN, then the clusters whose largest principal
    extent is at most ``max_extent`` [m].  Defaults: 0.1 m voxels (seed 002 §4.1;
    Algorithm 1 says 0.05), no ROI (the pipeline's crop box already bounds the
    foreground), ε = 0.5 m with 3 points (Algorithm 1), a 2 m drone-size limit."""

    voxel_size: float = 0.1
    roi_center_xy: tuple[float, float] = (0.0, 0.0)
    roi_radius: float = math.inf
    z_min: float = -math.inf
    z_max: float = math.inf
    eps: float = 0.5
    min_points: int = 3
    max_extent: float = 2.0

    def __post_init__(self) -> None:
        for name in ("roi_radius", "eps", "min_points", "max_extent"):
            value = getattr(self, name)
            if not value > 0.0:
                raise ConfigError(f"{name} must be positive, got {value}")
        if self.voxel_size < 0.0 or not self.z_min < self.z_max:
            raise ConfigError(
                f"need voxel_size ≥ 0 and z_min < z_max, got {self.voxel_size}, "
                f"{self.z_min}, {self.z_max}"
            )

    def __call__(self, points: FloatArray) -> Detections:
        """The candidates in ``points`` (M, 3) [m], in DBSCAN's label order, with the
        points of the clusters larger than ``max_extent`` (``Detections.oversized``)."""
        pts = voxel_centroids(points, self.voxel_size) if self.voxel_size > 0 else points
        pts = pts[cylinder_mask(pts, self.roi_center_xy, self.roi_radius, self.z_min, self.z_max)]
        labels = dbscan(pts, self.eps, self.min_points)
        st = cluster_statistics(pts, labels)
        ok = st.extents[:, 0] <= self.max_extent
        # the points of the clusters too large to be a candidate (label j is cluster j)
        oversized = pts[np.isin(labels, np.flatnonzero(~ok))]
        if not ok.any():
            return Detections.empty(oversized)
        return Detections(
            st.centroids[ok],
            st.counts[ok],
            st.extents[ok],
            st.covariances[ok],
            st.planarity[ok],
            st.lows[ok],
            oversized,
        )


SEED002_DETECTOR = CandidateDetector()
# Seed 003 gives no clustering parameters: ε = 0.5 m as seed 002, and single points
# count, as its controller reacts to a single return; no voxels, ROI or size limit.
SEED003_DETECTOR = CandidateDetector(voxel_size=0.0, min_points=1, max_extent=math.inf)


def engulfed(found: Detections, positions: FloatArray, radius: float) -> NDArray[np.bool_]:
    """(K,) whether a point of the frame's clusters too large to be a candidate
    (``Detections.oversized``) lies within ``radius`` [m] of each of ``positions``
    (K, 3): min_i |p_i − p_k| ≤ radius, the place is part of something larger than a
    drone."""
    big = found.oversized
    if len(big) == 0 or len(positions) == 0:
        return np.zeros(len(positions), dtype=bool)
    d, _ = cKDTree(big).query(np.asarray(positions, dtype=np.float64), distance_upper_bound=radius)
    out: NDArray[np.bool_] = np.isfinite(d)
    return out
