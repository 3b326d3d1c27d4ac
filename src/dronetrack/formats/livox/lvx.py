"""Livox Viewer recordings, ``.lvx`` and ``.lvx2``: headers, frames and packages as numpy
codecs (bytes ↔ arrays; reading files and cutting frames is ``sources.recordings.lvx``).

LVX 1.1.0.0 is what Livox Viewer 1 records from the Livox SDK 1 LiDARs (Mid-40/70,
Horizon, Tele, Avia); LVX2 2.0.0.0 what Livox Viewer 2 records from the SDK 2 ones
(Mid-360, HAP).  Sources: "LVX2 Specifications" (Livox, 2023, v1.0) for LVX2; for LVX
the "LVX Specifications" as Livox's own reader and writer lay it out (livox_ros_driver
``lvx_file.h``, Livox-SDK ``sample/lidar_lvx_file``).  Why our own decoder: on PyPI
``livox-lvx`` (0.2.1, 2021, alpha) reads LVX only, one Python object per point, with
x, y, z as unsigned integers; ``openpylivoxv2`` is a UDP driver without LVX; nothing
reads LVX2.  Little-endian, packed::

    public header  0 signature char[16] "livox_tech" + NULs | 16 version u8[4] (1.1.0.0 or
                   2.0.0.0) | 20 magic code u32 0xAC0EA767                              24 B
    private header 24 frame duration u32 [ms] (50) | 28 device count u8                  5 B
    device info    LVX:  0 LiDAR broadcast code char[16] | 16 hub code char[16] | 32 device
                   index u8 | 33 device type u8 | 34 extrinsic enable u8 | 35 roll, pitch,
                   yaw f32 [°] | 47 x, y, z f32 [m]                                     59 B
                   LVX2: 0 LiDAR SN char[16] | 16 hub SN char[16] | 32 LiDAR ID u32 | 36 LiDAR
                   type u8 (reserved) | 37 device type u8 | 38 extrinsic enable u8 | 39 roll,
                   pitch, yaw f32 [°] | 51 x, y, z f32 [m]                              63 B
    frame          0 current offset u64 | 8 next offset u64 (absolute, in the file) | 16
                   frame index u64 | 24 packages up to the next offset
    package        LVX:  device index u8, then one Livox SDK 1 point or IMU packet
                   (``formats.livox.sdk1``), whose length its data type sets
                   LVX2: 0 version u8 (0) | 1 LiDAR ID u32 | 5 LiDAR type u8 | 6 timestamp
                   type u8 | 7 timestamp u64 [ns] | 15 UDP counter u16 | 17 data type u8 |
                   18 length u32 (of the points) | 22 frame counter u8 | 23 reserved 4 B |
                   27 points: type 1 x, y, z i32 [mm], type 2 i16 [cm], each + reflectivity,
                   tag (``formats.livox.sdk2`` layouts)

Extrinsics, when enabled, carry the device's points into the recording's frame:
``p = R p_device + t`` with R = Rz(yaw) Ry(pitch) Rx(roll) (livox_ros_driver
``EulerAnglesToRotationMatrix``).  Point times: an LVX packet's as SDK 1 gives them
(firing j at timestamp + j Δt of the device type); an LVX2 package carries its first
point's time only, and point i is at timestamp + i Δt with Δt = 1 / point rate: Mid-360
5 µs (200,000 points/s), HAP 2.212 µs (452,000 points/s).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError, InputError
from dronetrack.formats.livox import sdk1 as s1
from dronetrack.formats.livox import sdk2 as s2
from dronetrack.formats.livox.common import Bytes, LivoxPoints, read_records, write_records
from dronetrack.geometry.transforms import FloatArray, make_pose, rot_x, rot_y, rot_z

__all__ = [
    "DEVICE_INFO",
    "FRAME_HEADER",
    "LVX2_INTERVAL_NS",
    "LVX2_PACKAGE",
    "MAGIC",
    "SIGNATURE",
    "LvxDevice",
    "LvxHeader",
    "Packages",
    "decode_lvx1",
    "decode_lvx2",
    "encode_frame",
    "encode_header",
    "encode_lvx2_packages",
    "extrinsic_of",
    "extrinsic_pose",
    "lvx2_heads",
    "lvx2_valid",
    "parse_frame_header",
    "parse_header",
    "split_packages",
]

SIGNATURE = b"livox_tech"
MAGIC = 0xAC0EA767
VERSIONS = {1: (1, 1, 0, 0), 2: (2, 0, 0, 0)}  # what each major version is written as
FRAME_DURATION_MS = 50
PUBLIC_HEADER = np.dtype([("signature", "S16"), ("version", "u1", (4,)), ("magic", "<u4")])
PRIVATE_HEADER = np.dtype([("frame_duration", "<u4"), ("device_count", "u1")])
_EXTRINSIC = [(k, "<f4") for k in ("roll", "pitch", "yaw", "x", "y", "z")]
_IDS = [("code", "S16"), ("hub_code", "S16")]
_V1 = [("ident", "u1"), ("device_type", "u1")]  # LVX: device index
_V2 = [("ident", "<u4"), ("lidar_type", "u1"), ("device_type", "u1")]  # LVX2: LiDAR ID
DEVICE_INFO = {
    1: np.dtype([*_IDS, *_V1, ("extrinsic_enable", "u1"), *_EXTRINSIC]),
    2: np.dtype([*_IDS, *_V2, ("extrinsic_enable", "u1"), *_EXTRINSIC]),
}
FRAME_HEADER = np.dtype([("current_offset", "<u8"), ("next_offset", "<u8"), ("frame_index", "<u8")])
LVX2_PACKAGE = np.dtype(
    [
        ("version", "u1"),
        ("lidar_id", "<u4"),
        ("lidar_type", "u1"),
        ("timestamp_type", "u1"),
        ("timestamp", "<u8"),
        ("udp_counter", "<u2"),
        ("data_type", "u1"),
        ("length", "<u4"),
        ("frame_counter", "u1"),
        ("reserved", "V4"),
    ]
)
HEAD_BYTES = PUBLIC_HEADER.itemsize + PRIVATE_HEADER.itemsize  # 29
LVX1_PACKAGE_HEAD = 1 + s1.HEADER_BYTES  # device index + SDK 1 packet header: 19
# Device types (Livox-SDK livox_def.h; the LVX2 document) → name
DEVICE_NAMES = {**s1.DEVICE_TYPES, 9: "Mid-360", 10: "HAP"}
# ns between an LVX2 package's points by device type (1 / the point rate)
LVX2_INTERVAL_NS = {9: 5_000, 10: 2_212}
LVX2_TIME_TYPES = (0, 1, 2)  # none, gPTP/PTP, GPS: all u64 ns


@dataclass(frozen=True)
class LvxDevice:
    """One device info block.  ``ident`` is the LVX device index or the LVX2 LiDAR ID,
    the key its packages carry; ``extrinsic``: roll, pitch, yaw [°], x, y, z [m]."""

    code: str
    hub_code: str
    ident: int
    device_type: int
    extrinsic_enabled: bool
    extrinsic: tuple[float, float, float, float, float, float] = (0.0,) * 6
    lidar_type: int = 0  # LVX2 only (reserved)

    @property
    def model(self) -> str:
        return DEVICE_NAMES.get(self.device_type, f"device type {self.device_type}")

    @property
    def pose(self) -> FloatArray:
        """(4, 4) pose of the device in the recording's frame (the identity if the
        extrinsics are disabled)."""
        return extrinsic_pose(self.extrinsic) if self.extrinsic_enabled else np.eye(4)


@dataclass(frozen=True)
class LvxHeader:
    """What precedes the frames: the major version (1: LVX, 2: LVX2), the whole version,
    the frame duration [ms], the devices, and the offset of the first frame."""

    major: int
    version: tuple[int, int, int, int]
    frame_duration_ms: int
    devices: tuple[LvxDevice, ...]
    data_offset: int


def _text(raw: bytes) -> str:
    return raw.split(b"\0", 1)[0].decode("ascii", "replace")


def header_bytes(major: int, device_count: int) -> int:
    """Bytes from the start of the file to the first frame."""
    return HEAD_BYTES + device_count * DEVICE_INFO[major].itemsize


def parse_header(buf: Bytes) -> LvxHeader:
    """The public and private headers and the device info blocks at the start of ``buf``;
    DecodeError naming what is wrong (a short ``buf`` is a truncated file)."""
    b = bytes(buf[: HEAD_BYTES + 255 * DEVICE_INFO[2].itemsize])
    if len(b) < PUBLIC_HEADER.itemsize:
        raise DecodeError(f"truncated in its public header ({len(b)} of 24 bytes)")
    pub = np.frombuffer(b, PUBLIC_HEADER, count=1)[0]
    signature = b[:16]
    if signature != SIGNATURE.ljust(16, b"\0"):
        raise DecodeError(f"file signature {signature!r} is not 'livox_tech' padded with NULs")
    if int(pub["magic"]) != MAGIC:
        raise DecodeError(f"magic code 0x{int(pub['magic']):08X} is not 0x{MAGIC:08X}")
    version = tuple(int(v) for v in pub["version"])
    major = version[0]
    if major not in VERSIONS or (major == 1 and version[1] != 1):
        raise DecodeError(
            f"version {'.'.join(map(str, version))} is neither LVX 1.1 (Livox Viewer 1) nor "
            "LVX2 2.x (Livox Viewer 2)"
        )
    if len(b) < HEAD_BYTES:
        raise DecodeError(f"truncated in its private header ({len(b)} of {HEAD_BYTES} bytes)")
    priv = np.frombuffer(b, PRIVATE_HEADER, count=1, offset=PUBLIC_HEADER.itemsize)[0]
    count = int(priv["device_count"])
    end = header_bytes(major, count)
    if count == 0:
        raise DecodeError("its device count is 0")
    if len(b) < end:
        raise DecodeError(f"truncated in its device info blocks ({len(b)} of {end} bytes)")
    info = np.frombuffer(b, DEVICE_INFO[major], count=count, offset=HEAD_BYTES)
    devices = []
    for d in info:
        ext = tuple(float(d[k]) for k in ("roll", "pitch", "yaw", "x", "y", "z"))
        devices.append(
            LvxDevice(
                code=_text(bytes(d["code"])),
                hub_code=_text(bytes(d["hub_code"])),
                ident=int(d["ident"]),
                device_type=int(d["device_type"]),
                extrinsic_enabled=int(d["extrinsic_enable"]) == 1,
                extrinsic=(ext[0], ext[1], ext[2], ext[3], ext[4], ext[5]),
                lidar_type=int(d["lidar_type"]) if major == 2 else 0,
            )
        )
    if len({d.ident for d in devices}) != count:
        raise DecodeError(f"two of its {count} devices have the same index or ID")
    frame_ms = int(priv["frame_duration"])
    v = (version[0], version[1], version[2], version[3])
    return LvxHeader(major, v, frame_ms, tuple(devices), end)


def encode_header(
    major: int, devices: Sequence[LvxDevice], frame_duration_ms: int = FRAME_DURATION_MS
) -> bytes:
    """The bytes before the first frame of an LVX (``major`` 1) or LVX2 (2) file."""
    if major not in VERSIONS or not 0 < len(devices) < 256:
        raise InputError(f"an LVX file is version 1 or 2 with 1-255 devices, not {major}")
    pub = np.zeros(1, PUBLIC_HEADER)
    pub["signature"], pub["version"], pub["magic"] = SIGNATURE, VERSIONS[major], MAGIC
    priv = np.zeros(1, PRIVATE_HEADER)
    priv["frame_duration"], priv["device_count"] = frame_duration_ms, len(devices)
    info = np.zeros(len(devices), DEVICE_INFO[major])
    for row, d in zip(info, devices, strict=True):
        row["code"], row["hub_code"] = d.code.encode("ascii"), d.hub_code.encode("ascii")
        row["ident"], row["device_type"] = d.ident, d.device_type
        row["extrinsic_enable"] = int(d.extrinsic_enabled)
        for k, v in zip(("roll", "pitch", "yaw", "x", "y", "z"), d.extrinsic, strict=True):
            row[k] = v
        if major == 2:
            row["lidar_type"] = d.lidar_type
    return pub.tobytes() + priv.tobytes() + info.tobytes()


def parse_frame_header(buf: Bytes) -> tuple[int, int, int]:
    """(current offset, next offset, frame index) of a frame header's 24 bytes."""
    if len(buf) < FRAME_HEADER.itemsize:
        raise DecodeError(f"frame header of {len(buf)} bytes is shorter than 24")
    cur, nxt, idx = struct.unpack_from("<QQQ", buf)
    return cur, nxt, idx


