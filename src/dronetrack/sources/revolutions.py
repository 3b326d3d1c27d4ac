"""A spinning head's stream cut into revolutions: one frame from one start of a
revolution to the next.

The stream's batches say where revolutions start (``PointBatch.cuts``: the VLP-16
link finds where the azimuth passes the cut angle, ``velodyne_timing``).  Frame k
holds every point with

    c_k ≤ t < c_{k+1}

for consecutive starts c_k, so its period is the revolution's own (60/rpm, give or
take the motor's wander), and it is complete as soon as the next start is known: the
firing that passes the cut angle is the next frame's.  The points before the first
start are dropped and counted (``before_start``), and so are points older than the
open frame (``late_points``: a packet delivered out of order after its revolution
was handed on).  A revolution with no return is still a frame, with no points.
"""

from __future__ import annotations

import numpy as np

from dronetrack.sources.assembly import PointBatch, StreamFrame

__all__ = ["RevolutionAssembler"]


def _join(parts: list[PointBatch]) -> PointBatch:
    if not parts:
        u8 = np.zeros(0, np.uint8)
        return PointBatch(np.zeros((0, 3)), np.zeros(0, np.int64), u8, u8)
    return PointBatch(
        np.concatenate([p.xyz for p in parts]).reshape(-1, 3),
        np.concatenate([p.t_ns for p in parts]).astype(np.int64),
        np.concatenate([p.reflectivity for p in parts]).astype(np.uint8),
        np.concatenate([p.line for p in parts]).astype(np.uint8),
    )


class RevolutionAssembler:
    """Cuts a time-ordered point stream into frames at its batches' ``cuts`` (the
    module docstring).  ``t0_ns``: the first start (None before it).  Counters:
    ``before_start``, ``late_points``; ``empty_periods`` is always 0 (a revolution
    without points is handed on as an empty frame)."""

    def __init__(self) -> None:
        self.t0_ns: int | None = None
        self.before_start = 0
        self.late_points = 0
        self.empty_periods = 0
        self._start: int | None = None  # the open frame's start [ns]
        self._index = -1
        self._parts: list[PointBatch] = []

    def push(self, batch: PointBatch) -> list[StreamFrame]:
        """Add ``batch``; the frames its cuts complete, in order."""
        if np.any(np.diff(batch.t_ns) < 0):
            batch = batch.take(np.argsort(batch.t_ns, kind="stable"))
        if self._start is not None and len(batch):
            late = batch.t_ns < self._start
            if late.any():
                self.late_points += int(late.sum())
                batch = batch.take(~late)
        done: list[StreamFrame] = []
        pos = 0
        for cut in sorted(batch.cuts):
            if self._start is not None and cut <= self._start:
                continue
            j = int(np.searchsorted(batch.t_ns, cut, side="left"))
            if self._start is None:
                self.before_start += j - pos
                self.t0_ns = cut
            else:
                self._parts.append(batch.take(slice(pos, j)))
                done.append(self._close(cut))
            pos = j
            self._start = cut
            self._index += 1
        if self._start is None:
            self.before_start += len(batch) - pos
        elif pos < len(batch):
            self._parts.append(batch.take(slice(pos, None)))
        return done

    def _close(self, end: int) -> StreamFrame:
        assert self._start is not None
        frame = StreamFrame(self._index, self._start, end - self._start, _join(self._parts))
        self._parts = []
        return frame

    def flush(self) -> list[StreamFrame]:
        """Nothing: the open revolution's end is not known until the next one starts."""
        return []
