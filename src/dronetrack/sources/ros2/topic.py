"""A ROS 2 point topic as a live Source: ``dronetrack live --lidar ros2:///livox/lidar``.

The topic is read over DDS (``sources.ros2.dds``; no ROS install): each
``sensor_msgs/PointCloud2`` or ``livox_ros_driver2/CustomMsg`` message is one frame,
decoded from its CDR bytes by our numpy decoders, as ``track`` decodes a bag's.
Which of the two the topic carries is read from the DDS type name its publisher
announces (the built-in DCPSPublication topic), unless the URI says
(``?type=pkg/msg/Name``).

Time.  The run's clock is the header stamps', in seconds since the first message's
stamp, as ``track`` times a bag: a frame starts at its stamp (or its first point,
if earlier) and lasts the scenario's integration time.

Poses.  ``/tf`` and ``/tf_static`` give the chain from the root of the tree (or
``pose_frame``) to the cloud's ``frame_id``, interpolated at the frame's times
(``sources.ros2.tf``).  A frame waits up to ``TF_WAIT_S`` for /tf to reach its end, as
tf2's message filter would.  Without a transform to its frame_id, the turret's
time-stamped joint readings give the poses through the mount, interpolated between
readings as ``sources.live`` does (``live.TurretPoses``: every reading since the
last frame, stamped on the host's clock as it came, moved onto the stamps' clock by
δ = max(t_last point − t_host at arrival)), and without a turret, the mount at
pan = tilt = 0.

Truth.  With ``truth_topic`` (``geometry_msgs/PoseStamped`` in the pose frame, as
``dronetrack record`` writes ``/ground_truth/pose``) the run is scored as ``track``
scores a bag; a frame waits up to ``TF_WAIT_S`` for the truth at its end.  Else
``truth`` (``--truth FILE``, as ``dronetrack emulate`` writes it) gives the target's
positions on the stamps' clock in seconds, shifted by the first stamp, as
``sources.live`` shifts it.

Queue and ending.  A reader thread takes the samples as they come; complete frames
wait in a queue of ``max_frames``, the oldest dropped and counted when processing
falls behind.  The iteration ends when the topic's last publisher leaves, after
``duration_s`` or on a stop request; no message within ``first_s`` of opening, or
none for ``stall_s`` while a publisher is there, is a DeviceError naming the topic.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from dronetrack.errors import DecodeError, DeviceError, DronetrackError, InputError
from dronetrack.formats.ros.livox_msg import decode_livox_cdr, livox_points
from dronetrack.formats.ros.msgs import NS, POINTCLOUD2, TF_MESSAGE, decode_tf, ros2_typestore
from dronetrack.formats.ros.pointcloud2 import CloudPoints, cloud_points
from dronetrack.formats.ros.pointcloud2_raw import decode_pointcloud2_cdr
from dronetrack.geometry.mount import MountGeometry
from dronetrack.interrupt import stop_requested
from dronetrack.sources.frame_queue import POLL_S, FrameQueue
from dronetrack.sources.frames import fixed_pose_frame
from dronetrack.sources.live import TurretPoses, TurretReader
from dronetrack.sources.ros2.dds import DdsDomain, ReaderSet
from dronetrack.sources.ros2.tf import TransformBuffer
from dronetrack.sources.truth import GroundTruth, RecordedTruth
from dronetrack.sources.truth_csv import RunTruth, TruthFile
from dronetrack.types import Frame, Sample, TurretState

__all__ = ["CUSTOM_MSG", "POINT_TYPES", "Ros2Source", "point_type"]

log = logging.getLogger(__name__)

CUSTOM_MSG = "livox_ros_driver2/msg/CustomMsg"
POINT_TYPES = (POINTCLOUD2, CUSTOM_MSG)
POSE_STAMPED = "geometry_msgs/msg/PoseStamped"
TF_WAIT_S = 0.03  # longest a frame waits for /tf (or the truth) to reach its end
TF_KEEP_S = 10.0  # how much /tf history is kept
POSE_SAMPLES = 5  # sensor poses over a frame from the turret's readings


def point_type(domain: DdsDomain, topic: str, wait_s: float) -> str:
    """The point message type a publisher of ``topic`` announces, waiting up to
    ``wait_s`` for one; DeviceError naming what the domain has otherwise."""
    end = time.monotonic() + wait_s
    seen: list[Any] = []
    while True:
        seen = domain.topics(wait_s=min(0.5, max(end - time.monotonic(), 0.0)))
        types = {s.msg_type for s in seen if s.topic == topic and s.writers > 0}
        usable = [t for t in POINT_TYPES if t in types]
        if usable:
            return usable[0]
        if types:
            raise DeviceError(
                f"ROS 2 topic {topic} carries {', '.join(sorted(types))}, not "
                f"{' or '.join(POINT_TYPES)}"
            )
        if time.monotonic() >= end or stop_requested():
            listed = ", ".join(f"{s.topic} ({s.msg_type})" for s in seen if s.writers) or "none"
            raise DeviceError(
                f"no publisher of ROS 2 topic {topic} on domain {domain.domain_id} within "
                f"{wait_s:g} s (published topics: {listed})"
            )


@dataclass(frozen=True, slots=True)
class _Cloud:
    stamp_ns: int
    frame_id: str
    points: CloudPoints
    received: float  # perf_counter when it was taken
    host: float  # the source's clock then


class Ros2Source:
    """Frames of a ROS 2 point topic as they come (see the module docstring)."""

    def __init__(
        self,
        domain: DdsDomain,
        topic: str,
        msg_type: str,
        mount: MountGeometry,
        turret: TurretReader | None = None,
        *,
        period_s: float = 0.1,
        max_frames: int = 2,
        duration_s: float | None = None,
        pose_frame: str | None = None,
        truth_topic: str | None = None,
        truth: GroundTruth | TruthFile | None = None,
        truth_radius: float = 0.5,
        first_s: float = 10.0,
        stall_s: float = 2.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if msg_type not in POINT_TYPES:
            raise InputError(f"{msg_type} is not a point message ({', '.join(POINT_TYPES)})")
        self.name = f"ros2://{topic}"
        self.topic = topic
        self.msg_type = msg_type
        self.mount = mount
        self.turret = turret
        self._period = period_s
        self.max_frames = max_frames
        self.duration_s = duration_s
        self.pose_frame = pose_frame
        self.truth_radius = truth_radius
        self.first_s = first_s
        self.stall_s = stall_s
        self.clock = clock
        self.frames_delivered = 0
        self.packets_lost = 0  # DDS reports no per-sample loss to a best-effort reader
        self.skipped: Counter[str] = Counter()
        self.tf = TransformBuffer()
        self._turret_poses = TurretPoses(turret, mount, period_s)
        self._origin_ns: int | None = None
        self._offset: float | None = None  # δ [s]
        self._tf_pending: list[Any] = []
        self._truth_rows: list[tuple[int, float, float, float]] = []  # handed over, not taken
        self._truth_t = np.empty(0)  # the truth taken so far: run-clock times [s], sorted
        self._truth_p = np.empty((0, 3))  # and positions [m]
        self._truth: GroundTruth | None = None
        self._truth_file = None if truth is None else RunTruth(truth, truth_radius)
        self._stop = threading.Event()
        self._queue: FrameQueue[_Cloud] = FrameQueue(max_frames, self._stop)
        self._cond = self._queue.cond  # also guards the transforms and truth handed over
        self.points = domain.reader(topic, msg_type, "sensor")
        self._tf_readers = [
            domain.reader("/tf", TF_MESSAGE, "tf"),
            domain.reader("/tf_static", TF_MESSAGE, "static"),
        ]
        self._truth_reader = (
            None if truth_topic is None else domain.reader(truth_topic, POSE_STAMPED, "default")
        )
        others = [r for r in (*self._tf_readers, self._truth_reader) if r is not None]
        self._waitset = ReaderSet([self.points, *others])
        self._thread: threading.Thread | None = None

    @property
    def period(self) -> float:
        return self._period

    @property
    def packets_malformed(self) -> int:
        return int(self.skipped["bad_point_message"])

    # -- the reader thread -------------------------------------------------------------

    def start(self) -> None:
        if self._thread is None:
            self._thread = threading.Thread(target=self._read_loop, name="ros2-reader", daemon=True)
            self._thread.start()

    def _read_loop(self) -> None:
        opened = time.monotonic()
        last: float | None = None  # when the last point message came
        try:
            while not self._stop.is_set():
                self._waitset.wait(POLL_S)
                self._take_side_topics()
                got = self.points.take()
                now = time.monotonic()
                for raw in got:
                    self._hand_on(raw)
                if got:
                    last = now
                    continue
                if self.points.matched() == 0 and self.points.ever_matched:
                    return  # the publisher left: the stream has ended
                if last is None and now - opened > self.first_s:
                    raise DeviceError(f"{self.name}: no message within {self.first_s:g} s")
                if last is not None and now - last > self.stall_s:
                    raise DeviceError(f"{self.name}: no message for {self.stall_s:g} s")
        except DronetrackError as exc:
            self._queue.fail(exc)
        finally:
            self._queue.end()

    def _take_side_topics(self) -> None:
        tf: list[Any] = []
        for k, reader in enumerate(self._tf_readers):
            for raw in reader.drain():
                try:
                    tf.extend((k == 1, s) for s in decode_tf(raw))
                except DecodeError as exc:
                    self._skip("bad_tf", exc)
        rows = []
        if self._truth_reader is not None:
            ts = ros2_typestore()
            for raw in self._truth_reader.drain():
                try:
                    msg: Any = ts.deserialize_cdr(raw, POSE_STAMPED)
                except Exception as exc:  # rosbags raises many kinds on bad bytes
                    self._skip("bad_ground_truth", exc)
                    continue
                p, st = msg.pose.position, msg.header.stamp
                rows.append(
                    (int(st.sec) * NS + int(st.nanosec), float(p.x), float(p.y), float(p.z))
                )
        if tf or rows:
            with self._cond:
                self._tf_pending.extend(tf)
                self._truth_rows.extend(rows)
                self._cond.notify_all()

    def _skip(self, reason: str, detail: object) -> None:
        self.skipped[reason] += 1
        if self.skipped[reason] <= 5:
            log.warning("%s: skipped a message (%s): %s", self.name, reason, detail)

    def _decode(self, raw: bytes) -> tuple[int, str, CloudPoints] | None:
        try:
            if self.msg_type == CUSTOM_MSG:
                lc = decode_livox_cdr(raw)
                return lc.stamp_ns, lc.frame_id, CloudPoints(*livox_points(lc))
            pc = decode_pointcloud2_cdr(raw)
            return pc.stamp_ns, pc.frame_id, cloud_points(pc.array(), pc.stamp_ns / NS)
        except (DecodeError, InputError, ValueError, IndexError) as exc:
            self._skip("bad_point_message", exc)
            return None

    def _hand_on(self, raw: bytes) -> None:
        received, host = time.perf_counter(), self.clock()
        decoded = self._decode(raw)
        if decoded is None:
            return
        stamp_ns, frame_id, points = decoded
        # δ = max (t_last point − t_host at arrival), the points' clock against the host's
        last = stamp_ns / NS + (
            float(points.t.max()) if points.t is not None and len(points.t) else 0.0
        )
        delta = last - host
        self._offset = delta if self._offset is None else max(self._offset, delta)
        self._queue.put(_Cloud(stamp_ns, frame_id, points, received, host))

    # -- the Source ---------------------------------------------------------------------

    def _next(self) -> _Cloud | None:
        return self._queue.get()

    @property
    def frames_dropped(self) -> int:
        """Whole frames dropped because the run fell behind (``FrameQueue``)."""
        return self._queue.dropped

    def _absorb(self) -> None:
        """Move the transforms and truth that came in into the buffer (run clock)."""
        origin = self._origin_ns
        assert origin is not None
        with self._cond:
            tf, self._tf_pending = self._tf_pending, []
            rows, self._truth_rows = self._truth_rows, []
        for static, s in tf:
            t = (s.stamp_ns - origin) / NS
            self.tf.add_transform(s.parent, s.child, t, s.translation, s.rotation_xyzw, static)
        if rows:
            # only the new rows are converted; the whole is sorted again only when one of
            # them comes before a row already taken
            stamps = np.array([r[0] for r in rows], dtype=np.int64)
            t = np.concatenate([self._truth_t, (stamps - origin) / NS])
            p = np.concatenate([self._truth_p, np.array([r[1:] for r in rows], np.float64)])
            if np.any(np.diff(t) < 0):
                order = np.argsort(t, kind="stable")
                t, p = t[order], p[order]
            self._truth_t, self._truth_p = t, p
            self._truth = GroundTruth(t, p, max_gap_s=max(1.0, 10 * self._period))

    def _tf_behind(self, frame_id: str, end: float) -> bool:
        """Whether the moving links above ``frame_id`` or the truth end before ``end``."""
        behind = False
        if frame_id in self.tf:
            root = self.pose_frame or self.tf.root(frame_id)
            if root != frame_id:
                newest = self.tf.newest(root, frame_id)
                behind = newest is not None and newest < end - 1e-6  # float rounding
        if self._truth_reader is not None:
            behind = behind or self._truth is None or float(self._truth.t[-1]) < end - 1e-6
        return behind

    def _settle(self, frame_id: str, end: float) -> None:
        """Take in /tf and the truth, waiting up to TF_WAIT_S for them to reach ``end``."""
        until = time.monotonic() + TF_WAIT_S
        self._absorb()
        while self._tf_behind(frame_id, end) and time.monotonic() < until:
            with self._cond:
                self._cond.wait(0.002)
            self._absorb()

    def _frame(self, cloud: _Cloud) -> tuple[Frame, TurretState | None]:
        origin = self._origin_ns
        assert origin is not None
        pts = cloud.points
        stamp = (cloud.stamp_ns - origin) / NS
        t = stamp + pts.t if pts.t is not None else None
        if t is not None and len(t):
            stamp = min(stamp, float(t.min()))
        end = stamp + self._period
        self._settle(cloud.frame_id, end)
        root = self.pose_frame or self.tf.root(cloud.frame_id)
        if cloud.frame_id in self.tf and root != cloud.frame_id:
            self.tf.prune(end - TF_KEEP_S)
            times = np.concatenate(
                [[stamp], self.tf.sample_times(root, cloud.frame_id, stamp, end), [end]]
            )
            poses = self.tf.lookup(root, cloud.frame_id, times)
            frame = fixed_pose_frame(
                stamp, self._period, pts.points, t, pts.intensity, pts.line, poses, times
            )
            return frame, None
        # the turret's readings, moved onto the run's clock by δ, interpolated per pose
        offset = self._offset if self._offset is not None else 0.0
        shift = offset - origin / NS  # t_run = t_host + δ − t₀

        def to_run(host: float) -> float:
            return host + shift

        def to_host(t: float) -> float:
            return t - shift

        state = self._turret_poses.read(end, to_run, to_host)
        times = stamp + self._period * np.linspace(0.0, 1.0, POSE_SAMPLES)
        poses = self._turret_poses.history.poses(times)
        frame = fixed_pose_frame(
            stamp, self._period, pts.points, t, pts.intensity, pts.line, poses, times
        )
        return frame, state

    def __iter__(self) -> Iterator[Sample]:
        self.start()
        try:
            while True:
                cloud = self._next()
                if cloud is None:
                    return
                if self._origin_ns is None:
                    self._origin_ns = cloud.stamp_ns
                frame, state = self._frame(cloud)
                truth = None
                if self._truth is not None:
                    pos = self._truth.at(frame.end)[0]
                    truth = RecordedTruth(self._truth, pos, self.truth_radius)
                elif self._truth_file is not None:
                    truth = self._truth_file.at(frame.end, self._origin_ns)
                self.frames_delivered += 1
                yield Sample(frame, truth, state, cloud.received)
                if self.duration_s is not None and frame.end >= self.duration_s:
                    return
        finally:
            self.stop()

    def stop(self) -> None:
        """Stop the reader thread (the domain is closed by whoever opened it)."""
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=1.0)