def encode_frame(offset: int, index: int, packages: Bytes) -> bytes:
    """A frame at file ``offset``: its header, then the ``packages``."""
    nxt = offset + FRAME_HEADER.itemsize + len(packages)
    return struct.pack("<QQQ", offset, nxt, index) + bytes(packages)


@dataclass(frozen=True)
class Packages:
    """The packages of one frame's body: where each starts and how long it is, whose it
    is (device index or LiDAR ID) and its data type."""

    start: NDArray[np.int64]
    size: NDArray[np.int64]
    ident: NDArray[np.int64]
    data_type: NDArray[np.int64]

    def __len__(self) -> int:
        return int(self.start.shape[0])

    def take(self, sel: NDArray[np.bool_] | NDArray[np.intp]) -> Packages:
        return Packages(self.start[sel], self.size[sel], self.ident[sel], self.data_type[sel])


def split_packages(body: Bytes, major: int) -> Packages:
    """The packages of a frame's ``body`` (the bytes after its header), walked one by one:
    an LVX package's length follows from its data type, an LVX2 package's from its length
    field.  DecodeError if a package runs past the end or has an unknown LVX data type."""
    b = bytes(body)
    start: list[int] = []
    size: list[int] = []
    ident: list[int] = []
    kind: list[int] = []
    pos, end = 0, len(b)
    head = LVX1_PACKAGE_HEAD if major == 1 else LVX2_PACKAGE.itemsize
    while pos < end:
        if pos + head > end:
            raise DecodeError(f"package at byte {pos} is cut off in its {head}-byte header")
        if major == 1:
            data_type = b[pos + 10]
            if data_type not in s1.PACKET_BYTES:
                raise DecodeError(f"package at byte {pos} has unknown data type {data_type}")
            n, who = 1 + s1.PACKET_BYTES[data_type], b[pos]
        else:
            who, data_type, length = (
                int.from_bytes(b[pos + 1 : pos + 5], "little"),
                b[pos + 17],
                int.from_bytes(b[pos + 18 : pos + 22], "little"),
            )
            n = head + length
        if pos + n > end:
            raise DecodeError(f"package at byte {pos} of {n} bytes runs past the frame's end")
        start.append(pos)
        size.append(n)
        ident.append(who)
        kind.append(data_type)
        pos += n
    return Packages(*(np.array(v, np.int64) for v in (start, size, ident, kind)))


