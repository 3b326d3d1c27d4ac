"""The tracker interface the pipeline drives; the trackers themselves are in
``track.particle``, ``track.sphere_kalman`` and ``track.cluster_kalman``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Candidates, Detections, TrackEstimate, Tracks

__all__ = ["CandidateStart", "ObjectTracker", "PositionStart", "SelfStart", "Tracker"]


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


@runtime_checkable
class PositionStart(Protocol):
    """A tracker that can be started on a known position (the Kalman filters), as seed 000
    started its EKF baselines on the drone's first clean view."""

    def initialize(self, position: FloatArray) -> None:
        """Start the track at ``position`` (3,) [m], at rest, with the initial covariance."""
        ...


@runtime_checkable
class CandidateStart(Protocol):
    """A tracker that starts (and, once lost, restarts) on the detect stage's confirmed
    candidates rather than on its own start region."""

    def acquire(self, candidates: Candidates) -> None:
        """Take this frame's confirmed candidates (best first, at the frame's end); the
        pipeline calls it only while the tracker is not locked, before ``step``, which
        applies them at the frame's end."""
        ...


@runtime_checkable
class SelfStart(Protocol):
    """A tracker that can also start by itself on the first non-empty frame (the
    Kalman filters, as the seeds run them); off when the detect stage's candidates
    start it, so that a lone false return cannot."""

    self_start: bool


class ObjectTracker(Protocol):
    """Every confirmed object's track (``track.multi``), beside the one tracker the
    turret follows."""

    def step(
        self,
        t: float,
        found: Detections,
        confirmed: Candidates,
        t_meas: float | None = None,
        in_view: Callable[[FloatArray], NDArray[np.bool_]] | None = None,
        floor: Callable[[FloatArray], FloatArray] | None = None,
    ) -> Tracks:
        """Take the clusters ``found`` of the frame ending at ``t`` (describing the time
        ``t_meas``) and the detect stage's confirmed candidates; the tracks after it.
        ``in_view`` tells which positions the sensor saw this frame (None: all);
        ``floor`` the ground's height under points (K, 2), which no track sinks below
        (NaN: unknown; None: no bound)."""
        ...

    def snapshot(self, estimate: TrackEstimate | None = None) -> Tracks:
        """The tracks as they stand, the one at a locked ``estimate`` marked locked."""
        ...

    def note_lock(self, tracks: Tracks, estimate: TrackEstimate) -> None:
        """The turret's tracker after a frame: the track it holds (``tracks.locked``)
        and its estimate."""
        ...

    def note_unlikely(self, ids: NDArray[np.int64]) -> None:
        """The tracks the classes hold no drone after a frame: at the cap they die first."""
        ...

    @property
    def resting(self) -> NDArray[np.int64]:
        """The identities of ended tracks whose lives an heir may take (kept meanwhile)."""
        ...

    @property
    def heirs(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """(new identities, the resting ones whose lives they take) of the last step."""
        ...

    def reset(self) -> None:
        """Forget every track."""
        ...
