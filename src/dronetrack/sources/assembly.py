"""Live streams into frames: points cut into integration periods by their own times,
and the sensor's pose during each frame from the turret's measured joint angles.

A LiDAR streams packets of a few dozen to a hundred points, each point with its
time.  A frame is every point whose time falls in one integration period:

    k(t) = ⌊(t − t₀) / T⌋                  the frame of a point at time t [ns]

with t₀ the first point's time and T the integration time (100 ms by default).
Frames are cut by the points' times, not by when packets arrive, so a late or
bunched packet still lands in its own frame.  A frame is complete once a point of
a later frame arrives, or a firing of a later frame with no return (a batch's
``firings``: where the sensor sees open sky, the next return may be tens of
milliseconds away, while its packets keep coming); the stream is in time order
(each batch is sorted by time first), so nothing more can join it.
A point older than the open frame (a packet delivered out of order after its
frame was handed on) is dropped and counted, and so are the periods that passed
with no point at all (every packet of a frame lost).

The turret's joints are read as the frames come in.  ``PoseHistory`` keeps the
recent time-stamped readings and gives the sensor's pose at any time in the frame
by the mount kinematics (``geometry.mount.sensor_poses``), the joint angles
interpolated linearly between readings.  Beyond the newest reading they move on
at its measured rates for at most ``lead_s`` (0 by default), then hold:

    q(t) = q_k + ω_k · min(t − t_k, lead_s)     for t > t_k, the newest reading

so a frame whose last milliseconds came after the newest reading is not bent
where the turret slews.
"""

from __future__ import annotations

import logging
from collections import Counter, deque
from collections.abc import Iterable, Iterator
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError, InputError
from dronetrack.geometry.mount import MountGeometry, sensor_poses
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Frame, TurretState

__all__ = ["FrameAssembler", "PointBatch", "PoseHistory", "StreamFrame", "cut_by_time"]

log = logging.getLogger(__name__)

NS = 1_000_000_000  # nanoseconds per second


@dataclass(frozen=True, slots=True)
class PointBatch:
    """Points as a decoder gives them, in time order: xyz (N, 3) [m] in the sensor
    frame, t_ns (N,) int64 [ns], reflectivity (N,) and line (N,) uint8.

    ``firings``: the times [ns] of the first and the last firing in the packets the
    points came from, with a return or not (None: not known, the points' own times
    stand for them).  A sensor's packets carry its firings without a return too, so
    they tell that time has passed where no point came back (open sky).

    ``cuts``: times [ns] within those firings at which a new frame starts, in order
    (a spinning head's revolutions, ``revolutions.RevolutionAssembler``); empty for a
    stream cut by time.
    """

    xyz: FloatArray
    t_ns: NDArray[np.int64]
    reflectivity: NDArray[np.uint8]
    line: NDArray[np.uint8]
    firings: tuple[int, int] | None = None
    cuts: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        n = len(self.t_ns)
        if self.xyz.shape != (n, 3) or self.reflectivity.shape != (n,) or self.line.shape != (n,):
            raise InputError(
                f"a point batch needs xyz (N, 3) and N times, reflectivities and lines; got "
                f"{self.xyz.shape}, {self.t_ns.shape}, {self.reflectivity.shape}, {self.line.shape}"
            )

    def __len__(self) -> int:
        return len(self.t_ns)

    def take(self, sel: slice | NDArray[np.intp] | NDArray[np.bool_]) -> PointBatch:
        """The points ``sel``, from the same packets (the same ``firings`` and ``cuts``)."""
        return PointBatch(
            self.xyz[sel],
            self.t_ns[sel],
            self.reflectivity[sel],
            self.line[sel],
            self.firings,
            self.cuts,
        )

    @property
    def first_ns(self) -> int | None:
        """The batch's earliest time: its first firing's, else its first point's."""
        if self.firings is not None:
            return self.firings[0]
        return int(self.t_ns.min()) if len(self) else None

    @property
    def last_ns(self) -> int | None:
        """The batch's latest time: its last firing's, else its last point's."""
        if self.firings is not None:
            return self.firings[1]
        return int(self.t_ns.max()) if len(self) else None


