"""Write a simulated run as the recording a real rig would make (``dronetrack record``).

Topics:
- ``/livox/lidar``: ``livox_ros_driver(2)/CustomMsg`` (the Livox driver's own
  format, ROS 1 / ROS 2 package names) or ``sensor_msgs/PointCloud2`` with the
  livox_ros_driver2 point layout; frame ``lidar``; the header stamp is the
  frame's start and every point keeps its own time;
- ``/tf_static``: world → turret_base and tilt_link → lidar;
- ``/tf``: turret_base → pan_link (pan) and pan_link → tilt_link (tilt), at
  ``tf_rate_hz``, as a robot_state_publisher would from joint states; on a moving
  observer also world → base_link (its odometry), and turret_base hangs from
  base_link instead of world;
- ``/ground_truth/pose``: ``geometry_msgs/PoseStamped`` of the target in ``world``
  at every frame end (motion capture);
- ``/dronetrack/config``: the resolved scenario (TOML) in a ``std_msgs/String``.

Containers: ``ros1`` (``.bag``), ``ros2-sqlite3`` and ``ros2-mcap``.  A ROS 2 path
ending in ``.db3`` or ``.mcap`` is written as that one bare file; any other path
becomes a rosbag2 folder with ``metadata.yaml``.  ``record_format`` takes the
container from the path's suffix and refuses a suffix that says another one; it
also knows Livox Viewer's ``lvx`` (``.lvx``) and ``lvx2`` (``.lvx2``), which
``sinks.lvx_writer`` writes.

Compression (``compress=True``): LZ4 chunks in a ROS 1 bag (rosbag's own choice
for speed), zstd chunks in MCAP (the MCAP storage's), and zstd per message in a
rosbag2 sqlite3 folder (rosbag2's message mode; its metadata.yaml says so, which
is why a bare ``.db3`` file, which has none, is written uncompressed only).
"""

from __future__ import annotations

import shutil
import tempfile
from pathlib import Path
from typing import Any, Literal, cast, get_args

import numpy as np
from rosbags.typesys import get_types_from_msg

from dronetrack.errors import ConfigError, InputError
from dronetrack.formats.ros.livox_msg import (
    LIVOX_POINT,
    LivoxCloud,
    encode_livox_cdr,
    encode_livox_ros1,
    livox_typestore,
)
from dronetrack.formats.ros.pointcloud2 import encode_cloud
from dronetrack.geometry.mount import (
    TURRET_FRAMES,
    MountGeometry,
    pointing_angles,
    sensor_poses,
    turret_links,
)
from dronetrack.geometry.transforms import (
    FloatArray,
    interpolate_poses,
    make_pose,
    matrix_to_quaternion,
)
from dronetrack.sources.recordings.bag import (
    CONFIG_TOPIC,
    POINTCLOUD2,
    POSESTAMPED,
    STRING_TYPE,
    TF_TYPE,
)
from dronetrack.types import Frame, Sample, StepResult

__all__ = [
    "DEFAULT_START_NS",
    "FORMAT_NAMES",
    "LIDAR_TOPIC",
    "RecordFormat",
    "RecordingWriter",
    "record_format",
]

RecordFormat = Literal["ros1", "ros2-sqlite3", "ros2-mcap", "lvx", "lvx2"]
RECORD_FORMATS: tuple[str, ...] = get_args(RecordFormat)
LIDAR_TOPIC = "/livox/lidar"
GT_TOPIC = "/ground_truth/pose"
DEFAULT_START_NS = 1_767_225_600 * 1_000_000_000  # t = 0 is 2026-01-01 00:00:00 UTC
_LIDAR_FRAME = TURRET_FRAMES[-1]
BODY_FRAME = "base_link"  # a moving observer's body
TF_MSG = "geometry_msgs/TransformStamped[] transforms"
# The container a suffix names; no suffix (or another) leaves the choice to --format.
SUFFIX_FORMATS: dict[str, RecordFormat] = {
    ".bag": "ros1",
    ".mcap": "ros2-mcap",
    ".db3": "ros2-sqlite3",
    ".lvx": "lvx",
    ".lvx2": "lvx2",
}
FORMAT_NAMES = {
    "ros1": "ROS 1 bag",
    "ros2-mcap": "ROS 2 bag, MCAP storage",
    "ros2-sqlite3": "ROS 2 bag, sqlite3 storage",
    "lvx": "Livox Viewer LVX 1.1",
    "lvx2": "Livox Viewer 2 LVX2",
}
COMPRESSION = {"ros1": "lz4", "ros2-mcap": "zstd", "ros2-sqlite3": "zstd, per message"}


