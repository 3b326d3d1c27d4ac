"""A recording as the run loop's Source: its frames in order, with its ground truth.

The poses are the recording's own (its /tf, or the fixed pose a reader assumed);
the truth, when the recording has one, is the target's position at each frame's
end, and the returns near it count as the target's.
"""

from __future__ import annotations

from collections.abc import Iterator

from dronetrack.sources.recordings.recording import Recording
from dronetrack.sources.truth import RecordedTruth
from dronetrack.types import Sample

__all__ = ["RecordingSource"]


class RecordingSource:
    """Every frame of ``recording``, each with its ground truth (if any).  ``radius``: a
    return within it of the true position counts as the target's [m]."""

    def __init__(self, recording: Recording, radius: float) -> None:
        self.recording = recording
        self.radius = radius

    @property
    def period(self) -> float:
        return self.recording.period

    def __len__(self) -> int:
        return int(getattr(self.recording, "n_frames", 0))

    def __iter__(self) -> Iterator[Sample]:
        truth = self.recording.ground_truth
        for frame in self.recording.frames():
            if truth is None:
                yield Sample(frame)
            else:
                yield Sample(frame, RecordedTruth(truth, truth.at(frame.end)[0], self.radius))