@dataclass(frozen=True, slots=True)
class StreamFrame:
    """One integration period of the stream: frame ``index`` k covers
    [start_ns, start_ns + period_ns)."""

    index: int
    start_ns: int
    period_ns: int
    points: PointBatch


def _concat(parts: list[PointBatch]) -> PointBatch:
    return PointBatch(
        np.concatenate([p.xyz for p in parts]).reshape(-1, 3),
        np.concatenate([p.t_ns for p in parts]).astype(np.int64),
        np.concatenate([p.reflectivity for p in parts]).astype(np.uint8),
        np.concatenate([p.line for p in parts]).astype(np.uint8),
    )


class FrameAssembler:
    """Cuts a time-ordered point stream into frames of ``period_s`` by the points' times.

    ``t0_ns``: the time of frame 0's start; the first point's time if None.
    Counters: ``late_points`` (dropped, older than the open frame) and
    ``empty_periods`` (periods with no point between two frames handed on).
    """

    def __init__(self, period_s: float, t0_ns: int | None = None) -> None:
        if not period_s > 0:
            raise ConfigError(f"the integration time must be positive, got {period_s} s")
        self.period_ns = round(period_s * NS)
        self.t0_ns = t0_ns
        self.late_points = 0
        self.empty_periods = 0
        self._open: int | None = None  # index of the frame being filled
        self._parts: list[PointBatch] = []
        self._last_done: int | None = None

    def push(self, batch: PointBatch) -> list[StreamFrame]:
        """Add ``batch``; the frames it completes, in order."""
        if len(batch) == 0:
            return self._passed(batch)
        if np.any(np.diff(batch.t_ns) < 0):  # a batch out of order: put it in time order
            batch = batch.take(np.argsort(batch.t_ns, kind="stable"))
        if self.t0_ns is None:
            self.t0_ns = int(batch.t_ns[0])
        # k(t) = ⌊(t − t₀) / T⌋
        k = (batch.t_ns - self.t0_ns) // self.period_ns
        # the earliest frame a point may still join: the open one, else the next one
        floor = self._open
        if floor is None and self._last_done is not None:
            floor = self._last_done + 1
        if floor is not None:
            late = k < floor
            if late.any():
                self.late_points += int(late.sum())
                batch, k = batch.take(~late), k[~late]
                if len(batch) == 0:
                    return self._passed(batch)
        done: list[StreamFrame] = []
        # The batch is in time order: split it where k changes.
        cuts = np.flatnonzero(np.diff(k)) + 1
        for sel, kk in zip(
            np.split(np.arange(len(k)), cuts), k[np.r_[0, cuts]].tolist(), strict=True
        ):
            if self._open is not None and kk != self._open:
                done.append(self._close())
            self._open = kk
            self._parts.append(batch.take(sel))
        return done + self._passed(batch)

    def _passed(self, batch: PointBatch) -> list[StreamFrame]:
        """The open frame, if ``batch``'s last firing is past its end (none else)."""
        if self._open is None or batch.firings is None or self.t0_ns is None:
            return []
        if batch.firings[1] < self.t0_ns + (self._open + 1) * self.period_ns:
            return []
        return [self._close()]

    def flush(self) -> list[StreamFrame]:
        """The open frame, if any (at the end of the stream)."""
        return [self._close()] if self._open is not None else []

    def _close(self) -> StreamFrame:
        k, t0 = self._open, self.t0_ns
        if k is None or t0 is None:
            raise InputError("no open frame to close")
        if self._last_done is not None:
            self.empty_periods += max(k - self._last_done - 1, 0)
        frame = StreamFrame(k, t0 + k * self.period_ns, self.period_ns, _concat(self._parts))
        self._last_done, self._open, self._parts = k, None, []
        return frame


