"""Livox SDK 1 wire protocol (Mid-40/70, Horizon, Tele, Avia): command frames, the
general commands of discovery and sampling, and point/IMU packets, as numpy codecs.

Command frame (Livox-SDK ``sdk_core/src/comm/sdk_protocol.h``), little-endian::

    0 sof 0xAA | 1 version 0 | 2 length u16 (whole frame) | 4 cmd_type (0 CMD, 1 ACK, 2 MSG)
    | 5 seq u16 | 7 crc16 u16 of bytes 0-6 | 9 cmd_set | 10 cmd_id | 11 payload | crc32 u32

CRC-16 is MCRF4XX (reflected 0x1021, no final xor) with register init 0x4C49, so
the CRC-16 over all 9 preamble bytes is 0; CRC-32 is the zlib CRC seeded with
0x564F580A (``comm_port.cpp``: ``SdkProtocol(0x4c49, 0x564f580a)``).

Point packet (``livox_def.h`` LivoxEthPacket): an 18-byte header ``version (5) | slot
| lidar id | reserved | status u32 | timestamp_type | data_type | timestamp 8 B`` then
points.  Timestamp types 0 (no sync), 1 (PTP), 4 (PPS): u64 ns; 3 (PPS+GPS): UTC
bytes year−2000, month, day, hour, then u32 µs within the hour.  The timestamp is
that of the first firing; firing i is at ``timestamp + i × point interval`` of the
device (10 000 ns Mid-40/70, 4 167 ns Horizon/Tele/Avia: livox_ros_driver ``lds.h``),
and the returns of one firing share its time (``lddc.cpp``).
"""

from __future__ import annotations

import ipaddress
import struct
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, date, datetime

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError, InputError
from dronetrack.formats.livox.common import (
    IMU_RECORD,
    Bytes,
    DecodedPackets,
    GroupDecoder,
    ImuSamples,
    LivoxPoints,
    RecordLayout,
    cartesian_layout,
    decode_batch,
    decode_one,
    packets_from_rows,
    read_imu,
    read_records,
    spherical_layout,
    write_imu,
    write_records,
)
from dronetrack.geometry.transforms import FloatArray

__all__ = [
    "CMD",
    "IMU_DATA_TYPE",
    "LAYOUTS",
    "PACKET_BYTES",
    "POINTS_PER_PACKET",
    "POINT_INTERVAL_NS",
    "Broadcast",
    "CommandFrame",
    "DeviceInfoAck",
    "Handshake",
    "HeartbeatAck",
    "crc16",
    "crc32",
    "decode_frame",
    "decode_packet",
    "decode_packets",
    "encode_frame",
    "encode_imu_packets",
    "encode_point_packets",
]

SOF = 0xAA
CMD, ACK, MSG = 0, 1, 2  # cmd_type
SET_GENERAL, SET_LIDAR, SET_HUB = 0, 1, 2  # cmd_set
BROADCAST, HANDSHAKE, DEVICE_INFO, HEARTBEAT, SAMPLING, COORDINATES, DISCONNECT = range(7)
BROADCAST_PORT, LIDAR_CMD_PORT = 55000, 65000
DEVICE_TYPES = {0: "Hub", 1: "Mid-40", 2: "Tele", 3: "Horizon", 6: "Mid-70", 7: "Avia"}
# ns between firings by device type (livox_ros_driver lds.h product_type_info_pair_table)
POINT_INTERVAL_NS = {1: 10_000, 2: 4_167, 3: 4_167, 6: 10_000, 7: 4_167}
PACKET_VERSION = 5  # livox_ros_driver lds_lvx.cpp accepts only version 5
HEADER_BYTES = 18
HEADER = np.dtype(
    [
        ("version", "u1"),
        ("slot", "u1"),
        ("lidar_id", "u1"),
        ("reserved", "u1"),
        ("status", "<u4"),
        ("timestamp_type", "u1"),
        ("data_type", "u1"),
        ("timestamp", "<u8"),
    ]
)
IMU_DATA_TYPE = 6
# data type → one firing's layout (livox_def.h point structs)
LAYOUTS: dict[int, RecordLayout] = {
    0: cartesian_layout(1, tagged=False),
    1: spherical_layout(1, tagged=False),
    2: cartesian_layout(1, tagged=True),
    3: spherical_layout(1, tagged=True),
    4: cartesian_layout(2, tagged=True),
    5: spherical_layout(2, tagged=True),
    7: cartesian_layout(3, tagged=True),
    8: spherical_layout(3, tagged=True),
}
# firings per packet (livox_ros_driver lds.h data_type_info_pair_table)
POINTS_PER_PACKET = {0: 100, 1: 100, 2: 96, 3: 96, 4: 48, 5: 48, 6: 1, 7: 30, 8: 30}
RECORD_BYTES = {t: lay.dtype.itemsize for t, lay in LAYOUTS.items()} | {6: IMU_RECORD.itemsize}
PACKET_BYTES = {t: HEADER_BYTES + n * RECORD_BYTES[t] for t, n in POINTS_PER_PACKET.items()}
NS_TIMESTAMPS, UTC_TIMESTAMP = (0, 1, 4), 3
US_PER_HOUR = 3_600_000_000


