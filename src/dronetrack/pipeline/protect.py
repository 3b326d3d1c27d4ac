"""What the learning map must not learn (``preprocess.learning``): the balls around
every track that may be a drone and around the turret's target."""

from __future__ import annotations

import numpy as np

from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TRACK_CLASSES, Detections, TrackEstimate, Tracks

__all__ = ["COASTING_EXTENT_M", "protected_balls"]

# A track without a cluster this frame is protected this far around its position [m],
# on top of the margin: the largest drone the models fly is under 1 m across.
COASTING_EXTENT_M = 1.0


def protected_balls(
    tracks: Tracks,
    found: Detections,
    estimate: TrackEstimate,
    margin: float,
    min_p: float = 0.2,
) -> tuple[FloatArray, FloatArray]:
    """Centres (B, 3) and radii (B,) of what the learning map must not learn: each track
    classed drone, or not classed static with p_drone ≥ ``min_p`` (the least of a track
    worth a look, ``control.choose.worth_a_look``), around its cluster (radius
    e/2 + margin, e its largest extent) or, coasting, its position
    (COASTING_EXTENT_M / 2 + margin); and the turret's target when locked and not on a
    static track."""
    static = tracks.classes == TRACK_CLASSES.index("static")
    keep = (tracks.classes == TRACK_CLASSES.index("drone")) | (~static & (tracks.p_drone >= min_p))
    j = tracks.clusters
    has = keep & (j >= 0)
    centres = np.array(tracks.positions, dtype=np.float64)
    extent = np.full(len(tracks), COASTING_EXTENT_M)
    centres[has] = found.centroids[j[has]]
    extent[has] = found.extents[j[has], 0]
    radii = 0.5 * extent + margin
    centres, radii = centres[keep], radii[keep]
    static_lock = bool(np.any(tracks.locked & static))
    if estimate.tracked and not static_lock and np.all(np.isfinite(estimate.position)):
        centres = np.vstack([centres, estimate.position[None, :]])
        radii = np.r_[radii, 0.5 * COASTING_EXTENT_M + margin]
    return centres, radii
