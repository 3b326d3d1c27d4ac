"""A live LiDAR as a Source: packets to frames in real time, with the turret's pose.

A reader thread takes the decoded point batches of a point stream (``livox://``,
``livox2://``, ``velodyne://``), cuts them into frames by the points' own times
(``assembly.FrameAssembler``; or, given another ``Assembler``, as it says: a spinning
head's revolutions, ``revolutions.RevolutionAssembler``) and queues each frame as it
completes, with the moment its last packet arrived.  The run loop takes frames from
the queue as fast as it can process them.  The queue holds ``max_frames`` frames:
when processing falls behind, the oldest whole frame is dropped and counted
(``frames_dropped``), so the pipeline always works on the newest data and memory
stays bounded.

Time.  Every time in the run is the sensor's, in seconds since frame 0's start (the
first point, or the first revolution's start; the run's clock, as ``seams`` says).
The turret's readings are stamped on the host's monotonic clock and moved onto the
sensor's by the offset

    δ = max over batches (t_last firing − t_host at its arrival)

the smallest delay seen between a firing's time and its arrival (a batch's last
firing, with a return or not, or its last point when the stream gives only
points), so δ follows the
sensor's clock to within the shortest transport delay (a fraction of a millisecond
on a wired link).

The turret's pose.  A turret that polls its joints (``readings``: the Dynamixel
turret reads them 100 times a second in a thread of its own) hands over every
reading made since the last frame; the frame waits only if the newest is stale
(older than the turret allows before the frame's end), so the serial round trip
is not in the frame's path.  A turret without ``readings`` is read once, before
the frame is handed on.  ``assembly.PoseHistory`` interpolates the readings to
each pose time of the frame, and carries the newest on at its measured rates for
at most ``LEAD_S`` beyond it, so the per-point sensor pose follows the measured
joint angles.

Latency.  Each frame carries ``received``, the ``time.perf_counter()`` when the
batch holding its last firing (its last point, with a return or not) was read off
the stream: the batch that completed the frame if it reaches into the frame, else
the batch before.  A frame is known complete only when a later firing arrives
(``assembly.FrameAssembler``; a stream whose batches carry no ``firings``: a later
point), and that wait is part of the latency ``pipeline.run`` measures, as it is
part of the delay on a rig.

Truth.  ``--truth`` gives the target's positions in the sensor's time base (the
points' own timestamps, in seconds); the run's clock starts at the first point, so
the truth is shifted by that point's time before it is looked up.

Liveness.  The stream raises ``DeviceError`` when its device falls silent (the
Livox clients: no point packet for ``stall_s``); the reader thread hands the error
to the run loop, which re-raises it, so the run ends with the device named.  A stop
request (Ctrl-C or SIGTERM, ``dronetrack.interrupt``) ends the iteration while it
waits for a frame.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Protocol

from dronetrack.errors import ConfigError, DeviceError, DronetrackError
from dronetrack.geometry.mount import MountGeometry
from dronetrack.sources.assembly import NS, FrameAssembler, PointBatch, PoseHistory, StreamFrame
from dronetrack.sources.frame_queue import POLL_S, FrameQueue
from dronetrack.sources.truth import GroundTruth, RecordedTruth
from dronetrack.sources.truth_csv import RunTruth, TruthFile
from dronetrack.types import Sample, TurretState

__all__ = [
    "LEAD_S",
    "OPEN_TIMEOUT_S",
    "Assembler",
    "LiveSource",
    "PointStream",
    "PolledTurret",
    "TurretPoses",
    "TurretReader",
]

OPEN_TIMEOUT_S = 5.0  # how long a LiDAR has to answer the connection and start sampling
POSE_WAIT_S = 1.0  # longest a frame waits for a fresh turret reading
LEAD_S = 0.05  # how far the newest reading's rates carry the pose beyond it [s]
# A frame ending this close before the duration ends the run: a revolution ends where
# the azimuth passes the cut angle, to a few µs of the nominal period.
END_SLACK_S = 1e-4


class PointStream(Protocol):
    """A live point stream: decoded batches in time order, and loss counters."""

    @property
    def name(self) -> str: ...

    packets_lost: int
    packets_malformed: int

    def read(self, timeout_s: float = 0.1) -> PointBatch: ...

    def close(self) -> None: ...


class Assembler(Protocol):
    """What cuts a stream into frames (``assembly.FrameAssembler`` by time,
    ``revolutions.RevolutionAssembler`` by revolution): the frames each batch
    completes, and the time of frame 0's start (the run's clock's zero; None before
    it is known)."""

    t0_ns: int | None

    def push(self, batch: PointBatch) -> list[StreamFrame]: ...


class TurretReader(Protocol):
    """What the source needs of a turret: its measured state (seams.Actuator.state)."""

    def state(self) -> TurretState | None: ...


class PolledTurret(TurretReader, Protocol):
    """A turret that reads its joints on its own (``DynamixelTurret.readings``): the
    states read since the last call, once the newest is fresh for host time
    ``until``, waiting at most ``timeout_s``; stamps on the host's clock."""

    def readings(self, until: float = ..., timeout_s: float = ...) -> list[TurretState]: ...


