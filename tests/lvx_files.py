"""Livox Viewer files built by hand with ``struct.pack`` from the specifications, never
with dronetrack's encoders: "LVX2 Specifications" (Livox, 2023, v1.0) for ``.lvx2``,
and for ``.lvx`` 1.1 the layout Livox's own reader and writer give it (livox_ros_driver
``lvx_file.h``).  Little-endian, packed:

- public header: signature char[16] "livox_tech" + 6 NULs, version u8[4], magic u32
  0xAC0EA767 (24 B); private header: frame duration u32 ms, device count u8 (5 B);
- LVX device info (59 B): LiDAR code char[16], hub code char[16], device index u8,
  device type u8, extrinsic enable u8, roll, pitch, yaw, x, y, z f32;
- LVX2 device info (63 B): LiDAR SN char[16], hub SN char[16], LiDAR ID u32, LiDAR type
  u8, device type u8, extrinsic enable u8, roll, pitch, yaw, x, y, z f32;
- frame: current offset u64, next offset u64, frame index u64 (24 B), packages;
- LVX package: device index u8 + a Livox SDK 1 packet (version 5, slot, LiDAR id,
  reserved, status u32, timestamp type, data type, timestamp u64; 18 B) + points;
- LVX2 package (27 B): version u8, LiDAR ID u32, LiDAR type u8, timestamp type u8,
  timestamp u64, UDP counter u16, data type u8, length u32, frame counter u8, reserved
  4 B; then points (type 1: x, y, z i32 mm + reflectivity + tag, 14 B; type 2: i16 cm, 8 B).
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from pathlib import Path

MAGIC = 0xAC0EA767
T0 = 1_767_225_600_000_000_000  # ns: a PTP time, 2026-01-01 UTC


def public_header(version: Sequence[int], magic: int = MAGIC) -> bytes:
    return b"livox_tech" + bytes(6) + bytes(version) + struct.pack("<I", magic)


def private_header(devices: int, duration_ms: int = 50) -> bytes:
    return struct.pack("<IB", duration_ms, devices)


def lvx1_device(
    code: bytes, index: int, dev_type: int, enable: int, ext: Sequence[float], hub: bytes = b""
) -> bytes:
    return struct.pack("<16s16sBBB6f", code, hub, index, dev_type, enable, *ext)


def lvx2_device(
    sn: bytes,
    lidar_id: int,
    dev_type: int,
    enable: int,
    ext: Sequence[float],
    lidar_type: int = 247,
    hub: bytes = b"",
) -> bytes:
    return struct.pack("<16s16sIBBB6f", sn, hub, lidar_id, lidar_type, dev_type, enable, *ext)


def sdk1_packet(
    data_type: int, stamp: int, records: bytes, ts_type: int = 1, version: int = 5
) -> bytes:
    """An SDK 1 point packet: the 18-byte header, then the records."""
    return struct.pack("<BBBBIBBQ", version, 0, 1, 0, 0, ts_type, data_type, stamp) + records


def avia_records(points: Sequence[tuple[int, int, int, int, int]]) -> bytes:
    """Data type 2 records: x, y, z i32 [mm], reflectivity, tag."""
    return b"".join(struct.pack("<iiiBB", *p) for p in points)


def lvx1_package(index: int, packet: bytes) -> bytes:
    return bytes([index]) + packet


def lvx2_package(
    lidar_id: int,
    stamp: int,
    data_type: int,
    records: bytes,
    *,
    ts_type: int = 0,
    udp: int = 0,
    version: int = 0,
    length: int | None = None,
) -> bytes:
    size = len(records) if length is None else length
    head = struct.pack(
        "<BIBBQHBIB4s", version, lidar_id, 8, ts_type, stamp, udp, data_type, size, 0, bytes(4)
    )
    assert len(head) == 27
    return head + records


def chain(offset: int, bodies: Sequence[bytes], first_index: int = 0) -> bytes:
    """Frames from file ``offset`` on: each header says where it is, where the next one
    starts and its index."""
    out = b""
    for k, body in enumerate(bodies):
        nxt = offset + 24 + len(body)
        out += struct.pack("<QQQ", offset, nxt, first_index + k) + body
        offset = nxt
    return out


def lvx_file(head: bytes, bodies: Sequence[bytes]) -> bytes:
    """A whole file: ``head`` (public and private headers, device infos), then frames."""
    return head + chain(len(head), bodies)


def mid40_lvx(path: Path, packets: int = 100) -> Path:
    """A Mid-40's LVX file (device type 1, data type 0: 100 firings 10 µs apart a
    packet, x, y, z i32 mm and reflectivity): a return 20 m ahead at every firing, 1 m
    left to right across each packet, extrinsics enabled (1 m up)."""
    records = b"".join(struct.pack("<iiiB", 20_000, k * 10, 5_000, 9) for k in range(100))
    head = (
        public_header((1, 1, 0, 0))
        + private_header(1)
        + lvx1_device(b"0TFDG1234567890", 0, 1, 1, (0.0, 0.0, 0.0, 0.0, 0.0, 1.0))
    )
    interval = 100 * 10_000  # ns a packet spans
    body = b"".join(
        lvx1_package(0, sdk1_packet(0, T0 + k * interval, records)) for k in range(packets)
    )
    path.write_bytes(lvx_file(head, [body]))
    return path