def cut_by_time(
    batches: Iterable[PointBatch],
    period_s: float,
    t0_ns: int | None,
    skipped: Counter[str],
    name: str,
) -> Iterator[StreamFrame]:
    """A recording's point batches, in time order, cut into frames of ``period_s`` as a
    live stream's are (``FrameAssembler`` from ``t0_ns``), to the last one; the points
    dropped as older than the frame being filled are counted in
    ``skipped["late_points"]`` and logged, ``name`` naming the recording."""
    assembler = FrameAssembler(period_s, t0_ns)
    for batch in batches:
        yield from assembler.push(batch)
    yield from assembler.flush()
    if assembler.late_points:
        skipped["late_points"] += assembler.late_points
        log.warning(
            "%s: dropped %d points older than the frame being filled (the clock went back)",
            name,
            assembler.late_points,
        )


class PoseHistory:
    """The turret's recent measured joint states, and the sensor pose at any time.

    ``keep_s``: how far back readings are kept [s]; ``lead_s``: how far beyond the
    newest reading its rates carry the joints (module docstring) [s].  Times are
    seconds on the run's clock.  Readings must come in time order; an older one is
    ignored.
    """

    def __init__(self, mount: MountGeometry, keep_s: float = 2.0, lead_s: float = 0.0) -> None:
        if not lead_s >= 0:
            raise ConfigError(f"a pose's lead past the newest reading must be >= 0 s, not {lead_s}")
        self.mount = mount
        self.keep_s = keep_s
        self.lead_s = lead_s
        self._states: deque[TurretState] = deque()

    def __len__(self) -> int:
        return len(self._states)

    def add(self, state: TurretState) -> None:
        if self._states and state.stamp <= self._states[-1].stamp:
            return
        self._states.append(state)
        while len(self._states) > 2 and self._states[1].stamp < state.stamp - self.keep_s:
            self._states.popleft()

    def angles(self, t: NDArray[np.float64]) -> tuple[FloatArray, FloatArray]:
        """Pan and tilt [rad] at times ``t`` [s]: linear between readings, held before
        the oldest, carried ``lead_s`` on at the newest's rates beyond it."""
        if not self._states:
            raise InputError("no turret reading yet: the sensor pose is unknown")
        s = np.array([x.stamp for x in self._states])
        pan = np.interp(t, s, np.array([x.pan for x in self._states]))
        tilt = np.interp(t, s, np.array([x.tilt for x in self._states]))
        last = self._states[-1]
        if self.lead_s > 0 and (last.pan_rate != 0 or last.tilt_rate != 0):
            # q(t) = q_k + ω_k · min(t − t_k, lead_s) beyond the newest reading k
            ahead = np.clip(np.asarray(t, dtype=np.float64) - last.stamp, 0.0, self.lead_s)
            pan = pan + last.pan_rate * ahead
            tilt = tilt + last.tilt_rate * ahead
        return pan, tilt

    def poses(self, t: NDArray[np.float64]) -> FloatArray:
        """world_T_sensor (K, 4, 4) at times ``t`` [s] (``angles`` through the mount)."""
        pan, tilt = self.angles(t)
        return sensor_poses(pan, tilt, self.mount)

    def frame(self, frame: StreamFrame, t0_ns: int, samples: int = 5) -> Frame:
        """``frame`` as the pipeline's Frame on the run's clock (seconds since ``t0_ns``),
        with ``samples`` sensor poses spread over its period."""
        pts = frame.points
        start = (frame.start_ns - t0_ns) / NS
        duration = frame.period_ns / NS
        pose_t = start + duration * np.linspace(0.0, 1.0, max(samples, 2))
        return Frame(
            stamp=start,
            duration=duration,
            points=pts.xyz.astype(np.float64),
            t=(pts.t_ns - t0_ns) / NS,
            line=pts.line,
            intensity=pts.reflectivity.astype(np.float32),
            pose_t=pose_t,
            poses=self.poses(pose_t),
        )