class TurretPoses:
    """A live source's turret readings as sensor poses (``PoseHistory``), on the run's
    clock: a ``PolledTurret``'s every reading since the last frame (waiting up to
    POSE_WAIT_S for one fresh for the frame's end), another turret's one ``state`` a
    frame, or, without a turret, a fixed sensor at pan = tilt = 0.  Shared by the
    Livox and ROS 2 sources."""

    def __init__(self, turret: TurretReader | None, mount: MountGeometry, period_s: float):
        self.turret = turret
        self.history = PoseHistory(mount, keep_s=max(2.0, 4 * period_s), lead_s=LEAD_S)
        self.newest: TurretState | None = None  # the newest reading, run clock

    def read(
        self, frame_end: float, to_run: Callable[[float], float], to_host: Callable[[float], float]
    ) -> TurretState:
        """Add the turret's new readings for a frame ending at ``frame_end`` (run clock);
        the newest.  ``to_run`` and ``to_host`` move a time from the host's clock onto
        the run's and back."""
        if self.turret is None:
            self.newest = TurretState(frame_end, 0.0, 0.0)
            self.history.add(self.newest)
            return self.newest
        read = getattr(self.turret, "readings", None)
        if read is None:
            state = self.turret.state()
            if state is None:
                raise DeviceError("the turret reports no joint state")
            states = [state]
        else:
            states = read(to_host(frame_end), POSE_WAIT_S)
        for state in states:
            stamp = to_run(state.stamp)
            self.newest = TurretState(stamp, state.pan, state.tilt, state.pan_rate, state.tilt_rate)
            self.history.add(self.newest)
        if self.newest is None:
            raise DeviceError("the turret reports no joint state")
        return self.newest


@dataclass(frozen=True, slots=True)
class _Done:
    frame: StreamFrame
    received: float  # perf_counter when its last batch arrived [s]


