"""Hand-built ``Tracks`` for the evaluation tests."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.types import Tracks


def hand_tracks(
    ids: Sequence[int],
    positions: ArrayLike,
    classes: Sequence[int],
    updated: Sequence[bool] | None = None,
    in_view: Sequence[bool] | None = None,
) -> Tracks:
    """Tracks at ``positions`` (K, 3), at rest, born at 0, with these classes; every one
    updated this frame and in the sensor's view unless ``updated``, ``in_view`` say
    otherwise."""
    k = len(ids)
    return Tracks(
        ids=np.array(ids, dtype=np.int64),
        positions=np.asarray(positions, dtype=float).reshape(k, 3),
        velocities=np.zeros((k, 3)),
        covariances=np.tile(np.eye(6), (k, 1, 1)),
        born=np.zeros(k),
        updated=np.ones(k, dtype=bool) if updated is None else np.array(updated, dtype=bool),
        hovered=np.zeros(k, dtype=bool),
        locked=np.zeros(k, dtype=bool),
        classes=np.array(classes, dtype=np.int64),
        in_view=np.ones(k, dtype=bool) if in_view is None else np.array(in_view, dtype=bool),
    )