def decode_lvx1(
    body: Bytes, packages: Packages, point_interval_ns: int | None, lines: int = 1
) -> tuple[LivoxPoints, NDArray[np.uint8], int]:
    """Points of LVX packages (their SDK 1 packets), every firing with or without a
    return; the laser line of each (its firing's index in the packet modulo ``lines``)
    and the number of malformed packets skipped (version, length, timestamp).  Firings
    are ``point_interval_ns`` apart; None (an unknown device type): as the data type
    says, 10 µs for types 0 and 1 (Mid-40/70), else 4.167 µs (``sources.livox.sdk1``)."""
    view = memoryview(bytes(body))
    parts: list[LivoxPoints] = []
    line_parts: list[NDArray[np.uint8]] = []
    bad = 0
    for data_type in np.unique(packages.data_type).tolist():
        sel = packages.take(packages.data_type == data_type)
        packets = [
            view[a + 1 : a + n] for a, n in zip(sel.start.tolist(), sel.size.tolist(), strict=True)
        ]
        interval = point_interval_ns or s1.POINT_INTERVAL_NS[1 if data_type in (0, 1) else 7]
        decoded, skipped = s1.decode_packets(packets, interval)
        bad += skipped
        pts = decoded.points
        if len(pts) == 0 or data_type not in s1.LAYOUTS:
            continue
        layout, n = s1.LAYOUTS[data_type], s1.POINTS_PER_PACKET[data_type]
        firing = np.arange(len(pts)) // layout.returns % n
        parts.append(pts)
        line_parts.append((firing % lines).astype(np.uint8))
    line = np.concatenate(line_parts) if line_parts else np.zeros(0, np.uint8)
    return LivoxPoints.concat(parts), line, bad


