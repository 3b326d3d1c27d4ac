"""The small ROS 2 messages dronetrack reads and writes, as CDR bytes, with rosbags.

rosbags' Humble typestore with the Livox and Interbotix messages registered
(``ros2_typestore``) serialises and deserialises them; the point clouds go
through our own numpy codecs (``formats.ros.pointcloud2``, ``formats.ros.livox_msg``), as a
generic deserialiser makes one Python object per point.  Times are ROS times in
integer nanoseconds, split as ``builtin_interfaces/Time`` (sec, nanosec).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Literal

import numpy as np
from rosbags.typesys.store import Typestore

from dronetrack.errors import DecodeError
from dronetrack.formats.ros.livox_msg import livox_typestore
from dronetrack.formats.ros.pointcloud2 import encode_cloud
from dronetrack.geometry.transforms import FloatArray, matrix_to_quaternion

__all__ = [
    "JOINT_GROUP_COMMAND",
    "JOINT_STATE",
    "MARKER_ARRAY",
    "NS",
    "PATH",
    "POINTCLOUD2",
    "POINT_STAMPED",
    "STRING",
    "TF_MESSAGE",
    "JointReading",
    "MarkerSpec",
    "TfSample",
    "decode_joint_state",
    "decode_tf",
    "encode_joint_command",
    "encode_marker_array",
    "encode_path",
    "encode_point_stamped",
    "encode_points",
    "encode_tf",
    "ros2_typestore",
]

NS = 1_000_000_000
POINTCLOUD2 = "sensor_msgs/msg/PointCloud2"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
JOINT_STATE = "sensor_msgs/msg/JointState"
JOINT_GROUP_COMMAND = "interbotix_xs_msgs/msg/JointGroupCommand"
POINT_STAMPED = "geometry_msgs/msg/PointStamped"
PATH = "nav_msgs/msg/Path"
STRING = "std_msgs/msg/String"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
MARKER = "visualization_msgs/msg/Marker"

_JOINT_GROUP_COMMAND_MSG = "string name\nfloat32[] cmd\n"


@lru_cache(maxsize=1)
def ros2_typestore() -> Typestore:
    """rosbags' Humble typestore with livox_ros_driver2 and interbotix_xs_msgs added."""
    from rosbags.typesys import get_types_from_msg

    ts = livox_typestore(ros1=False)
    ts.register(get_types_from_msg(_JOINT_GROUP_COMMAND_MSG, JOINT_GROUP_COMMAND))
    return ts


def _cdr(msg: Any, msg_type: str) -> bytes:
    return bytes(ros2_typestore().serialize_cdr(msg, msg_type, little_endian=True))


def _header(stamp_ns: int, frame_id: str) -> Any:
    types = ros2_typestore().types
    sec, nanosec = divmod(int(stamp_ns), NS)
    stamp = types["builtin_interfaces/msg/Time"](sec=sec, nanosec=nanosec)
    return types["std_msgs/msg/Header"](stamp=stamp, frame_id=frame_id)


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * NS + int(header.stamp.nanosec)


def _decode(raw: bytes | memoryview, msg_type: str) -> Any:
    try:
        return ros2_typestore().deserialize_cdr(bytes(raw), msg_type)
    except Exception as exc:  # rosbags raises many kinds on bad bytes
        raise DecodeError(f"a bad {msg_type}: {exc}") from None


def encode_point_stamped(stamp_ns: int, frame_id: str, p: FloatArray) -> bytes:
    """geometry_msgs/PointStamped of ``p`` (3,) [m]."""
    types = ros2_typestore().types
    x, y, z = (float(v) for v in np.asarray(p, dtype=np.float64).reshape(3))
    point = types["geometry_msgs/msg/Point"](x=x, y=y, z=z)
    return _cdr(
        types[POINT_STAMPED](header=_header(stamp_ns, frame_id), point=point), POINT_STAMPED
    )