class LiveSource:
    """Frames of a live ``stream`` as they complete (see the module docstring).

    ``mount``: the sensor's mount on the turret; ``turret``: its readings give the
    sensor pose, a ``PolledTurret``'s every reading, else one ``state`` a frame
    (None: a fixed sensor at pan = tilt = 0); ``period_s``: the
    integration time (the pipeline's frame period); ``assembler``: how frames are cut
    (None: by ``period_s``, ``FrameAssembler``); ``max_frames``: the queue bound;
    ``duration_s``: stop after the frame that ends at (within ``END_SLACK_S``) or after
    this much sensor time (None: until the stream ends or the run is stopped);
    ``truth``: the target's positions in the sensor's time base (``--truth``; a
    ``TruthFile`` is read as it grows), and
    ``truth_radius``: a return within it of the true position counts as the
    target's [m].
    """

    def __init__(
        self,
        stream: PointStream,
        mount: MountGeometry,
        turret: TurretReader | None = None,
        *,
        period_s: float = 0.1,
        assembler: Assembler | None = None,
        max_frames: int = 2,
        duration_s: float | None = None,
        truth: GroundTruth | TruthFile | None = None,
        truth_radius: float = 0.5,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if max_frames < 1:
            raise ConfigError(f"the frame queue needs room for 1 frame, got {max_frames}")
        self.stream = stream
        self.turret = turret
        self.max_frames = max_frames
        self.duration_s = duration_s
        self.truth = truth
        self.truth_radius = truth_radius
        self._run_truth = None if truth is None else RunTruth(truth, truth_radius)
        self.clock = clock
        self.assembler: Assembler = FrameAssembler(period_s) if assembler is None else assembler
        self._turret_poses = TurretPoses(turret, mount, period_s)
        self.poses = self._turret_poses.history
        self._period = period_s
        self.frames_delivered = 0
        self._offset: float | None = None  # δ [s] (module docstring)
        self._stop = threading.Event()
        self._queue: FrameQueue[_Done] = FrameQueue(max_frames, self._stop)
        self._thread: threading.Thread | None = None

    @property
    def period(self) -> float:
        return self._period

    @property
    def packets_lost(self) -> int:
        return int(self.stream.packets_lost)

    @property
    def packets_malformed(self) -> int:
        return int(self.stream.packets_malformed)

    # -- the reader thread -------------------------------------------------------------

    def start(self) -> None:
        """Start reading (``__iter__`` does it if not yet done)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._read_loop, name="live-reader", daemon=True)
            self._thread.start()

    def _read_loop(self) -> None:
        before = float("nan")  # when the previous batch arrived (perf_counter)
        try:
            while not self._stop.is_set():
                batch = self.stream.read(POLL_S)
                first, last = batch.first_ns, batch.last_ns
                if first is None or last is None:
                    continue
                arrived = time.perf_counter()
                host = self.clock()
                # δ = max (t_last firing − t_host at arrival)
                delta = last / NS - host
                self._offset = delta if self._offset is None else max(self._offset, delta)
                for frame in self.assembler.push(batch):
                    # its last point came in this batch if the batch reaches into it
                    mine = first < frame.start_ns + frame.period_ns
                    self._hand_on(_Done(frame, arrived if mine or math.isnan(before) else before))
                before = arrived
        except DronetrackError as exc:
            self._fail(exc)
        except OSError as exc:  # a socket error the stream did not name: name it here
            self._fail(DeviceError(f"{self.stream.name}: {exc}"))
        finally:
            self._queue.end()

    def _fail(self, exc: DronetrackError) -> None:
        self._queue.fail(exc)

    def _hand_on(self, done: _Done) -> None:
        self._queue.put(done)  # the oldest whole frame goes if the queue is full

    def _next(self) -> _Done | None:
        """The oldest queued frame; None once the stream has ended or stop() was called."""
        return self._queue.get()

    @property
    def frames_dropped(self) -> int:
        """Whole frames dropped because the run fell behind (``FrameQueue``)."""
        return self._queue.dropped

    # -- the Source ---------------------------------------------------------------------

    def run_time(self, host: float) -> float:
        """A time on the host's clock (``clock``) on the run's clock, seconds since the
        first frame's start: t_host + δ − t₀; NaN before the first point."""
        t0 = self.assembler.t0_ns
        if self._offset is None or t0 is None:
            return float("nan")
        return host + self._offset - t0 / NS

    def sensor_time(self) -> float:
        """The host's clock now on the run's clock (``run_time``)."""
        return self.run_time(self.clock())

    def host_time(self, t: float) -> float:
        """A time on the run's clock on the host's (``clock``): the inverse of
        ``run_time``, t − δ + t₀; NaN before the first point."""
        t0 = self.assembler.t0_ns
        if self._offset is None or t0 is None:
            return float("nan")
        return t - self._offset + t0 / NS

    def _read_turret(self, frame_end: float) -> TurretState:
        """Add the turret's new readings to the pose history (for a frame ending at
        ``frame_end`` on the run's clock); the newest reading."""
        if self.turret is None:  # a fixed sensor: its pose now
            frame_end = self.sensor_time()
        return self._turret_poses.read(frame_end, self.run_time, self.host_time)

    def __iter__(self) -> Iterator[Sample]:
        self.start()
        try:
            while True:
                done = self._next()
                if done is None:
                    return
                t0_ns = self.assembler.t0_ns
                assert t0_ns is not None
                end_ns = done.frame.start_ns + done.frame.period_ns
                state = self._read_turret((end_ns - t0_ns) / NS)
                frame = self.poses.frame(done.frame, t0_ns)
                self.frames_delivered += 1
                yield Sample(frame, self._truth_at(frame.end, t0_ns), state, done.received)
                if self.duration_s is not None and frame.end >= self.duration_s - END_SLACK_S:
                    return
        finally:
            self.stop()

    def _truth_at(self, t: float, t0_ns: int) -> RecordedTruth | None:
        """The truth at ``t`` on the run's clock (None without ``truth``)."""
        return None if self._run_truth is None else self._run_truth.at(t, t0_ns)

    def stop(self) -> None:
        """Stop the reader thread (the stream is closed by whoever opened it)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)
