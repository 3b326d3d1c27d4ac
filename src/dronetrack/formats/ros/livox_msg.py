"""Numpy decoding and encoding of Livox ``CustomMsg`` (livox_ros_driver, livox_ros_driver2).

The generic rosbags deserializer builds one Python object per point (about
100 ms per 24 k-point frame); these functions read and write the bytes directly.

Message definitions (identical in both drivers)::

    CustomPoint: uint32 offset_time  # ns after timebase
                 float32 x, y, z     # m, sensor frame
                 uint8 reflectivity, tag, line
    CustomMsg:   std_msgs/Header header
                 uint64 timebase     # absolute time of the frame's first point [ns]
                 uint32 point_num
                 uint8 lidar_id
                 uint8[3] rsvd
                 CustomPoint[] points

Absolute time of point i [ns] = ``timebase + points[i].offset_time``.

ROS 1 serialization (livox_ros_driver; little-endian, packed, no alignment)
---------------------------------------------------------------------------
``seq u32 | stamp.secs u32 | stamp.nsecs u32 | frame_id: len u32 + len bytes (no NUL)
| timebase u64 | point_num u32 | lidar_id u8 | rsvd 3 B | points: n u32 + n × 19 B``.
The message ends exactly after the last record.

ROS 2 CDR serialization (livox_ros_driver2)
-------------------------------------------
A 4-byte encapsulation header ``00 01 00 00`` (little-endian) or ``00 00 00 00``
(big-endian) precedes the payload.  Alignment is relative to the byte after that
header: each primitive of size s starts at a multiple of s.

``stamp.sec i32 | stamp.nanosec u32 | frame_id: len u32 (counts the NUL) + len bytes
| pad to 8 | timebase u64 | point_num u32 | lidar_id u8 | rsvd 3 B | points: n u32
| n records``.  Each record is 19 bytes aligned to 4, so records start every
20 bytes and the last one has no trailing pad byte: the points take
``20 n − 1`` bytes (0 when n = 0).  Up to 3 trailing bytes (padding to a 4-byte
boundary, as some middlewares write) are accepted after the last record.  A
frame_id length of 0 (no NUL) decodes as the empty string.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError, InputError
from dronetrack.formats.ros.wire import ByteCursor, as_byte_view, decode_string
from dronetrack.geometry.transforms import FloatArray

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

__all__ = [
    "CUSTOM_MSG_MSG",
    "CUSTOM_POINT_MSG",
    "LIVOX_POINT",
    "LIVOX_TYPES",
    "LivoxCloud",
    "decode_livox_cdr",
    "decode_livox_ros1",
    "encode_livox_cdr",
    "encode_livox_ros1",
    "livox_points",
    "livox_typestore",
    "register_livox_types",
]

CUSTOM_POINT_MSG = """\
uint32 offset_time
float32 x
float32 y
float32 z
uint8 reflectivity
uint8 tag
uint8 line
"""

CUSTOM_MSG_MSG = """\
std_msgs/Header header
uint64 timebase
uint32 point_num
uint8 lidar_id
uint8[3] rsvd
CustomPoint[] points
"""

_PACKAGES = ("livox_ros_driver", "livox_ros_driver2")
LIVOX_TYPES = frozenset(f"{pkg}/msg/CustomMsg" for pkg in _PACKAGES)

# One CustomPoint, packed (19 B): the ROS 1 record.
LIVOX_POINT = np.dtype(
    [
        ("offset_time", "<u4"),
        ("x", "<f4"),
        ("y", "<f4"),
        ("z", "<f4"),
        ("reflectivity", "u1"),
        ("tag", "u1"),
        ("line", "u1"),
    ]
)
_CDR_STRIDE = 20  # a CDR record: 19 B re-aligned to 4
# The same fields at the same offsets, padded to the CDR stride.
_CDR_POINT = np.dtype(
    {
        "names": ["offset_time", "x", "y", "z", "reflectivity", "tag", "line"],
        "formats": ["<u4", "<f4", "<f4", "<f4", "u1", "u1", "u1"],
        "offsets": [0, 4, 8, 12, 16, 17, 18],
        "itemsize": _CDR_STRIDE,
    }
)
_NS_PER_S = 1_000_000_000
_U32_MAX = 2**32 - 1
_U64_MAX = 2**64 - 1
_CDR_MAX_TRAILING = 3  # padding some middlewares append to reach a 4-byte boundary


@dataclass(frozen=True, slots=True)
class LivoxCloud:
    """One CustomMsg: header ``stamp_ns`` [ns], ``frame_id``, ``timebase_ns`` [ns],
    ``points`` (structured, the fields of LIVOX_POINT; may be a strided read-only view
    of the message bytes) and ``lidar_id``."""

    stamp_ns: int
    frame_id: str
    timebase_ns: int
    points: NDArray[np.void]
    lidar_id: int = 0


def register_livox_types(typestore: Typestore) -> None:
    """Register CustomPoint and CustomMsg of both Livox drivers on a rosbags typestore."""
    from rosbags.typesys import get_types_from_msg

    for pkg in _PACKAGES:
        types = get_types_from_msg(CUSTOM_POINT_MSG, f"{pkg}/msg/CustomPoint")
        types |= get_types_from_msg(CUSTOM_MSG_MSG, f"{pkg}/msg/CustomMsg")
        typestore.register(types)


def livox_typestore(ros1: bool) -> Typestore:
    """A Noetic (``ros1``) or Humble typestore that also knows the Livox messages."""
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    register_livox_types(typestore)
    return typestore


def _check_count(point_num: int, n: int, what: str) -> None:
    if point_num != n:
        raise DecodeError(f"{what} point_num {point_num} disagrees with its {n} points")


def decode_livox_cdr(raw: bytes | bytearray | memoryview | NDArray[np.uint8]) -> LivoxCloud:
    """Decode a ROS 2 (CDR) livox_ros_driver2/CustomMsg; points are a strided view."""
    what = "Livox CDR CustomMsg"
    buf = as_byte_view(raw)
    if len(buf) < 4 or buf[0] != 0 or buf[1] not in (0, 1):
        head = bytes(buf[:4]).hex(" ")
        raise DecodeError(f"{what} has an unsupported encapsulation header ({head})")
    little = buf[1] == 1
    r = ByteCursor(buf, 4, "little" if little else "big", 4, what)
    sec = r.uint(4, "header.stamp.sec", signed=True)
    nanosec = r.uint(4, "header.stamp.nanosec")
    frame_id = decode_string(r.take(r.uint(4, "frame_id length"), "frame_id"), True, what)
    r.align(8)
    timebase = r.uint(8, "timebase")
    point_num = r.uint(4, "point_num")
    lidar_id = r.uint(1, "lidar_id")
    r.take(3, "rsvd")
    n = r.uint(4, "points length")
    # the records take 20 n − 1 bytes: stride 20, the last without its pad byte
    size = _CDR_STRIDE * n - 1 if n else 0
    r.take(size, "points")
    if len(buf) - r.pos > _CDR_MAX_TRAILING:
        raise DecodeError(f"{what} has {len(buf) - r.pos} bytes after its {n} points")
    _check_count(point_num, n, what)
    start = r.pos - size
    dtype = LIVOX_POINT if little else LIVOX_POINT.newbyteorder(">")
    points: NDArray[np.void] = np.ndarray(
        (n,), dtype=dtype, buffer=buf, offset=start, strides=(_CDR_STRIDE,)
    )
    if not little:
        points = points.astype(LIVOX_POINT)  # native layout for the rest of the code
    return LivoxCloud(sec * _NS_PER_S + nanosec, frame_id, timebase, points, lidar_id)


def decode_livox_ros1(raw: bytes | bytearray | memoryview | NDArray[np.uint8]) -> LivoxCloud:
    """Decode a ROS 1 livox_ros_driver/CustomMsg; points are a view of the 19-B records."""
    what = "Livox ROS 1 CustomMsg"
    buf = as_byte_view(raw)
    r = ByteCursor(buf, 0, "little", 0, what)
    r.take(4, "header.seq")
    secs = r.uint(4, "header.stamp.secs")
    nsecs = r.uint(4, "header.stamp.nsecs")
    frame_id = decode_string(r.take(r.uint(4, "frame_id length"), "frame_id"), False, what)
    timebase = r.uint(8, "timebase")
    point_num = r.uint(4, "point_num")
    lidar_id = r.uint(1, "lidar_id")
    r.take(3, "rsvd")
    n = r.uint(4, "points length")
    r.take(LIVOX_POINT.itemsize * n, "points")
    if r.pos != len(buf):
        raise DecodeError(f"{what} has {len(buf) - r.pos} bytes after its {n} points")
    _check_count(point_num, n, what)
    start = r.pos - LIVOX_POINT.itemsize * n
    points: NDArray[np.void] = np.frombuffer(buf, dtype=LIVOX_POINT, count=n, offset=start)
    return LivoxCloud(secs * _NS_PER_S + nsecs, frame_id, timebase, points, lidar_id)


def _records(points: NDArray[np.void], dtype: np.dtype[np.void]) -> NDArray[np.void]:
    """``points`` copied field by field into zeroed records of ``dtype``."""
    names = points.dtype.names or ()
    missing = [n for n in LIVOX_POINT.names or () if n not in names]
    if points.ndim != 1 or missing:
        raise InputError(f"Livox points must be a 1-D structured array; missing {missing}")
    out = np.zeros(points.shape[0], dtype=dtype)  # zeros: pad bytes are deterministic
    for name in LIVOX_POINT.names or ():
        out[name] = points[name]
    return out


def _check_cloud(cloud: LivoxCloud, ros1: bool) -> None:
    """InputError when a header value does not fit its wire type."""
    sec = cloud.stamp_ns // _NS_PER_S
    lo, hi = (0, _U32_MAX) if ros1 else (-(2**31), 2**31 - 1)
    if not lo <= sec <= hi:
        raise InputError(f"stamp {cloud.stamp_ns} ns is out of range for the message header")
    if not 0 <= cloud.timebase_ns <= _U64_MAX:
        raise InputError(f"timebase {cloud.timebase_ns} ns does not fit uint64")
    if not 0 <= cloud.lidar_id <= 255:
        raise InputError(f"lidar_id {cloud.lidar_id} does not fit uint8")
    if "\0" in cloud.frame_id:
        raise InputError(f"frame_id {cloud.frame_id!r} contains a NUL character")


def encode_livox_cdr(cloud: LivoxCloud) -> bytes:
    """Little-endian CDR bytes of a livox_ros_driver2/CustomMsg (with encapsulation header)."""
    _check_cloud(cloud, ros1=False)
    records = _records(cloud.points, _CDR_POINT)
    n = records.shape[0]
    name = cloud.frame_id.encode("utf-8") + b"\0"
    sec, nanosec = divmod(cloud.stamp_ns, _NS_PER_S)
    head = b"\x00\x01\x00\x00"  # CDR, little-endian, no options
    body = struct.pack("<iII", sec, nanosec, len(name)) + name
    body += b"\0" * (-len(body) % 8)  # timebase is 8-aligned (origin: after the header)
    body += struct.pack("<QIB3xI", cloud.timebase_ns, n, cloud.lidar_id, n)
    data = records.tobytes()[:-1] if n else b""  # the last record has no pad byte
    return head + body + data


def encode_livox_ros1(cloud: LivoxCloud, seq: int = 0) -> bytes:
    """ROS 1 bytes of a livox_ros_driver/CustomMsg with header sequence number ``seq``."""
    _check_cloud(cloud, ros1=True)
    if not 0 <= seq <= _U32_MAX:
        raise InputError(f"seq {seq} does not fit uint32")
    records = _records(cloud.points, LIVOX_POINT)
    n = records.shape[0]
    name = cloud.frame_id.encode("utf-8")
    secs, nsecs = divmod(cloud.stamp_ns, _NS_PER_S)
    head = struct.pack("<IIII", seq, secs, nsecs, len(name)) + name
    head += struct.pack("<QIB3xI", cloud.timebase_ns, n, cloud.lidar_id, n)
    return head + records.tobytes()


def livox_points(
    cloud: LivoxCloud,
) -> tuple[FloatArray, FloatArray, NDArray[np.float32], NDArray[np.uint8]]:
    """``xyz`` (N, 3) [m], ``t_rel`` (N,) [s] after the header stamp, reflectivity, line."""
    pts = cloud.points
    xyz = np.empty((pts.shape[0], 3), dtype=np.float64)
    # Corrupt bytes may hold signalling NaNs: they stay NaN, and the pipeline counts them.
    with np.errstate(invalid="ignore"):
        for k, axis in enumerate(("x", "y", "z")):
            xyz[:, k] = pts[axis]
    # t_rel = (timebase + offset_time − stamp) · 1e-9; the integer part is exact in Python
    t_rel = pts["offset_time"].astype(np.float64) * 1e-9 + (
        (cloud.timebase_ns - cloud.stamp_ns) * 1e-9
    )
    return xyz, t_rel, pts["reflectivity"].astype(np.float32), pts["line"].astype(np.uint8)