def encode_path(stamp_ns: int, frame_id: str, points: FloatArray) -> bytes:
    """nav_msgs/Path through ``points`` (K, 3) [m], identity orientations."""
    types = ros2_typestore().types
    header = _header(stamp_ns, frame_id)
    q = types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)
    poses = []
    for x, y, z in np.asarray(points, dtype=np.float64).reshape(-1, 3).tolist():
        pose = types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=x, y=y, z=z), orientation=q
        )
        poses.append(types["geometry_msgs/msg/PoseStamped"](header=header, pose=pose))
    return _cdr(types[PATH](header=header, poses=poses), PATH)


def encode_points(
    stamp_ns: int,
    frame_id: str,
    points: FloatArray,
    t_rel: FloatArray | None = None,
    intensity: FloatArray | None = None,
    line: FloatArray | None = None,
) -> bytes:
    """sensor_msgs/PointCloud2 of ``points`` (N, 3) [m] in the livox_ros_driver2 layout
    (``pointcloud2.encode_cloud``); times ``t_rel`` [s] after the stamp."""
    types = ros2_typestore().types
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n = len(p)
    zeros = np.zeros(n)
    fields, data, step = encode_cloud(
        p,
        zeros if t_rel is None else t_rel,
        zeros if intensity is None else intensity,
        zeros if line is None else line,
        stamp_ns / NS,
    )
    msg = types[POINTCLOUD2](
        header=_header(stamp_ns, frame_id),
        height=1,
        width=n,
        fields=[
            types["sensor_msgs/msg/PointField"](
                name=f.name, offset=f.offset, datatype=f.datatype, count=f.count
            )
            for f in fields
        ],
        is_bigendian=False,
        point_step=step,
        row_step=step * n,
        data=np.frombuffer(data, dtype=np.uint8),
        is_dense=True,
    )
    return _cdr(msg, POINTCLOUD2)


def encode_tf(stamp_ns: int, links: Sequence[tuple[str, str, FloatArray]]) -> bytes:
    """tf2_msgs/TFMessage of (parent, child, parent_T_child (4, 4)) edges."""
    types = ros2_typestore().types
    out = []
    for parent, child, T in links:
        w, x, y, z = matrix_to_quaternion(np.asarray(T)[:3, :3])
        px, py, pz = (float(v) for v in np.asarray(T)[:3, 3])
        transform = types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=px, y=py, z=pz),
            rotation=types["geometry_msgs/msg/Quaternion"](
                x=float(x), y=float(y), z=float(z), w=float(w)
            ),
        )
        out.append(
            types["geometry_msgs/msg/TransformStamped"](
                header=_header(stamp_ns, parent), child_frame_id=child, transform=transform
            )
        )
    return _cdr(types[TF_MESSAGE](transforms=out), TF_MESSAGE)


@dataclass(frozen=True, slots=True)
class MarkerSpec:
    """One visualization_msgs/Marker: a sphere ``size`` [m] wide or a text ``size`` [m]
    high at ``position`` [m], or the deletion of marker ``id`` of namespace ``ns``."""

    ns: str
    id: int
    kind: Literal["sphere", "text", "delete"]
    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    size: float = 0.0
    rgba: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)  # each 0-1
    text: str = ""