def _crc16_table() -> list[int]:
    table = []
    for byte in range(256):
        c = byte
        for _ in range(8):  # reflected polynomial 0x1021 → 0x8408
            c = (c >> 1) ^ 0x8408 if c & 1 else c >> 1
        table.append(c)
    return table


_CRC16 = _crc16_table()


def crc16(data: Bytes, init: int = 0x4C49) -> int:
    """CRC-16/MCRF4XX with the Livox register init 0x4C49."""
    c = init
    for b in bytes(data):
        c = (c >> 8) ^ _CRC16[(c ^ b) & 0xFF]
    return c


def crc32(data: Bytes) -> int:
    """CRC-32 (reflected 0x04C11DB7) seeded as the SDK does: zlib's with 0x564F580A."""
    return zlib.crc32(data, 0x564F580A)


@dataclass(frozen=True)
class CommandFrame:
    cmd_type: int
    seq: int
    cmd_set: int
    cmd_id: int
    payload: bytes = b""
    version: int = 0


def encode_frame(frame: CommandFrame) -> bytes:
    length = 15 + len(frame.payload)
    pre = struct.pack("<BBHBH", SOF, frame.version, length, frame.cmd_type, frame.seq & 0xFFFF)
    body = pre + struct.pack("<HBB", crc16(pre), frame.cmd_set, frame.cmd_id) + frame.payload
    return body + struct.pack("<I", crc32(body))


def decode_frame(buf: Bytes) -> CommandFrame:
    """One command frame (one UDP datagram); DecodeError naming what is wrong."""
    b = bytes(buf)
    if len(b) < 15:
        raise DecodeError(f"Livox command frame of {len(b)} bytes is shorter than 15")
    sof, version, length, cmd_type, seq = struct.unpack_from("<BBHBH", b)
    if sof != SOF:
        raise DecodeError(f"Livox command frame starts with 0x{sof:02X}, not SOF 0xAA")
    if length != len(b):
        raise DecodeError(f"Livox command frame length field {length} != {len(b)} bytes")
    if crc16(b[:9]) != 0:
        raise DecodeError("Livox command frame preamble CRC-16 mismatch")
    if crc32(b[:-4]) != struct.unpack_from("<I", b, len(b) - 4)[0]:
        raise DecodeError("Livox command frame CRC-32 mismatch")
    return CommandFrame(cmd_type, seq, b[9], b[10], b[11:-4], version)


def _payload(p: Bytes, size: int, what: str) -> bytes:
    b = bytes(p)
    if len(b) != size:
        raise DecodeError(f"Livox {what} payload has {len(b)} bytes, expected {size}")
    return b


@dataclass(frozen=True)
class Broadcast:
    """0x00, LiDAR → host port 55000: broadcast code (≤ 15 chars) and device type."""

    code: str
    dev_type: int

    def encode(self) -> bytes:
        return struct.pack("<16sBH", self.code.encode("ascii"), self.dev_type, 0)

    @staticmethod
    def decode(payload: Bytes) -> Broadcast:
        code, dev_type, _ = struct.unpack("<16sBH", _payload(payload, 19, "broadcast"))
        return Broadcast(code.split(b"\0", 1)[0].decode("ascii", "replace"), dev_type)