def lvx2_heads(body: Bytes, packages: Packages) -> NDArray[np.void]:
    """The LVX2 package headers (``LVX2_PACKAGE``) of ``packages`` in ``body``."""
    raw = np.frombuffer(bytes(body), np.uint8)
    rows = raw[packages.start[:, None] + np.arange(LVX2_PACKAGE.itemsize)]
    heads: NDArray[np.void] = np.ascontiguousarray(rows).view(LVX2_PACKAGE)[:, 0]
    return heads


def lvx2_valid(heads: NDArray[np.void], size: NDArray[np.int64]) -> NDArray[np.bool_]:
    """Which LVX2 packages (headers ``heads``, whole sizes ``size``) are well formed:
    version 0, data type 1 or 2 with a length of whole points that the package holds,
    a known timestamp type and a timestamp below 2⁶² ns."""
    data_type = heads["data_type"].astype(np.int64)
    length = heads["length"].astype(np.int64)
    point = np.where(data_type == 1, 14, 8)  # bytes a point of type 1 or 2
    ok: NDArray[np.bool_] = (
        (heads["version"] == 0)
        & np.isin(data_type, (1, 2))
        & (length > 0)
        & (length % point == 0)
        & np.isin(heads["timestamp_type"], LVX2_TIME_TYPES)
        & (heads["timestamp"] < np.uint64(1 << 62))
        & (size == LVX2_PACKAGE.itemsize + length)
    )
    return ok