def _marker(types: Any, header: Any, spec: MarkerSpec) -> Any:
    cls = types[MARKER]
    kind = {"sphere": cls.SPHERE, "text": cls.TEXT_VIEW_FACING, "delete": cls.SPHERE}[spec.kind]
    action = cls.DELETE if spec.kind == "delete" else cls.ADD
    x, y, z = (float(v) for v in spec.position)
    r, g, b, a = (float(v) for v in spec.rgba)
    size = float(spec.size)
    no_bytes = np.zeros(0, dtype=np.uint8)
    return cls(
        header=header,
        ns=spec.ns,
        id=int(spec.id),
        type=kind,
        action=action,
        pose=types["geometry_msgs/msg/Pose"](
            position=types["geometry_msgs/msg/Point"](x=x, y=y, z=z),
            orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        ),
        scale=types["geometry_msgs/msg/Vector3"](x=size, y=size, z=size),
        color=types["std_msgs/msg/ColorRGBA"](r=r, g=g, b=b, a=a),
        lifetime=types["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
        frame_locked=False,
        points=[],
        colors=[],
        texture_resource="",
        texture=types["sensor_msgs/msg/CompressedImage"](
            header=_header(0, ""), format="", data=no_bytes
        ),
        uv_coordinates=[],
        text=spec.text,
        mesh_resource="",
        mesh_file=types["visualization_msgs/msg/MeshFile"](filename="", data=no_bytes),
        mesh_use_embedded_materials=False,
    )


def encode_marker_array(stamp_ns: int, frame_id: str, markers: Sequence[MarkerSpec]) -> bytes:
    """visualization_msgs/MarkerArray (ROS 2 Humble's Marker) of ``markers``, in order;
    each lives until replaced or deleted."""
    types = ros2_typestore().types
    header = _header(stamp_ns, frame_id)
    msg = types[MARKER_ARRAY](markers=[_marker(types, header, m) for m in markers])
    return _cdr(msg, MARKER_ARRAY)


@dataclass(frozen=True, slots=True)
class TfSample:
    """One transform of a TFMessage: parent_T_child at ``stamp_ns``."""

    stamp_ns: int
    parent: str
    child: str
    translation: tuple[float, float, float]
    rotation_xyzw: tuple[float, float, float, float]


def decode_tf(raw: bytes | memoryview) -> list[TfSample]:
    """The transforms of a tf2_msgs/TFMessage; DecodeError for bad bytes."""
    msg = _decode(raw, TF_MESSAGE)
    out = []
    for tr in msg.transforms:
        p, q = tr.transform.translation, tr.transform.rotation
        out.append(
            TfSample(
                _stamp_ns(tr.header),
                str(tr.header.frame_id),
                str(tr.child_frame_id),
                (float(p.x), float(p.y), float(p.z)),
                (float(q.x), float(q.y), float(q.z), float(q.w)),
            )
        )
    return out


def encode_joint_state(
    stamp_ns: int,
    names: Sequence[str],
    position: Sequence[float],
    velocity: Sequence[float] = (),
) -> bytes:
    """sensor_msgs/JointState with the joints ``names`` at ``position`` [rad]."""
    types = ros2_typestore().types
    msg = types[JOINT_STATE](
        header=_header(stamp_ns, ""),
        name=list(names),
        position=np.asarray(position, dtype=np.float64),
        velocity=np.asarray(velocity, dtype=np.float64),
        effort=np.zeros(0, dtype=np.float64),
    )
    return _cdr(msg, JOINT_STATE)


def encode_joint_command(group: str, cmd: Sequence[float]) -> bytes:
    """interbotix_xs_msgs/JointGroupCommand: ``cmd`` [rad] for the joints of ``group``."""
    msg = ros2_typestore().types[JOINT_GROUP_COMMAND](
        name=group, cmd=np.asarray(cmd, dtype=np.float32)
    )
    return _cdr(msg, JOINT_GROUP_COMMAND)


@dataclass(frozen=True, slots=True)
class JointReading:
    """A JointState's stamp [ns] and each named joint's position and velocity (NaN
    where the message gives none)."""

    stamp_ns: int
    position: dict[str, float]
    velocity: dict[str, float]


def decode_joint_state(raw: bytes | memoryview) -> JointReading:
    """A sensor_msgs/JointState; DecodeError for bad bytes."""
    msg = _decode(raw, JOINT_STATE)
    names = [str(n) for n in msg.name]
    pos = [float(v) for v in msg.position]
    vel = [float(v) for v in msg.velocity]
    if len(pos) not in (0, len(names)) or len(vel) not in (0, len(names)):
        raise DecodeError(
            f"a JointState with {len(names)} names has {len(pos)} positions and "
            f"{len(vel)} velocities"
        )
    nan = float("nan")
    return JointReading(
        _stamp_ns(msg.header),
        {n: (pos[i] if pos else nan) for i, n in enumerate(names)},
        {n: (vel[i] if vel else nan) for i, n in enumerate(names)},
    )
