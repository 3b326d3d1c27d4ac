"""A recording as the run loop's Source: its frames in order, with its ground truth.

The poses are the recording's own (its /tf, or the fixed pose a reader assumed);
the truth, when the recording has one, is the target's position at each frame's
end, and the returns near it count as the target's.
"""

from __future__ import annotations

from collections.abc import Iterator

import numba as nb
import numpy as np

from dronetrack.geometry.transforms import FloatArray
from dronetrack.sources.recording import GroundTruth, Recording
from dronetrack.types import Frame, Sample

__all__ = ["RecordedTruth", "RecordingSource", "target_point_count"]


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


class RecordedTruth:
    """A recorded frame's truth (``types.Truth``): the position at the frame's end, and the
    returns within ``radius`` of the track during the frame."""

    __slots__ = ("radius", "target_position", "track")

    def __init__(self, track: GroundTruth, position: FloatArray, radius: float) -> None:
        self.track = track
        self.target_position = position
        self.radius = radius

    def target_returns(self, frame: Frame, world: FloatArray) -> int:
        """-1 (unknown) where the truth is, or the frame could not be placed in the world."""
        known = bool(np.all(np.isfinite(self.target_position)))
        if not known or len(world) != len(frame):
            return -1
        return target_point_count(frame, world, self.track, self.radius)


def target_point_count(frame: Frame, world: FloatArray, truth: GroundTruth, radius: float) -> int:
    """Returns of the frame within ``radius`` of the true position at each return's time;
    ``world`` (N, 3) are the frame's points in the world frame.

    The truth is taken as moving linearly between its values at the frame's start
    and end (exact when its samples are the frame ends, as in our recordings).
    """
    if len(frame) == 0:
        return 0
    g0, g1 = truth.at([frame.stamp, frame.end])
    return int(_count_near(world, frame.t, frame.stamp, frame.duration, g0, g1, radius))


@nb.njit(cache=True)
def _count_near(
    W: FloatArray, t: FloatArray, t0: float, T: float, g0: FloatArray, g1: FloatArray, r: float
) -> int:
    """Points of W (N, 3) within r of g(t_i) = g0 + u_i (g1 − g0), u_i = (t_i − t0) / T ∈ [0, 1]."""
    n = 0
    r2 = r * r
    for i in range(W.shape[0]):
        u = min(max((t[i] - t0) / T, 0.0), 1.0)
        d2 = 0.0
        for k in range(3):
            d = W[i, k] - (g0[k] + u * (g1[k] - g0[k]))
            d2 += d * d
        if d2 <= r2:
            n += 1
    return n
