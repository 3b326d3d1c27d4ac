"""ROS 1 bags, ROS 2 bags (sqlite3 and MCAP storage) and bare ``.mcap`` files.

The containers are read with rosbags (pure Python, no ROS install).  Point
messages are decoded from their bytes by our numpy decoders
(``io.pointcloud2_raw``, ``io.livox``): rosbags' generic deserialiser makes one
Python object per Livox point, about 100× too slow for replay, and copies a
PointCloud2's data.

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
"""

from __future__ import annotations

import logging
import shutil
import struct
import tempfile
import weakref
from collections import Counter
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag1 import ReaderError as Reader1Error
from rosbags.rosbag2 import ReaderError as Reader2Error

from dronetrack.errors import DecodeError, RecordingError
from dronetrack.formats.livox import (
    LIVOX_TYPES,
    LivoxCloud,
    decode_livox_cdr,
    decode_livox_ros1,
    livox_points,
    livox_typestore,
)
from dronetrack.formats.magic import EXPECTED, check_mcap_end, ros1_damage, sniff_file
from dronetrack.formats.pointcloud2 import CloudPoints, cloud_points
from dronetrack.formats.pointcloud2_raw import (
    RawCloud,
    decode_pointcloud2_cdr,
    decode_pointcloud2_ros1,
)
from dronetrack.geometry.geodesy import enu_from_geodetic
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sources.mcap_info import check_ros2_profile
from dronetrack.sources.recording import (
    GroundTruth,
    RecordingInfo,
    ReplayOptions,
    TopicInfo,
    fixed_pose_frame,
    frame_period,
    identity_pose_warning,
)
from dronetrack.sources.tf import TransformBuffer
from dronetrack.types import Frame

__all__ = ["CONFIG_TOPIC", "BagFile", "BagRecording", "bag_paths"]

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
_MAX_WARNINGS = 5  # per reason; later skips are only counted


_SUFFIX = {"ros1": ".bag", "mcap": ".mcap", "sqlite3": ".db3"}


def bag_paths(path: Path) -> list[Path]:
    """What to hand to rosbags: split ROS 1 bags in a folder, else the path itself."""
    if path.is_dir() and not (path / "metadata.yaml").exists():
        return sorted(path.glob("*.bag"))
    return [path]


def _kind(path: Path) -> str:
    """The container, as ``dronetrack info`` names it."""
    if path.is_dir():
        if any(path.glob("*.bag")) and not (path / "metadata.yaml").exists():
            return "ros1"
        return "ros2-sqlite3" if any(path.glob("*.db3")) else "ros2-mcap"
    return {"ros1": "ros1", "mcap": "mcap", "sqlite3": "ros2-sqlite3"}.get(
        sniff_file(path) or "", "unknown"
    )


def _open_error(path: Path, exc: Exception) -> RecordingError:
    """One line on why the bag ``path`` does not open, and what can be done about it."""
    damage = ros1_damage(path) if path.is_file() and sniff_file(path) == "ros1" else None
    if damage is not None:
        return RecordingError(f"{path}: {damage}")
    if isinstance(exc, UnicodeDecodeError):
        return RecordingError(
            f"{path}: cannot open the recording: it is corrupt (a header field that should "
            "be text is not UTF-8)"
        )
    return RecordingError(f"{path}: cannot open the recording: {exc}")


def _rosbags_paths(path: Path) -> tuple[list[Path], Path | None]:
    """The paths to hand to rosbags, which tells the containers apart by suffix, and a
    temporary folder to remove afterwards: a bag file whose suffix does not say what it
    holds (``record --out flight`` writes one) is handed over as a link named right."""
    paths = bag_paths(path)
    if path.is_dir():
        for inner in path.glob("*.mcap"):
            check_mcap_end(inner)
        return paths, None
    kind = sniff_file(path)
    if kind == "mcap":
        check_mcap_end(path)
        check_ros2_profile(path)
    suffix = _SUFFIX.get(kind or "")
    if suffix is None:
        raise RecordingError(f"{path} is not a bag: it starts with none of {EXPECTED}")
    if path.suffix == suffix:
        return paths, None
    alias = Path(tempfile.mkdtemp(prefix="dronetrack-bag-"))
    link = alias / f"{path.stem or 'recording'}{suffix}"
    link.symlink_to(path.resolve())
    return [link], alias


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


# What a corrupt message or container can raise from rosbags or our decoders.
_BAD_DATA = (
    AnyReaderError,
    Reader1Error,
    Reader2Error,
    EOFError,
    OverflowError,
    DecodeError,
    ValueError,
    IndexError,
    KeyError,
    struct.error,
    UnicodeDecodeError,
    # rosbags' ROS 1 reader checks a chunk's message against its index entry with an
    # assert (the two times must agree), so a flipped byte there raises AssertionError
    AssertionError,
)