def record_format(path: Path, fmt: str | None) -> RecordFormat:
    """The container to write ``path`` as: ``fmt`` if given, else the one its suffix
    names (.bag, .mcap, .db3, .lvx, .lvx2), else ROS 1.  A ``ConfigError`` when the two disagree
    (a .mcap file of ROS 1 bytes would be unreadable as MCAP)."""
    implied = SUFFIX_FORMATS.get(path.suffix.lower())
    if fmt is None:
        return implied or "ros1"
    if fmt not in RECORD_FORMATS:
        raise ConfigError(f"unknown format {fmt!r}; choose one of {', '.join(RECORD_FORMATS)}")
    if implied is not None and implied != fmt:
        wanted = {v: k for k, v in SUFFIX_FORMATS.items()}[cast(RecordFormat, fmt)]
        folder = "" if fmt in ("lvx", "lvx2") else " (or a folder, for ROS 2)"
        raise ConfigError(
            f"--format {fmt} writes a {FORMAT_NAMES[fmt]}, but --out {path} ends in "
            f"{path.suffix}, which is for {implied}; name it {path.stem}{wanted}{folder}, "
            f"or give --format {implied}"
        )
    return cast(RecordFormat, fmt)


class RecordingWriter:
    """Streams frames, turret transforms and ground truth into a bag; ``close`` finishes it."""

    def __init__(
        self,
        path: Path,
        fmt: RecordFormat,
        mount: MountGeometry,
        *,
        livox_custom: bool = True,
        config_text: str | None = None,
        start_ns: int = DEFAULT_START_NS,
        tf_rate_hz: float = 100.0,
        observer: bool = False,
        compress: bool = False,
    ) -> None:
        fmt = record_format(path, fmt)  # the container the suffix names, if fmt agrees
        if fmt in ("lvx", "lvx2"):
            raise ConfigError(f"{fmt} is Livox Viewer's format, which sinks.lvx_writer writes")
        if path.exists():
            raise ConfigError(f"{path} exists; choose a new --out")
        if compress and fmt == "ros2-sqlite3" and path.suffix == ".db3":
            raise ConfigError(
                f"--compress: a bare .db3 file has no metadata.yaml to say its messages are "
                f"compressed, so no reader could decompress {path}; write a rosbag2 folder "
                "(--out without a suffix) or MCAP (--out NAME.mcap)"
            )
        if tf_rate_hz <= 0:
            raise ConfigError(f"tf_rate_hz must be > 0, got {tf_rate_hz}")
        self.path = path
        self.ros1 = fmt == "ros1"
        self.mount = mount
        self.livox = livox_custom
        self.start_ns = start_ns
        self.tf_period = 1.0 / tf_rate_hz
        self.ts = livox_typestore(ros1=self.ros1)
        if TF_TYPE not in self.ts.types:  # the Noetic store lacks tf2_msgs
            self.ts.register(get_types_from_msg(TF_MSG, TF_TYPE))
        self._seq = 0
        self._bare: Path | None = None
        self.format = fmt
        self.compression = COMPRESSION[fmt] if compress else None
        self._writer = self._open(path, fmt, compress)
        lidar_type = (
            ("livox_ros_driver" if self.ros1 else "livox_ros_driver2") + "/msg/CustomMsg"
            if livox_custom
            else POINTCLOUD2
        )
        self._lidar_type = lidar_type
        add = self._writer.add_connection
        self._lidar = add(LIDAR_TOPIC, lidar_type, typestore=self.ts)
        self._tf = add("/tf", TF_TYPE, typestore=self.ts)
        self._tf_static = add("/tf_static", TF_TYPE, typestore=self.ts)
        self._gt = add(GT_TOPIC, POSESTAMPED, typestore=self.ts)
        self._next_tf = 0.0
        self._last: tuple[Frame, tuple[float, float]] | None = None
        # On a moving observer the turret (held still) rides on its body:
        # world → base_link (odometry) → turret_base.
        self.observer = observer
        links = turret_links(0.0, 0.0, mount)
        base = (BODY_FRAME, *links[0][1:]) if observer else links[0]
        static = [base, links[-1]]
        self._write(self._tf_static, 0.0, self._tf_message(0.0, static), TF_TYPE)
        if config_text is not None:
            conn = add(CONFIG_TOPIC, STRING_TYPE, typestore=self.ts)
            msg = self.ts.types[STRING_TYPE](data=config_text)
            self._write(conn, 0.0, msg, STRING_TYPE)

    def _open(self, path: Path, fmt: str, compress: bool) -> Any:
        path.parent.mkdir(parents=True, exist_ok=True)
        if self.ros1:
            from rosbags.rosbag1 import Writer as Writer1

            w1 = Writer1(path)
            if compress:
                w1.set_compression(Writer1.CompressionFormat.LZ4)
            w1.open()
            return w1
        from rosbags.rosbag2 import CompressionFormat, CompressionMode, StoragePlugin
        from rosbags.rosbag2 import Writer as Writer2

        mcap = fmt == "ros2-mcap"
        plugin = StoragePlugin.MCAP if mcap else StoragePlugin.SQLITE3
        target = path
        if path.suffix in (".mcap", ".db3"):
            self._bare = Path(tempfile.mkdtemp(prefix="dronetrack-record-")) / "bag"
            target = self._bare
        w2 = Writer2(target, version=9, storage_plugin=plugin)
        if compress:
            mode = CompressionMode.STORAGE if mcap else CompressionMode.MESSAGE
            w2.set_compression(mode, CompressionFormat.ZSTD)
        w2.open()
        return w2

    def _ns(self, t: float) -> int:
        return self.start_ns + round(t * 1e9)

    def _header(self, t: float, frame_id: str) -> Any:
        sec, nsec = divmod(self._ns(t), 1_000_000_000)
        stamp = self.ts.types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)
        Header = self.ts.types["std_msgs/msg/Header"]
        if self.ros1:
            self._seq += 1
            return Header(seq=self._seq, stamp=stamp, frame_id=frame_id)
        return Header(stamp=stamp, frame_id=frame_id)

    def _write(self, conn: Any, t: float, msg: Any, msgtype: str) -> None:
        raw = (
            self.ts.serialize_ros1(msg, msgtype)
            if self.ros1
            else self.ts.serialize_cdr(msg, msgtype)
        )
        self._writer.write(conn, self._ns(t), raw)

    def _tf_message(self, t: float, links: list[tuple[str, str, FloatArray]]) -> Any:
        types = self.ts.types
        out = []
        for parent, child, T in links:
            w, x, y, z = matrix_to_quaternion(T[:3, :3])
            p = T[:3, 3]
            transform = types["geometry_msgs/msg/Transform"](
                translation=types["geometry_msgs/msg/Vector3"](x=p[0], y=p[1], z=p[2]),
                rotation=types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
            )
            out.append(
                types["geometry_msgs/msg/TransformStamped"](
                    header=self._header(t, parent), child_frame_id=child, transform=transform
                )
            )
        return types[TF_TYPE](transforms=out)

    def frame(
        self,
        frame: Frame,
        target: FloatArray,
        attitude: FloatArray,
        turret: tuple[float, float] = (0.0, 0.0),
    ) -> None:
        """Write one frame, the turret's transforms during it and the target's pose at its
        end.  ``turret``: the (fixed) pan and tilt [rad] on a moving observer."""
        self._write_turret(frame, turret)
        self._write_points(frame)
        self._write_truth(frame.end, target, attitude)

    def write(self, sample: Sample, result: StepResult) -> None:
        """The run loop's sink: every frame, with the simulator's truth (the target's
        position and attitude) and the turret's angles."""
        truth, turret = sample.truth, sample.turret
        attitude = getattr(truth, "target_attitude", None)
        if truth is None or attitude is None:
            raise InputError(
                "a recording is written from a simulated run: its frames need the truth"
            )
        angles = (0.0, 0.0) if turret is None else (turret.pan, turret.tilt)
        self.frame(sample.frame, truth.target_position, attitude, angles)

    def _write_turret(self, frame: Frame, turret: tuple[float, float]) -> None:
        """The /tf samples in [frame start, frame end); the next frame writes its end."""
        self._last = (frame, turret)
        times = np.arange(self._next_tf, frame.end - 1e-9, self.tf_period)
        times = times[times >= frame.pose_t[0] - 1e-9]
        if len(times) == 0:
            return
        self._next_tf = float(times[-1] + self.tf_period)
        self._write_tf_at(frame, times, turret)

    def _write_tf_at(self, frame: Frame, times: FloatArray, turret: tuple[float, float]) -> None:
        if self.observer:
            self._write_observer(frame, times, *turret)
            return
        pan, tilt = pointing_angles(frame.poses)
        pan = np.interp(times, frame.pose_t, np.unwrap(pan))
        tilt = np.interp(times, frame.pose_t, tilt)
        for t, a, b in zip(times, pan, tilt, strict=True):
            moving = turret_links(a, b, self.mount)[1:3]
            self._write(self._tf, float(t), self._tf_message(float(t), moving), TF_TYPE)

    def _write_observer(self, frame: Frame, times: FloatArray, pan: float, tilt: float) -> None:
        """world → base_link from the frame's poses, the fixed turret links after it."""
        # world_T_body = world_T_sensor · (body_T_sensor)⁻¹, body_T_sensor the fixed turret
        body = frame.poses @ np.linalg.inv(sensor_poses(pan, tilt, self.mount))
        R, p = interpolate_poses(frame.pose_t, body, times)
        links = turret_links(pan, tilt, self.mount)[1:3]
        for t, T in zip(times, make_pose(R, p), strict=True):
            edges = [(TURRET_FRAMES[0], BODY_FRAME, T), *links]
            self._write(self._tf, float(t), self._tf_message(float(t), edges), TF_TYPE)

    def _write_points(self, frame: Frame) -> None:
        t_rel = frame.t - frame.stamp
        if self.livox:
            stamp_ns = self._ns(frame.stamp)
            pts = np.zeros(len(frame), dtype=LIVOX_POINT)
            pts["offset_time"] = np.clip(np.round(t_rel * 1e9), 0, 2**32 - 1)
            for k, axis in enumerate("xyz"):
                pts[axis] = frame.points[:, k]
            pts["reflectivity"] = np.clip(np.round(frame.intensity), 0, 255)
            pts["line"] = frame.line
            cloud = LivoxCloud(stamp_ns, _LIDAR_FRAME, stamp_ns, pts)
            raw = encode_livox_ros1(cloud, self._seq) if self.ros1 else encode_livox_cdr(cloud)
            self._writer.write(self._lidar, stamp_ns, raw)
            return
        fields, data, step = encode_cloud(
            frame.points, t_rel, frame.intensity, frame.line, self._ns(frame.stamp) * 1e-9
        )
        types = self.ts.types
        PointField = types["sensor_msgs/msg/PointField"]
        msg = types[POINTCLOUD2](
            header=self._header(frame.stamp, _LIDAR_FRAME),
            height=1,
            width=len(frame),
            fields=[
                PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count)
                for f in fields
            ],
            is_bigendian=False,
            point_step=step,
            row_step=step * len(frame),
            data=np.frombuffer(data, dtype=np.uint8),
            is_dense=True,
        )
        self._write(self._lidar, frame.stamp, msg, POINTCLOUD2)

    def _write_truth(self, t: float, target: FloatArray, attitude: FloatArray) -> None:
        types = self.ts.types
        w, x, y, z = matrix_to_quaternion(attitude)
        pose = types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=target[0], y=target[1], z=target[2]),
            orientation=types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w),
        )
        msg = types[POSESTAMPED](header=self._header(t, TURRET_FRAMES[0]), pose=pose)
        self._write(self._gt, t, msg, POSESTAMPED)

    def close(self) -> None:
        """Finish the bag (and move a bare ROS 2 file into place)."""
        if self._last is not None:  # the last frame's end, which no next frame writes
            frame, turret = self._last
            self._write_tf_at(frame, np.array([frame.end]), turret)
            self._last = None
        self._writer.close()
        if self._bare is not None:
            files = sorted(self._bare.glob("*.mcap")) + sorted(self._bare.glob("*.db3"))
            shutil.move(str(files[0]), self.path)
            shutil.rmtree(self._bare.parent, ignore_errors=True)
