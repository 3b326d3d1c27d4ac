"""``file://`` playback at wall-clock speed: frames handed on when their last point is
due, with that moment as their arrival, and whole frames dropped when the consumer
falls behind by the live queue's room.  A manual clock makes every time exact."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from dronetrack.errors import ConfigError
from dronetrack.sources.frames import fixed_pose_frame
from dronetrack.sources.paced import PacedSource
from dronetrack.types import Sample

T = 0.1


class Clock:
    """A clock that only sleeping moves; ``sleeps`` records each sleep."""

    def __init__(self, t: float = 100.0) -> None:
        self.t = t
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.t

    def sleep(self, s: float) -> None:
        self.sleeps.append(s)
        self.t += s


class Frames:
    """n frames of T s starting at ``start`` (a recording's clock need not start at 0)."""

    def __init__(self, n: int, start: float = 3.0) -> None:
        self.n, self.start = n, start

    @property
    def period(self) -> float:
        return T

    def __iter__(self) -> Iterator[Sample]:
        for k in range(self.n):
            yield Sample(fixed_pose_frame(self.start + k * T, T, np.zeros((1, 3))))


def test_each_frame_comes_when_its_end_is_due() -> None:
    """τ_k = τ_0 + (e_k − s_0): frame k's end, T (k + 1) after the first frame's start."""
    clock = Clock()
    source = PacedSource(Frames(5), clock=clock, sleep=clock.sleep)
    got = []
    for sample in source:
        got.append((clock(), sample.received))
    due = 100.0 + T * np.arange(1, 6)
    np.testing.assert_allclose([g[0] for g in got], due, atol=1e-12)
    np.testing.assert_allclose([g[1] for g in got], due, atol=1e-12)
    assert max(clock.sleeps) <= 0.05  # slices, so a stop request is seen
    assert source.frames_dropped == 0
    assert source.frames_delivered == 5


def test_a_consumer_behind_by_the_queues_room_loses_whole_frames() -> None:
    """Work of 0.33 s a frame against frames of 0.1 s with room for 2: frame k is
    dropped once frame k + 2 is due (now ≥ τ_k + 0.2 s); the rest come in order."""
    clock = Clock()
    source = PacedSource(Frames(20), max_frames=2, clock=clock, sleep=clock.sleep)
    stamps = []
    for sample in source:
        stamps.append(round(sample.frame.stamp - 3.0, 9))
        clock.t += 0.33
    # By hand: frame 0 at 100.1, done 100.43; frame 1 (due 100.2) dropped (100.4 ≤
    # 100.43), frame 2 (due 100.3) kept, done 100.76; frames 3-4 dropped (100.6, 100.7
    # ≤ 100.76), frame 5 (due 100.6) kept.
    assert stamps[:3] == pytest.approx([0.0, 0.2, 0.5])
    assert source.frames_dropped > 0
    assert source.frames_dropped + source.frames_delivered == 20
    assert np.all(np.diff(stamps) > 0)


def test_the_duration_keeps_the_frames_that_start_within_it() -> None:
    clock = Clock()
    source = PacedSource(Frames(20), duration_s=0.5, clock=clock, sleep=clock.sleep)
    assert len(list(source)) == 5


def test_a_stop_request_ends_the_wait(monkeypatch: pytest.MonkeyPatch) -> None:
    import dronetrack.sources.paced as paced

    clock = Clock()
    calls = iter([False, False, True])
    monkeypatch.setattr(paced, "stop_requested", lambda: next(calls, True))
    assert list(PacedSource(Frames(5), clock=clock, sleep=clock.sleep)) == []


def test_the_queue_needs_room() -> None:
    with pytest.raises(ConfigError, match="room"):
        PacedSource(Frames(1), max_frames=0)
