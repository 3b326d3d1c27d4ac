"""Which objects the turret may serve: the confirmed candidates of tracks not classed
static, and whether the target held is a static one (``classify``).

A candidate of the detect stage (a confirmed tentative track) and a track of the track
layer (``track.multi``) meet in the frame's cluster: the candidate's position is its
cluster's centroid, and a track records the cluster that updated it.  A static-class
track (an object the background map lacks: a far building's edge, a parked car) is
never offered to the tracker, and a lock on one is given up as soon as its track is
classed static, so the turret never holds one for longer than a frame after that.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TRACK_CLASSES, Candidates, Detections, Tracks

__all__ = ["STATIC", "candidate_tracks", "held_track", "not_static"]

STATIC = TRACK_CLASSES.index("static")
_SAME = 1e-9  # a candidate is its cluster's centroid, to the bit


def candidate_tracks(candidates: Candidates, found: Detections, tracks: Tracks) -> NDArray[np.intp]:
    """(K,) the index into ``tracks`` of the track each candidate's cluster updated, −1
    where none did."""
    out = np.full(len(candidates), -1, dtype=np.intp)
    if len(candidates) == 0 or len(found) == 0 or len(tracks) == 0:
        return out
    cluster = candidates.clusters.astype(np.intp)
    if np.any(cluster < 0):  # not recorded by the detect stage: found by position
        gap = np.linalg.norm(candidates.positions[:, None, :] - found.centroids[None, :, :], axis=2)
        nearest = np.argmin(gap, axis=1)
        exact = gap[np.arange(len(candidates)), nearest] <= _SAME
        cluster = np.where(exact, nearest, -1)
    # owner[j]: the track cluster j updated
    owner = np.full(len(found), -1, dtype=np.intp)
    took = tracks.clusters >= 0
    owner[tracks.clusters[took]] = np.flatnonzero(took)
    has = cluster >= 0
    out[has] = owner[cluster[has]]
    return out


def not_static(candidates: Candidates, found: Detections, tracks: Tracks) -> Candidates:
    """The candidates whose track is not classed static, in their order."""
    owner = candidate_tracks(candidates, found, tracks)
    static = np.zeros(len(candidates), dtype=bool)
    has = owner >= 0
    static[has] = tracks.classes[owner[has]] == STATIC
    return candidates.take(np.flatnonzero(~static))


def held_track(tracks: Tracks, position: FloatArray, within: float) -> int:
    """The index of the track nearest ``position`` within ``within`` [m], −1 if none."""
    if len(tracks) == 0:
        return -1
    gap = np.linalg.norm(tracks.positions - position, axis=1)
    k = int(np.argmin(gap))
    return k if gap[k] <= within else -1
