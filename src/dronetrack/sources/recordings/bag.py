"""ROS 1 bags, ROS 2 bags (sqlite3 and MCAP storage) and bare ``.mcap`` files.

The containers are read with rosbags (pure Python, no ROS install). Point messages are
decoded from their bytes by our numpy decoders (``formats.ros.pointcloud2_raw``,
``formats.ros.livox_msg``): rosbags' generic deserialiser makes one Python object per
Livox point, about 100× too slow for replay, and copies a PointCloud2's data.

Topics:
- LiDAR: ``sensor_msgs/PointCloud2`` or ``livox_ros_driver(2)/CustomMsg``; chosen
  automatically when there is exactly one such topic.
- Sensor pose: ``/tf`` and ``/tf_static`` (``tf2_msgs/TFMessage``), the chain from
  the pose frame (default: the root of the tree) to the cloud's ``frame_id``;
  without it, a fixed pose (identity by default).
- Ground truth: ``sensor_msgs/NavSatFix`` (to a local ENU frame) or
  ``geometry_msgs/PoseStamped``; chosen automatically when there is exactly one.
- ``/dronetrack/config`` (``std_msgs/String``): the scenario a simulated recording
  was made from (``dronetrack record``), so replay uses the same settings.

Times are the messages' header stamps, relative to the first LiDAR stamp.

Frames.  Each LiDAR message is a frame, its period the median step of the first
stamps.  ``--period`` T re-cuts them by the points' own times, as a live stream is
cut (``sources.assembly``): frame k holds the points of [t₀ + kT, t₀ + (k + 1)T), t₀
the first stamp, whichever messages they came in (intensities are clipped to
0-255 there, as a live stream's reflectivities; the tracker does not use them).
Messages without per-point times cannot be re-cut: ``--period`` is refused unless it
is their period already.  With /tf for the LiDAR's frame, ``--sensor-pose`` is
ignored, with a warning.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.errors import RecordingError
from dronetrack.formats.ros.livox_msg import (
    LIVOX_TYPES,
    LivoxCloud,
    decode_livox_cdr,
    decode_livox_ros1,
    livox_points,
)
from dronetrack.formats.ros.pointcloud2 import (
    TIME_FIELD_NAMES,
    CloudPoints,
    cloud_points,
    has_point_times,
)
from dronetrack.formats.ros.pointcloud2_raw import (
    RawCloud,
    decode_pointcloud2_cdr,
    decode_pointcloud2_ros1,
)
from dronetrack.geometry.geodesy import SiteFrame
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sources.assembly import NS, PointBatch, StreamFrame, cut_by_time
from dronetrack.sources.frames import fixed_pose_frame
from dronetrack.sources.recordings.bag_file import BAD_DATA, BagFile
from dronetrack.sources.recordings.recording import (
    ReplayOptions,
    frame_period,
    identity_pose_warning,
)
from dronetrack.sources.ros2.tf import TransformBuffer
from dronetrack.sources.truth import GroundTruth
from dronetrack.types import Frame

__all__ = ["CONFIG_TOPIC", "BagRecording"]

log = logging.getLogger(__name__)

POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
LIDAR_TYPES = frozenset({POINTCLOUD2, *LIVOX_TYPES})
NAVSATFIX = "sensor_msgs/msg/NavSatFix"
POSESTAMPED = "geometry_msgs/msg/PoseStamped"
GT_TYPES = frozenset({NAVSATFIX, POSESTAMPED})
TF_TYPE = "tf2_msgs/msg/TFMessage"
STRING_TYPE = "std_msgs/msg/String"
CONFIG_TOPIC = "/dronetrack/config"
_PERIOD_SAMPLES = 21  # LiDAR stamps read to estimate the frame period
PERIOD_TOL = 0.01  # a --period this close (relative) to the messages' is theirs


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


class BagRecording(BagFile):
    """A bag opened for replay (see the module docstring)."""

    def __init__(self, path: Path, options: ReplayOptions | None = None) -> None:
        super().__init__(path, check=False)  # opened below
        self.options = options = options or ReplayOptions()
        self._lidar_frame: str | None = None  # the clouds' frame_id, once one is decoded
        self.pose_warning: str | None = None  # set by the first frame that needs one
        self._point_times = False  # whether the first message gives each point its time
        with self._reader() as reader:
            conns = reader.connections
            lidar = _choose(conns, options.lidar_topic, LIDAR_TYPES, "LiDAR", "--lidar-topic")
            assert lidar is not None
            self.lidar: Any = lidar
            self.n_frames = int(self.lidar.msgcount)
            gt = _choose(conns, options.gt_topic, GT_TYPES, "ground-truth", "--gt-topic", True)
            self.gt_connection = gt
            self.is2 = bool(reader.is2)
            stamps = self._first_stamps(reader)
            if not stamps:
                raise RecordingError(f"{path}: LiDAR topic {self.lidar.topic} has no messages")
            self.origin_ns = stamps[0]
            self.origin = self.origin_ns * 1e-9
            steps = (np.asarray(stamps) - stamps[0]) * 1e-9
            self.message_period = frame_period(ReplayOptions(), steps)
            self.period = frame_period(options, steps)
            self.recut = self._recut(options.period_s)
            if self.recut:  # an estimate, for the progress bar
                self.n_frames = math.ceil(self.n_frames * self.message_period / self.period)
            self.tf = self._read_tf(reader, conns)
            self.config_text = self._read_config(reader, conns)
            self.ground_truth = self._read_ground_truth(reader, gt) if gt is not None else None

    def _first_stamps(self, reader: Any) -> list[int]:
        """The header stamps [ns] of the first LiDAR messages (their points are not read)."""
        stamps: list[int] = []
        for _, _, raw in self._messages(reader, [self.lidar]):
            header = self._parse(reader, raw)
            if header is not None:
                if not stamps:
                    self._point_times = isinstance(header, LivoxCloud) or has_point_times(
                        header.fields
                    )
                self._lidar_frame = header.frame_id
                stamps.append(header.stamp_ns)
            if len(stamps) >= _PERIOD_SAMPLES:
                break
        self.skipped.clear()  # frames() reads these messages again and counts them then
        self._warned.clear()
        return stamps

    def _recut(self, period: float | None) -> bool:
        """Whether ``--period`` re-cuts the messages into frames of that period (the
        module docstring); RecordingError when their points have no times to cut by."""
        if period is None:
            return False
        if self._point_times:
            return True
        if abs(period - self.message_period) <= PERIOD_TOL * self.message_period:
            return False  # each message is a frame of that period already
        names = ", ".join(TIME_FIELD_NAMES)
        raise RecordingError(
            f"{self.path}: --period {period:g} s cannot re-cut {self.lidar.topic}: its "
            f"PointCloud2 messages have no per-point time field ({names}), so each message "
            f"is one frame, {self.message_period:g} s apart by their stamps; leave out --period"
        )

    def _read_tf(self, reader: Any, conns: Sequence[Any]) -> TransformBuffer:
        tf = TransformBuffer()
        tf_conns = [c for c in conns if c.msgtype == TF_TYPE]
        for conn, _, raw in self._messages(reader, tf_conns):
            msg = self._deserialize(reader, raw, conn.msgtype, "bad_tf")
            if msg is None:
                continue
            static = conn.topic.endswith("tf_static")
            for tr in msg.transforms:
                t = (_stamp_ns(tr.header) - self.origin_ns) * 1e-9
                q, p = tr.transform.rotation, tr.transform.translation
                xyzw = (q.x, q.y, q.z, q.w)
                tf.add_transform(
                    tr.header.frame_id, tr.child_frame_id, t, (p.x, p.y, p.z), xyzw, static
                )
        if tf.conflicts:
            self.skipped["tf_second_parent"] += tf.conflicts
        if tf.invalid:
            self.skipped["bad_tf"] += tf.invalid
        return tf

    def _read_config(self, reader: Any, conns: Sequence[Any]) -> str | None:
        found = [c for c in conns if c.topic == CONFIG_TOPIC and c.msgtype == STRING_TYPE]
        text = None
        for conn, _, raw in self._messages(reader, found):
            msg = self._deserialize(reader, raw, conn.msgtype, "bad_config")
            if msg is not None:
                text = str(msg.data)
        return text

    def _read_ground_truth(self, reader: Any, conn: Any) -> GroundTruth | None:
        t: list[float] = []
        rows: list[tuple[float, float, float]] = []
        frames: list[str] = []
        for _, _, raw in self._messages(reader, [conn]):
            msg = self._deserialize(reader, raw, conn.msgtype, "bad_ground_truth")
            if msg is None:
                continue
            if conn.msgtype == NAVSATFIX:
                if int(msg.status.status) < 0:  # STATUS_NO_FIX
                    self.skipped["gt_no_fix"] += 1
                    continue
                rows.append((float(msg.latitude), float(msg.longitude), float(msg.altitude)))
            else:
                p = msg.pose.position
                rows.append((float(p.x), float(p.y), float(p.z)))
                frames.append(str(msg.header.frame_id))
            t.append((_stamp_ns(msg.header) - self.origin_ns) * 1e-9)
        if not rows:
            return None
        ts = np.asarray(t)
        values = np.asarray(rows, dtype=np.float64)
        if conn.msgtype == NAVSATFIX:
            values = self._enu(values)
        else:
            values = self._to_pose_frame(ts, values, frames)
        finite = np.all(np.isfinite(values), axis=1) & np.isfinite(ts)
        if not finite.all():
            self.skipped["gt_nonfinite"] += int(np.count_nonzero(~finite))
            ts, values = ts[finite], values[finite]
        if len(ts) == 0:
            return None
        order = np.argsort(ts, kind="stable")
        return GroundTruth(ts[order], values[order], max_gap_s=max(1.0, 10 * self.period))

    def _enu(self, lla: FloatArray) -> FloatArray:
        """GNSS fixes (N, 3: lat°, lon°, alt m) in the world frame: the site's
        (``gt_site``) unless ``--gt-origin`` gives the frame's origin; without either, an
        ENU frame at the first fix.  ``--gt-heading`` ψ_E, the yaw of world x from east,
        is a site heading (from north) of 90° − ψ_E; the conversion is the site frame's."""
        origin = self.options.gt_origin
        site = self.options.gt_site
        if origin is not None or site is None:
            if origin is None:
                origin = (float(lla[0, 0]), float(lla[0, 1]), float(lla[0, 2]))
                log.warning(
                    "%s: ground truth in an ENU frame at the first fix (%.7f°, %.7f°, %.2f m);"
                    " give the sensor's position with --gt-origin or a [site] section",
                    self.path.name,
                    *origin,
                )
            site = SiteFrame(*origin, heading_deg=90.0 - self.options.gt_heading_deg)
        return site.from_geodetic(lla[:, 0], lla[:, 1], lla[:, 2])

    def _to_pose_frame(self, t: FloatArray, xyz: FloatArray, frames: list[str]) -> FloatArray:
        """Poses given in another frame of the /tf tree are moved into the pose frame."""
        root = self._root()
        frame = frames[0] if frames else ""
        if not frame or frame == root or root is None or frame not in self.tf:
            return xyz
        T = self.tf.lookup(root, frame, t)
        out: FloatArray = np.einsum("nij,nj->ni", T[:, :3, :3], xyz) + T[:, :3, 3]
        return out

    def _root(self) -> str | None:
        if self.options.pose_frame is not None:
            return self.options.pose_frame
        frame = self._lidar_frame
        return self.tf.root(frame) if frame else None

    def _parse(self, reader: Any, raw: bytes) -> LivoxCloud | RawCloud | None:
        """The message's header and a view of its points, or None for a bad message."""
        try:
            if self.lidar.msgtype in LIVOX_TYPES:
                return decode_livox_cdr(raw) if reader.is2 else decode_livox_ros1(raw)
            return decode_pointcloud2_cdr(raw) if reader.is2 else decode_pointcloud2_ros1(raw)
        except BAD_DATA as exc:
            self._skip("bad_point_message", exc)
        return None

    def _points(self, msg: LivoxCloud | RawCloud) -> CloudPoints | None:
        """Positions, times relative to the stamp, intensity and line, or None."""
        try:
            if isinstance(msg, LivoxCloud):
                return CloudPoints(*livox_points(msg))
            return cloud_points(msg.array(), msg.stamp_ns * 1e-9)
        except BAD_DATA as exc:
            self._skip("bad_point_message", exc)
        return None

    def frames(self) -> Iterator[Frame]:
        """The LiDAR frames in the pose frame's time line (see the module docstring)."""
        clouds = self._clouds()
        yield from self._recut_frames(clouds) if self.recut else self._message_frames(clouds)

    def _clouds(self) -> Iterator[tuple[int, str, CloudPoints]]:
        """(stamp [ns], frame_id, points) of each LiDAR message that decodes."""
        with self._reader() as reader:
            for _, _, raw in self._messages(reader, [self.lidar]):
                msg = self._parse(reader, raw)
                cloud = self._points(msg) if msg is not None else None
                if msg is not None and cloud is not None:
                    yield msg.stamp_ns, msg.frame_id, cloud

    def _message_frames(self, clouds: Iterator[tuple[int, str, CloudPoints]]) -> Iterator[Frame]:
        """One frame a message, from its stamp (or its earliest point) for a period."""
        for stamp_ns, frame_id, cloud in clouds:
            stamp = (stamp_ns - self.origin_ns) * 1e-9
            t = stamp + cloud.t if cloud.t is not None else None
            if t is not None and len(t):
                stamp = min(stamp, float(t.min()))
            yield self._frame(stamp, frame_id, cloud.points, t, cloud.intensity, cloud.line)

    def _recut_frames(self, clouds: Iterator[tuple[int, str, CloudPoints]]) -> Iterator[Frame]:
        """The messages' points cut into frames of ``period`` by their own times, in the
        clouds' frame_id (one for the topic)."""
        batches = self._batches(clouds)
        frame_id = self._lidar_frame or ""
        name = self.path.name
        for done in cut_by_time(batches, self.period, self.origin_ns, self.skipped, name):
            yield self._cut_frame(done, frame_id)

    def _batches(self, clouds: Iterator[tuple[int, str, CloudPoints]]) -> Iterator[PointBatch]:
        """Each message's timed points as a batch on the absolute clock [ns]."""
        for stamp_ns, _, cloud in clouds:
            if cloud.t is None:
                self._skip("bad_point_message", "no per-point time field to cut frames by")
                continue
            timed = np.isfinite(cloud.t)
            if not timed.all():
                self.skipped["untimed_points"] += int(np.count_nonzero(~timed))
            t_ns = stamp_ns + np.rint(cloud.t[timed] * NS).astype(np.int64)
            refl = np.clip(np.rint(cloud.intensity[timed]), 0, 255).astype(np.uint8)
            yield PointBatch(cloud.points[timed], t_ns, refl, cloud.line[timed])

    def _cut_frame(self, done: StreamFrame, frame_id: str) -> Frame:
        pts = done.points
        stamp = (done.start_ns - self.origin_ns) / NS
        t = (pts.t_ns - self.origin_ns) / NS
        return self._frame(stamp, frame_id, pts.xyz, t, pts.reflectivity, pts.line)

    def _frame(
        self,
        stamp: float,
        frame_id: str,
        xyz: FloatArray,
        t: FloatArray | None,
        intensity: Any,
        line: Any,
    ) -> Frame:
        end = stamp + self.period
        root = self.options.pose_frame or self.tf.root(frame_id)
        if frame_id in self.tf and root != frame_id:
            if self.options.sensor_pose is not None and self.pose_warning is None:
                self.pose_warning = (
                    f"{self.path.name}'s /tf gives the pose of its LiDAR frame {frame_id!r} "
                    f"(the chain from {root!r}), so --sensor-pose is ignored"
                )
            times = np.concatenate(
                [[stamp], self.tf.sample_times(root, frame_id, stamp, end), [end]]
            )
            poses = self.tf.lookup(root, frame_id, times)
            return fixed_pose_frame(stamp, self.period, xyz, t, intensity, line, poses, times)
        pose = self.options.sensor_pose
        if pose is None and self.pose_warning is None:
            self.pose_warning = identity_pose_warning(self.path, frame_id)
        return fixed_pose_frame(stamp, self.period, xyz, t, intensity, line, pose)


