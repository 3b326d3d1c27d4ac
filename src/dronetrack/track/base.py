"""The tracker interface the pipeline drives; the trackers themselves are in
``track.particle``, ``track.sphere_kalman`` and ``track.cluster_kalman``."""

from __future__ import annotations

from typing import Protocol

from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TrackEstimate

__all__ = ["Tracker"]


class Tracker(Protocol):
    """Anything the pipeline can feed with foreground points."""

    @property
    def period(self) -> float:
        """The filter period T [s]."""
        ...

    def step(self, t: float, points: FloatArray, steps: int) -> TrackEstimate:
        """Predict ``steps`` periods (0 for a repeated frame), update with ``points`` (M, 3)."""
        ...

    def reset(self) -> None:
        """Start again from the initial belief."""
        ...