def decode_lvx2(
    body: Bytes, packages: Packages, point_interval_ns: int, lines: int = 1
) -> tuple[LivoxPoints, NDArray[np.uint8], int]:
    """Points of LVX2 packages, point i of a package at its timestamp + i Δt; the laser
    line of each (its index in the package modulo ``lines``) and the number of
    malformed packages skipped (version, data type, length, timestamp)."""
    b = bytes(body)
    heads = lvx2_heads(b, packages)
    ok = lvx2_valid(heads, packages.size)
    parts: list[LivoxPoints] = []
    line_parts: list[NDArray[np.uint8]] = []
    for data_type in (1, 2):
        idx = np.flatnonzero(ok & (packages.data_type == data_type))
        if len(idx) == 0:
            continue
        layout = s2.LAYOUTS[data_type]
        counts = (packages.size[idx] - LVX2_PACKAGE.itemsize) // layout.dtype.itemsize
        payload = b"".join(
            b[a + LVX2_PACKAGE.itemsize : a + n]
            for a, n in zip(packages.start[idx].tolist(), packages.size[idx].tolist(), strict=True)
        )
        rec = np.frombuffer(payload, layout.dtype)
        # i: each point's index in its package; t = timestamp + i Δt
        first = np.repeat(np.cumsum(counts) - counts, counts)
        i = np.arange(len(rec), dtype=np.int64) - first
        t = np.repeat(heads["timestamp"][idx].astype(np.int64), counts) + i * point_interval_ns
        parts.append(read_records(rec, layout, t))
        line_parts.append((i % lines).astype(np.uint8))
    line = np.concatenate(line_parts) if line_parts else np.zeros(0, np.uint8)
    return LivoxPoints.concat(parts), line, int(np.count_nonzero(~ok))


