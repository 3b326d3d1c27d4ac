"""The detect stage of every tracking frame, as the pipeline holds it: the clustering,
the tentative tracks and their confirmation, the history of the tracker's lock on them
and every confirmed object's track (``Acquisition``)."""

from __future__ import annotations

from dataclasses import dataclass, field

from dronetrack.detect.candidates import CandidateDetector
from dronetrack.detect.lock import LockBook
from dronetrack.detect.tentative import TentativeTracks
from dronetrack.geometry.transforms import FloatArray
from dronetrack.track.base import ObjectTracker
from dronetrack.types import Candidates, Detections

__all__ = ["Acquisition"]


@dataclass(frozen=True, slots=True)
class Acquisition:
    """The detect stage of every tracking frame: clustering, then tentative tracks, the
    history of the tracker's lock on them (``detect.lock``), and every confirmed
    object's track (``track.multi``)."""

    detector: CandidateDetector
    tracks: TentativeTracks
    objects: ObjectTracker | None = None
    lock: LockBook = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "lock", LockBook(self.tracks.settings))

    def step(
        self, t: float, points: FloatArray, sensor: FloatArray | None = None
    ) -> tuple[Detections, Candidates]:
        """The clusters of the foreground ``points`` at ``t``, seen from ``sensor`` (3,),
        and the confirmed candidates."""
        found = self.detector(points)
        return found, self.tracks.update(t, found, sensor)

    def reset(self) -> None:
        self.tracks.reset()
        self.lock.reset()
        if self.objects is not None:
            self.objects.reset()
