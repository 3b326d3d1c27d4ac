"""Whether a cluster stands alone in its frame, or among others: the *crowded* test.

A drone flies in free space, while a far structure that the map lacks breaks into
fragments a little more than the clustering's ε apart.  A cluster is crowded when
another of the frame's clusters lies within a gap of it:

    |c − c'| − (e + e')/2 ≤ min(g_c, θ_c r)

with c the centroids, e the largest extents, r the range from the sensor, g_c a gap
(twice ε by default, ``pipeline.factory``) and θ_c = 1° (``CROWD_RAD``: two of an
Avia's mean spacings in a frame, 24,000 returns over 70° × 77°, one of a Mid-360's).
Fragments lie a few of the sensor's sample spacings apart in angle, so the gap shrinks
with range as θ_c r; g_c bounds it beyond 2ε / θ_c (115 m for ε = 1 m).  Near the
sensor a cluster a metre away is another object: a person standing beside a drone
hovering 2 m from a Mid-360.

Two stages use it: the detect stage's tentative tracks spend their bounded room on
the clusters that stand alone first (``detect.tentative``), and the classes count
a track's crowded observations (``classify.observe``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Detections

__all__ = ["CROWD_RAD", "crowded", "nearest_gap"]

CROWD_RAD = math.radians(1.0)  # θ_c


def nearest_gap(found: Detections, which: NDArray[np.int64]) -> FloatArray:
    """(K,) the gap from each cluster ``which`` to the nearest other cluster of the frame,
    min over j' ≠ j of |c_j − c_j'| − (e_j + e_j')/2 (e the largest extent) [m]; +inf when
    it is the only one."""
    c, e = found.centroids, found.extents[:, 0]
    gap = np.linalg.norm(c[which, None, :] - c[None, :, :], axis=2) - 0.5 * (
        e[which, None] + e[None, :]
    )
    gap[np.arange(len(which)), which] = np.inf
    out: FloatArray = gap.min(axis=1, initial=np.inf)
    return out


def crowded(
    found: Detections, which: NDArray[np.int64], gap_m: float, sensor: FloatArray | None
) -> NDArray[np.bool_]:
    """(K,) whether each cluster ``which`` is crowded: its nearest gap ≤ min(g_c, θ_c r),
    with g_c = ``gap_m`` and r its range from ``sensor`` (None: the gap is g_c)."""
    gap = nearest_gap(found, which)
    if sensor is None:
        return np.asarray(gap <= gap_m)
    rng = np.linalg.norm(found.centroids[which] - sensor, axis=1)
    return np.asarray(gap <= np.minimum(gap_m, CROWD_RAD * rng))
