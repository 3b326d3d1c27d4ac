"""Livox SDK 2 wire protocol (Mid-360), the data side: point and IMU packets, as numpy
codecs.  Command frames, discovery and parameters are in
``formats/livox/sdk2_control.py``.

Source: Livox "Communication Protocol -- Mid360" (livox_wiki_en
``livox_eth_protocol_mid360.md``) and Livox-SDK2 ``include/livox_lidar_def.h``.
Little-endian.

Point packet, a 36-byte header then ``dot_num`` records::

    0 version 0 | 1 length u16 (whole datagram) | 3 time_interval u16 (0.1 µs, last − first
    point) | 5 dot_num u16 | 7 udp_cnt u16 | 9 frame_cnt | 10 data_type | 11 time_type
    | 12 reserved 12 B | 24 crc32 of bytes 28… | 28 timestamp u64 ns (first point) | 36 data

Data types: 0 IMU, 1 Cartesian x, y, z i32 mm, 2 Cartesian i16 cm, 3 spherical; each
with reflectivity and tag.  The points of a packet are equally spaced in time:
``t_i = timestamp + i · time_interval / (dot_num − 1)``.  (livox_ros_driver2 divides
by ``dot_num`` instead; the document's definition is used here.)  Livox-SDK2 never
checks the point packet's CRC-32, so the decoder checks it only when asked.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.formats.livox.common import (
    IMU_RECORD,
    Bytes,
    DecodedPackets,
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
    "HEADER_BYTES",
    "IMU_DATA_TYPE",
    "LAYOUTS",
    "POINTS_PER_PACKET",
    "RECORD_BYTES",
    "decode_packet",
    "decode_packets",
    "encode_imu_packets",
    "encode_point_packets",
    "packet_problem",
]

HEADER_BYTES = 36
HEADER = np.dtype(
    [
        ("version", "u1"),
        ("length", "<u2"),
        ("time_interval", "<u2"),
        ("dot_num", "<u2"),
        ("udp_cnt", "<u2"),
        ("frame_cnt", "u1"),
        ("data_type", "u1"),
        ("time_type", "u1"),
        ("reserved", "V12"),
        ("crc32", "<u4"),
        ("timestamp", "<u8"),
    ]
)
IMU_DATA_TYPE = 0
LAYOUTS: dict[int, RecordLayout] = {
    1: cartesian_layout(1, tagged=True),
    2: cartesian_layout(1, tagged=True, coord="<i2", unit_m=1e-2),
    3: spherical_layout(1, tagged=True),
}
RECORD_BYTES = {t: lay.dtype.itemsize for t, lay in LAYOUTS.items()} | {0: IMU_RECORD.itemsize}
POINTS_PER_PACKET = 96
TIME_TYPES = (0, 1, 2)  # none, PTP/gPTP, GPS: all u64 ns


def packet_problem(buf: Bytes, check_crc: bool = False) -> str | None:
    """What makes a point/IMU packet malformed, or None if it decodes."""
    found = _inspector(check_crc)(bytes(buf))
    return found if isinstance(found, str) else None


def _inspector(check_crc: bool) -> Callable[[bytes], tuple[int, object] | str]:
    def inspect(b: bytes) -> tuple[int, object] | str:
        if len(b) < HEADER_BYTES:
            return f"{len(b)} bytes, shorter than the 36-byte header"
        version, length, _, dot_num = struct.unpack_from("<BHHH", b)
        data_type, time_type = b[10], b[11]
        if version != 0:
            return f"packet version {version}, expected 0"
        if length != len(b):
            return f"length field {length} != {len(b)} bytes"
        if data_type not in RECORD_BYTES:
            return f"unknown data type {data_type}"
        if dot_num == 0 or len(b) != HEADER_BYTES + dot_num * RECORD_BYTES[data_type]:
            return f"{len(b)} bytes do not hold {dot_num} records of data type {data_type}"
        if time_type not in TIME_TYPES:
            return f"unknown time type {time_type}"
        (stamp,) = struct.unpack_from("<Q", b, 28)
        if stamp >= 1 << 62:
            return f"timestamp {stamp} ns is out of range"
        if check_crc and zlib.crc32(b[28:]) != struct.unpack_from("<I", b, 24)[0]:
            return "CRC-32 mismatch"
        return (data_type << 16) | dot_num, None

    return inspect


def _decode_group(
    key: int, rows: NDArray[np.uint8], _: list[object]
) -> tuple[LivoxPoints | None, ImuSamples | None]:
    data_type, n = key >> 16, key & 0xFFFF
    hdr = np.ascontiguousarray(rows[:, :HEADER_BYTES]).view(HEADER)[:, 0]
    body = np.ascontiguousarray(rows[:, HEADER_BYTES:])
    # t_i = t0 + i · (time_interval · 100 ns) / (n − 1), in integer ns
    i = np.arange(n, dtype=np.int64)[None, :]
    span = hdr["time_interval"].astype(np.int64)[:, None] * 100
    t = hdr["timestamp"].astype(np.int64)[:, None] + (i * span) // max(n - 1, 1)
    if data_type == IMU_DATA_TYPE:
        return None, read_imu(body.view(IMU_RECORD), t)
    return read_records(body.view(LAYOUTS[data_type].dtype), LAYOUTS[data_type], t), None


def decode_packets(packets: Sequence[Bytes], check_crc: bool = False) -> tuple[DecodedPackets, int]:
    """Points and IMU samples of many packets (vectorised per data type and size), and the
    number of malformed packets skipped (length, version, type, time type, CRC if asked)."""
    return decode_batch(packets, _inspector(check_crc), _decode_group)


def decode_packet(buf: Bytes, check_crc: bool = False) -> DecodedPackets:
    """One packet; DecodeError naming the problem if it is malformed."""
    return decode_one(buf, _inspector(check_crc), _decode_group, "Livox SDK 2 packet")


def _packets(
    data_type: int,
    rec: NDArray[np.void],
    t0_ns: int,
    interval_ns: int,
    per_packet: int,
    time_type: int,
    udp_cnt: int,
    frame_cnt: int,
) -> list[bytes]:
    if time_type not in TIME_TYPES:
        raise InputError(f"time type {time_type} is not one of {TIME_TYPES}")
    out: list[bytes] = []
    for k, start in enumerate(range(0, rec.shape[0], per_packet)):
        chunk = rec[start : start + per_packet]
        n = chunk.shape[0]
        span = round(interval_ns * (n - 1) / 100)  # 0.1 µs
        if span > 0xFFFF:
            raise InputError(f"{n} points {interval_ns} ns apart span more than 6.5535 ms")
        hdr = np.zeros(1, HEADER)
        hdr["length"] = HEADER_BYTES + n * chunk.dtype.itemsize
        hdr["time_interval"], hdr["dot_num"] = span, n
        hdr["udp_cnt"], hdr["frame_cnt"] = (udp_cnt + k) & 0xFFFF, frame_cnt & 0xFF
        hdr["data_type"], hdr["time_type"] = data_type, time_type
        hdr["timestamp"] = t0_ns + start * interval_ns
        packet = bytearray(packets_from_rows(hdr, chunk[None, :])[0])
        packet[24:28] = struct.pack("<I", zlib.crc32(packet[28:]))
        out.append(bytes(packet))
    return out


def encode_point_packets(
    points: FloatArray,
    reflectivity: NDArray[np.uint8],
    tag: NDArray[np.uint8] | None = None,
    *,
    t0_ns: int,
    point_interval_ns: int,
    data_type: int = 1,
    time_type: int = 0,
    points_per_packet: int = POINTS_PER_PACKET,
    udp_cnt: int = 0,
    frame_cnt: int = 0,
) -> list[bytes]:
    """Point packets of data type 1, 2 or 3 from points (N, 3) in metres, point i at
    t0 + i·Δt; the last packet holds the remainder."""
    if data_type not in LAYOUTS:
        raise InputError(f"data type {data_type} is not a point type (1, 2, 3)")
    rec = write_records(points, reflectivity, tag, LAYOUTS[data_type])
    return _packets(
        data_type, rec, t0_ns, point_interval_ns, points_per_packet, time_type, udp_cnt, frame_cnt
    )


def encode_imu_packets(
    t_ns: NDArray[np.int64], gyro: FloatArray, acc: FloatArray, *, time_type: int = 0
) -> list[bytes]:
    """One IMU packet (data type 0) per sample: gyro rad/s, acc in g, float32."""
    rec = write_imu(gyro, acc)
    ts = np.asarray(t_ns, np.int64).reshape(-1)
    if ts.shape[0] != rec.shape[0]:
        raise InputError(f"{ts.shape[0]} IMU times for {rec.shape[0]} samples")
    return [
        _packets(IMU_DATA_TYPE, rec[j : j + 1], int(ts[j]), 0, 1, time_type, j, 0)[0]
        for j in range(rec.shape[0])
    ]
