"""What the learning map must not learn (pipeline/protect.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from dronetrack.pipeline.protect import protected_balls
from dronetrack.types import TRACK_CLASSES, Detections, TrackEstimate
from track_helpers import hand_tracks


def test_only_what_may_be_a_drone_is_protected() -> None:
    """A drone-class track, an unknown one, one the classes hold unlikely (part of the
    world, p_drone below a look's 0.2), a static one, and the turret's target locked on
    nothing the tracks hold: protected are the first two and the target."""
    drone, unknown, static = (TRACK_CLASSES.index(c) for c in ("drone", "unknown", "static"))
    k = 4
    positions = np.array([[50.0, 0, 10], [60.0, 5, 12], [80.0, -5, 3], [90.0, 10, 2]])
    tracks = replace(
        hand_tracks(range(1, k + 1), positions, [drone, unknown, unknown, static]),
        clusters=np.arange(k),
        p_drone=np.array([0.98, 0.5, 0.05, 0.01]),
    )
    found = Detections(
        positions, np.full(k, 5), np.tile([0.4, 0.2, 0.1], (k, 1)), np.zeros((k, 3, 3)), np.zeros(k)
    )
    target = np.array([30.0, 0.0, 8.0])
    estimate = TrackEstimate(1.0, target, np.zeros(3), True, 0.1)
    centres, radii = protected_balls(tracks, found, estimate, 0.5, min_p=0.2)
    np.testing.assert_allclose(centres, np.vstack([positions[:2], target]))
    np.testing.assert_allclose(radii[:2], 0.2 + 0.5)
    # at min_p 0 every track not static is protected, as a look would take any
    centres, _ = protected_balls(tracks, found, estimate, 0.5, min_p=0.0)
    np.testing.assert_allclose(centres, np.vstack([positions[:3], target]))