@dataclass(frozen=True)
class Handshake:
    """0x01, host → LiDAR: the host IP (dotted order on the wire) and its UDP ports."""

    host_ip: str
    data_port: int
    cmd_port: int
    imu_port: int

    def encode(self) -> bytes:
        try:
            ip = ipaddress.IPv4Address(self.host_ip).packed
        except ValueError as exc:
            raise InputError(f"handshake host IP {self.host_ip!r}: {exc}") from exc
        return ip + struct.pack("<HHH", self.data_port, self.cmd_port, self.imu_port)

    @staticmethod
    def decode(payload: Bytes) -> Handshake:
        b = _payload(payload, 10, "handshake")
        return Handshake(str(ipaddress.IPv4Address(b[:4])), *struct.unpack_from("<HHH", b, 4))


@dataclass(frozen=True)
class HeartbeatAck:
    """ACK of 0x03: return code, state (1 normal), feature and the status code u32."""

    ret_code: int
    state: int
    feature: int
    status: int

    def encode(self) -> bytes:
        return struct.pack("<BBBI", self.ret_code, self.state, self.feature, self.status)

    @staticmethod
    def decode(payload: Bytes) -> HeartbeatAck:
        return HeartbeatAck(*struct.unpack("<BBBI", _payload(payload, 7, "heartbeat ACK")))


@dataclass(frozen=True)
class DeviceInfoAck:
    """ACK of 0x02 (query device information; ``livox_def.h`` DeviceInformationResponse):
    return code and the firmware version, four bytes."""

    ret_code: int
    firmware: tuple[int, int, int, int]

    def encode(self) -> bytes:
        return struct.pack("<B4B", self.ret_code, *self.firmware)

    @staticmethod
    def decode(payload: Bytes) -> DeviceInfoAck:
        ret, *fw = struct.unpack("<B4B", _payload(payload, 5, "device information ACK"))
        return DeviceInfoAck(ret, (fw[0], fw[1], fw[2], fw[3]))

    @property
    def version(self) -> str:
        return ".".join(map(str, self.firmware))


def encode_sampling(start: bool) -> bytes:
    """Payload of 0x04: 1 starts sampling, 0 stops it."""
    return bytes([1 if start else 0])


def decode_sampling(payload: Bytes) -> bool:
    return _payload(payload, 1, "sampling")[0] == 1


def decode_ret_code(payload: Bytes) -> int:
    """The ret_code (0 = success) of a one-byte ACK (handshake, sampling, disconnect)."""
    return _payload(payload, 1, "ACK")[0]


def _stamp_ns(kind: int, raw: bytes) -> int | str:
    if kind in NS_TIMESTAMPS:
        ns = int.from_bytes(raw, "little")
    elif kind == UTC_TIMESTAMP:
        year, month, day, hour = raw[:4]
        us = int.from_bytes(raw[4:], "little")
        try:
            days = (date(2000 + year, month, day) - date(1970, 1, 1)).days
        except ValueError:
            return f"UTC timestamp has no date {2000 + year}-{month}-{day}"
        if hour > 23 or us >= US_PER_HOUR:
            return f"UTC timestamp hour {hour}, {us} µs is out of range"
        ns = ((days * 24 + hour) * US_PER_HOUR + us) * 1000
    else:
        return f"unknown timestamp type {kind}"
    return ns if ns < 1 << 62 else f"timestamp {ns} ns is out of range"


def _inspect(b: bytes) -> tuple[int, object] | str:
    if len(b) < HEADER_BYTES:
        return f"{len(b)} bytes, shorter than the 18-byte header"
    if b[0] != PACKET_VERSION:
        return f"packet version {b[0]}, expected {PACKET_VERSION}"
    data_type = b[9]
    if data_type not in PACKET_BYTES:
        return f"unknown data type {data_type}"
    if len(b) != PACKET_BYTES[data_type]:
        return f"{len(b)} bytes for data type {data_type}, expected {PACKET_BYTES[data_type]}"
    stamp = _stamp_ns(b[8], b[10:18])
    return stamp if isinstance(stamp, str) else (data_type, stamp)


def _group_decoder(point_interval_ns: int) -> GroupDecoder:
    def decode(
        data_type: int, rows: NDArray[np.uint8], stamps: list[object]
    ) -> tuple[LivoxPoints | None, ImuSamples | None]:
        ts = np.array(stamps, np.int64)
        body = np.ascontiguousarray(rows[:, HEADER_BYTES:])
        if data_type == IMU_DATA_TYPE:
            return None, read_imu(body.view(IMU_RECORD), ts)
        rec = body.view(LAYOUTS[data_type].dtype)  # (P, n)
        # firing j of a packet stamped ts: t = ts + j·Δt
        t = ts[:, None] + np.arange(rec.shape[1], dtype=np.int64)[None, :] * point_interval_ns
        return read_records(rec, LAYOUTS[data_type], t), None

    return decode