def _choose(
    conns: Sequence[Any],
    wanted: str | None,
    types: frozenset[str],
    what: str,
    option: str,
    optional: bool = False,
) -> Any | None:
    """The connection of topic ``wanted``, or the only one of the right types."""
    if wanted is not None:
        named = [c for c in conns if c.topic == wanted]
        if not named:
            have = ", ".join(sorted({c.topic for c in conns})) or "none"
            raise RecordingError(f"no topic {wanted!r} in the recording (topics: {have})")
        if named[0].msgtype not in types:
            kinds = ", ".join(sorted(t.replace("/msg/", "/") for t in types))
            raise RecordingError(
                f"topic {wanted} has type {named[0].msgtype}, not a {what} type ({kinds})"
            )
        return named[0]
    found = {c.topic: c for c in conns if c.msgtype in types}
    if len(found) == 1:
        return next(iter(found.values()))
    if not found:
        if optional:
            return None
        raise RecordingError(f"the recording has no {what} topic; topics: {_listing(conns)}")
    if optional:
        log.warning("several %s topics (%s): give one with %s", what, ", ".join(found), option)
        return None
    raise RecordingError(
        f"several {what} topics ({', '.join(sorted(found))}): choose with {option}"
    )


def _listing(conns: Sequence[Any]) -> str:
    return ", ".join(f"{c.topic} ({c.msgtype})" for c in conns) or "none"