class BagFile:
    """A bag's container: open it, list it, iterate its raw messages."""

    def __init__(self, path: Path, *, check: bool = True) -> None:
        self.path = path
        self.skipped: Counter[str] = Counter()
        self._warned: Counter[str] = Counter()
        self._paths: list[Path] | None = None
        if check:
            with self._reader():
                pass  # fail now, with one line, if it cannot be opened

    def info(self) -> RecordingInfo:
        """Topics, types, message counts and duration."""
        with self._reader() as reader:
            counts: Counter[tuple[str, str]] = Counter()
            for c in reader.connections:
                counts[(c.topic, c.msgtype)] += int(c.msgcount)
            start, end = int(reader.start_time), int(reader.end_time)
        topics = tuple(TopicInfo(t, m, n) for (t, m), n in sorted(counts.items()))
        return RecordingInfo(
            self.path, _kind(self.path), start * 1e-9, (end - start) * 1e-9, topics
        )

    def _rosbags_paths(self) -> list[Path]:
        if self._paths is None:
            if not self.path.exists():
                raise RecordingError(f"{self.path}: no such recording")
            self._paths, alias = _rosbags_paths(self.path)
            if alias is not None:
                weakref.finalize(self, shutil.rmtree, alias, ignore_errors=True)
        return self._paths

    @contextmanager
    def _reader(self) -> Iterator[Any]:
        paths = self._rosbags_paths()
        if not paths or not all(p.exists() for p in paths):
            raise RecordingError(f"{self.path}: no such recording")
        try:
            reader = AnyReader(paths, default_typestore=livox_typestore(ros1=False))
            reader.open()
        except (OSError, *_BAD_DATA) as exc:
            raise _open_error(self.path, exc) from None
        try:
            yield reader
        except (AnyReaderError, OSError) as exc:
            raise RecordingError(f"{self.path}: the recording is corrupt: {exc}") from None
        finally:
            reader.close()

    def _skip(self, reason: str, detail: object) -> None:
        self.skipped[reason] += 1
        self._warned[reason] += 1
        if self._warned[reason] <= _MAX_WARNINGS:
            log.warning("%s: skipped a message (%s): %s", self.path.name, reason, detail)

    def _messages(self, reader: Any, conns: Sequence[Any]) -> Iterator[tuple[Any, int, bytes]]:
        """(connection, log time, raw bytes); a corrupt container ends with a RecordingError."""
        # Connections belong to the reader that listed them: find this reader's own.
        wanted = {(c.topic, c.msgtype) for c in conns}
        own = [c for c in reader.connections if (c.topic, c.msgtype) in wanted]
        if not own:  # rosbags reads every connection when given none
            return
        it = reader.messages(connections=own)
        while True:
            try:
                item = next(it)
            except StopIteration:
                return
            except _BAD_DATA as exc:
                raise RecordingError(f"{self.path}: the recording is corrupt: {exc}") from None
            yield item

    def _deserialize(self, reader: Any, raw: bytes, msgtype: str, reason: str) -> Any | None:
        try:
            return reader.deserialize(raw, msgtype)
        except _BAD_DATA as exc:
            self._skip(reason, exc)
            return None


class BagRecording(BagFile):
    """A bag opened for replay (see the module docstring)."""

    def __init__(self, path: Path, options: ReplayOptions | None = None) -> None:
        super().__init__(path, check=False)  # opened below
        self.options = options = options or ReplayOptions()
        self._lidar_frame: str | None = None  # the clouds' frame_id, once one is decoded
        self.pose_warning: str | None = None  # set once a frame has no pose source
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
            self.period = frame_period(options, (np.asarray(stamps) - stamps[0]) * 1e-9)
            self.tf = self._read_tf(reader, conns)
            self.config_text = self._read_config(reader, conns)
            self.ground_truth = self._read_ground_truth(reader, gt) if gt is not None else None

    def _first_stamps(self, reader: Any) -> list[int]:
        """The header stamps [ns] of the first LiDAR messages (their points are not read)."""
        stamps: list[int] = []
        for _, _, raw in self._messages(reader, [self.lidar]):
            header = self._parse(reader, raw)
            if header is not None:
                self._lidar_frame = header.frame_id
                stamps.append(header.stamp_ns)
            if len(stamps) >= _PERIOD_SAMPLES:
                break
        self.skipped.clear()  # frames() reads these messages again and counts them then
        self._warned.clear()
        return stamps

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
        origin = self.options.gt_origin
        if origin is None:
            origin = (float(lla[0, 0]), float(lla[0, 1]), float(lla[0, 2]))
            log.warning(
                "%s: ground truth in an ENU frame at the first fix (%.7f°, %.7f°, %.2f m);"
                " give the sensor's position with --gt-origin",
                self.path.name,
                *origin,
            )
        return enu_from_geodetic(
            lla[:, 0], lla[:, 1], lla[:, 2], origin, self.options.gt_heading_deg
        )

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
        except _BAD_DATA as exc:
            self._skip("bad_point_message", exc)
        return None

    def _points(self, msg: LivoxCloud | RawCloud) -> CloudPoints | None:
        """Positions, times relative to the stamp, intensity and line, or None."""
        try:
            if isinstance(msg, LivoxCloud):
                return CloudPoints(*livox_points(msg))
            return cloud_points(msg.array(), msg.stamp_ns * 1e-9)
        except _BAD_DATA as exc:
            self._skip("bad_point_message", exc)
        return None

    def frames(self) -> Iterator[Frame]:
        """The LiDAR frames in the pose frame's time line (see the module docstring)."""
        with self._reader() as reader:
            for _, _, raw in self._messages(reader, [self.lidar]):
                msg = self._parse(reader, raw)
                cloud = self._points(msg) if msg is not None else None
                if msg is None or cloud is None:
                    continue
                stamp = (msg.stamp_ns - self.origin_ns) * 1e-9
                t = stamp + cloud.t if cloud.t is not None else None
                if t is not None and len(t):
                    stamp = min(stamp, float(t.min()))
                yield self._frame(stamp, msg.frame_id, cloud.points, t, cloud.intensity, cloud.line)

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