def decode_packets(packets: Sequence[Bytes], point_interval_ns: int) -> tuple[DecodedPackets, int]:
    """Points and IMU samples of many point/IMU packets (vectorised per data type), and
    the number of malformed packets skipped (wrong length, version, type, timestamp)."""
    return decode_batch(packets, _inspect, _group_decoder(point_interval_ns))


def decode_packet(buf: Bytes, point_interval_ns: int) -> DecodedPackets:
    """One packet; DecodeError naming the problem if it is malformed."""
    return decode_one(buf, _inspect, _group_decoder(point_interval_ns), "Livox SDK 1 packet")


def _stamp_bytes(ns: NDArray[np.int64], kind: int) -> NDArray[np.uint64]:
    if kind in NS_TIMESTAMPS:
        return ns.astype(np.uint64)
    if kind != UTC_TIMESTAMP:
        raise InputError(f"timestamp type {kind} is not one of 0, 1, 3, 4")
    out = np.zeros(ns.shape, np.uint64)
    for i, v in enumerate(ns.tolist()):
        when = datetime.fromtimestamp(v // 10**9, UTC)
        if not 2000 <= when.year < 2256:
            raise InputError(f"UTC timestamps cover years 2000-2255, not {when.year}")
        us = (v % (US_PER_HOUR * 1000)) // 1000  # Unix-time hours are UTC hours
        head = bytes([when.year - 2000, when.month, when.day, when.hour])
        out[i] = int.from_bytes(head + us.to_bytes(4, "little"), "little")
    return out


def _headers(
    K: int, data_type: int, ts: NDArray[np.int64], kind: int, lidar_id: int, status: int
) -> NDArray[np.void]:
    hdr = np.zeros(K, HEADER)
    hdr["version"], hdr["lidar_id"], hdr["status"] = PACKET_VERSION, lidar_id, status
    hdr["timestamp_type"], hdr["data_type"] = kind, data_type
    hdr["timestamp"] = _stamp_bytes(ts, kind)
    return hdr


def encode_point_packets(
    points: FloatArray,
    reflectivity: NDArray[np.uint8],
    tag: NDArray[np.uint8] | None = None,
    *,
    data_type: int,
    t0_ns: int,
    point_interval_ns: int,
    timestamp_type: int = 0,
    lidar_id: int = 1,
    status: int = 0,
) -> list[bytes]:
    """Point packets of ``data_type`` (0-5, 7, 8) from points (F·R, 3) in metres, R
    returns per firing in the decoder's order; firing j is at t0 + j·Δt.  The last
    packet is filled up with zero-range firings."""
    if data_type not in LAYOUTS:
        raise InputError(f"data type {data_type} is not a point type (0-5, 7, 8)")
    layout, n = LAYOUTS[data_type], POINTS_PER_PACKET[data_type]
    rec = write_records(points, reflectivity, tag, layout)
    K = -(-rec.shape[0] // n)
    rec = np.concatenate([rec, np.zeros(K * n - rec.shape[0], layout.dtype)])
    ts = t0_ns + np.arange(K, dtype=np.int64) * (n * point_interval_ns)
    return packets_from_rows(
        _headers(K, data_type, ts, timestamp_type, lidar_id, status), rec.reshape(K, n)
    )


def encode_imu_packets(
    t_ns: NDArray[np.int64],
    gyro: FloatArray,
    acc: FloatArray,
    *,
    timestamp_type: int = 0,
    lidar_id: int = 1,
) -> list[bytes]:
    """One IMU packet (data type 6) per sample: gyro rad/s, acc in g, float32."""
    rec = write_imu(gyro, acc)
    ts = np.asarray(t_ns, np.int64).reshape(-1)
    if ts.shape[0] != rec.shape[0]:
        raise InputError(f"{ts.shape[0]} IMU times for {rec.shape[0]} samples")
    hdr = _headers(rec.shape[0], IMU_DATA_TYPE, ts, timestamp_type, lidar_id, 0)
    return packets_from_rows(hdr, rec.reshape(-1, 1))