def encode_lvx2_packages(
    points: FloatArray,
    reflectivity: NDArray[np.uint8],
    *,
    lidar_id: int,
    t0_ns: int,
    point_interval_ns: int,
    data_type: int = 1,
    points_per_package: int = s2.POINTS_PER_PACKET,
    timestamp_type: int = 0,
    lidar_type: int = 8,
    udp_counter: int = 0,
) -> list[bytes]:
    """LVX2 packages of ``points`` (N, 3) [m], point i at t0 + i Δt, the last package
    holding the remainder; (0, 0, 0) is a point without a return."""
    if data_type not in (1, 2):
        raise InputError(f"LVX2 data type {data_type} is not 1 or 2")
    rec = write_records(points, reflectivity, None, s2.LAYOUTS[data_type])
    out = []
    for k, a in enumerate(range(0, len(rec), points_per_package)):
        chunk = rec[a : a + points_per_package]
        head = np.zeros(1, LVX2_PACKAGE)
        head["lidar_id"], head["lidar_type"] = lidar_id, lidar_type
        head["timestamp_type"], head["timestamp"] = timestamp_type, t0_ns + a * point_interval_ns
        head["udp_counter"], head["data_type"] = (udp_counter + k) & 0xFFFF, data_type
        head["length"] = chunk.nbytes
        out.append(head.tobytes() + chunk.tobytes())
    return out


def extrinsic_pose(extrinsic: Sequence[float]) -> FloatArray:
    """(4, 4) pose of roll, pitch, yaw [°] and x, y, z [m]: R = Rz(yaw) Ry(pitch) Rx(roll)."""
    roll, pitch, yaw, x, y, z = (float(v) for v in extrinsic)
    R = rot_z(math.radians(yaw)) @ rot_y(math.radians(pitch)) @ rot_x(math.radians(roll))
    pose: FloatArray = make_pose(R, (x, y, z))
    return pose


def extrinsic_of(pose: FloatArray) -> tuple[float, float, float, float, float, float]:
    """Roll, pitch, yaw [°] and x, y, z [m] of a (4, 4) pose, the inverse of
    ``extrinsic_pose`` with pitch in [−90°, 90°]:
    pitch = −asin R₂₀, roll = atan2(R₂₁, R₂₂), yaw = atan2(R₁₀, R₀₀); at pitch ±90°
    only roll ∓ yaw counts: roll = 0, yaw = atan2(−R₀₁, R₁₁)."""
    R = np.asarray(pose, np.float64)[:3, :3]
    pitch = -math.asin(max(-1.0, min(1.0, float(R[2, 0]))))
    if math.hypot(float(R[2, 1]), float(R[2, 2])) < 1e-12:  # cos(pitch) = 0
        roll, yaw = 0.0, math.atan2(-float(R[0, 1]), float(R[1, 1]))
    else:
        roll = math.atan2(float(R[2, 1]), float(R[2, 2]))
        yaw = math.atan2(float(R[1, 0]), float(R[0, 0]))
    x, y, z = (float(v) for v in np.asarray(pose, np.float64)[:3, 3])
    return math.degrees(roll), math.degrees(pitch), math.degrees(yaw), x, y, z
