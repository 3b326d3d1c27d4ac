"""Livox SDK 2 wire protocol (Mid-360): command frames, discovery, parameter
key/value lists, and point/IMU packets, as numpy codecs.

Source: Livox "Communication Protocol -- Mid360" (livox_wiki_en
``livox_eth_protocol_mid360.md``) and Livox-SDK2 ``include/livox_lidar_def.h``.
Little-endian.

Command frame, a 24-byte header then data::

    0 sof 0xAA | 1 version 0 | 2 length u16 (whole frame, ≤ 1400) | 4 seq u32 | 8 cmd_id u16
    | 10 cmd_type (0 REQ, 1 ACK) | 11 sender (0 host, 1 LiDAR) | 12 reserved 6 B
    | 18 crc16 of bytes 0-17 (CRC-16/CCITT-FALSE) | 20 crc32 of data (0 if none) | 24 data

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

import binascii
import ipaddress
import struct
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError, InputError
from dronetrack.formats.livox_common import (
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
    "DISCOVERY",
    "INFO_KEYS",
    "KEY_IMU_HOST",
    "KEY_POINT_HOST",
    "KEY_STATE_HOST",
    "KEY_WORK_MODE",
    "KEY_WORK_STATE",
    "LAYOUTS",
    "SET_PARAMS",
    "CommandFrame",
    "DeviceInfo",
    "DiscoveryAck",
    "HostIpConfig",
    "ParamAck",
    "QueryAck",
    "crc16",
    "decode_frame",
    "decode_key_list",
    "decode_key_values",
    "decode_packet",
    "decode_packets",
    "encode_frame",
    "encode_imu_packets",
    "encode_key_list",
    "encode_key_values",
    "encode_point_packets",
    "host_config_request",
    "packet_problem",
]

SOF = 0xAA
REQ, ACK = 0, 1  # cmd_type
HOST, LIDAR = 0, 1  # sender
DISCOVERY, SET_PARAMS, QUERY_PARAMS, PUSH, REBOOT = 0x0000, 0x0100, 0x0101, 0x0102, 0x0200
MAX_FRAME_BYTES = 1400
DEVICE_TYPE_MID360 = 9  # Livox-SDK2 livox_lidar_def.h LivoxLidarDeviceType
# LiDAR-side ports; the host's are configurable (56101, 56201, 56301, 56401 by default)
DISCOVERY_PORT, CMD_PORT, PUSH_PORT, POINT_PORT, IMU_PORT = 56000, 56100, 56200, 56300, 56400
KEY_DATA_TYPE, KEY_STATE_HOST, KEY_POINT_HOST, KEY_IMU_HOST = 0x0000, 0x0005, 0x0006, 0x0007
KEY_WORK_MODE, KEY_IMU_ENABLE = 0x001A, 0x001C
# read-only keys (document, "0x0102 LiDAR Information Push", key_value_list): serial
# number, product info, firmware (app, loader, hardware) versions, MAC, current work state
KEY_SERIAL, KEY_PRODUCT_INFO, KEY_VERSION_APP = 0x8000, 0x8001, 0x8002
KEY_VERSION_LOADER, KEY_VERSION_HARDWARE, KEY_MAC, KEY_WORK_STATE = 0x8003, 0x8004, 0x8005, 0x8006
INFO_KEYS = (
    KEY_SERIAL,
    KEY_PRODUCT_INFO,
    KEY_VERSION_APP,
    KEY_VERSION_LOADER,
    KEY_VERSION_HARDWARE,
    KEY_MAC,
    KEY_WORK_STATE,
)
# work states (document, "LiDAR Working Status")
WORK_STATES = {
    0x01: "SAMPLING",
    0x02: "IDLE",
    0x04: "ERROR",
    0x05: "SELFCHECK",
    0x06: "MOTORSTARTUP",  # the document spells it MOTORSTARUP
    0x08: "UPGRADE",
    0x09: "READY",
}
WORK_MODE_SAMPLING, WORK_MODE_IDLE = 0x01, 0x02
# return codes (protocol document, "Return Code Description")
RET_OK, RET_FAILURE, RET_NOT_PERMITTED, RET_OUT_OF_RANGE = 0x00, 0x01, 0x02, 0x03
RET_KEY_UNSUPPORTED, RET_READ_ONLY, RET_BAD_LENGTH = 0x20, 0x22, 0x23
CMD_HEADER = struct.Struct("<BBHIHBB6sHI")

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


def crc16(data: Bytes) -> int:
    """CRC-16/CCITT-FALSE (0x1021, init 0xFFFF, not reflected)."""
    return binascii.crc_hqx(bytes(data), 0xFFFF)


@dataclass(frozen=True)
class CommandFrame:
    cmd_id: int
    cmd_type: int
    seq: int
    payload: bytes = b""
    sender: int = HOST
    version: int = 0


def encode_frame(frame: CommandFrame) -> bytes:
    length = 24 + len(frame.payload)
    if length > MAX_FRAME_BYTES:
        raise InputError(f"Livox command frame of {length} bytes exceeds {MAX_FRAME_BYTES}")
    head = struct.pack(
        "<BBHIHBB6s",
        SOF,
        frame.version,
        length,
        frame.seq,
        frame.cmd_id,
        frame.cmd_type,
        frame.sender,
        b"",
    )
    data_crc = zlib.crc32(frame.payload) if frame.payload else 0
    return head + struct.pack("<HI", crc16(head), data_crc) + frame.payload


def decode_frame(buf: Bytes) -> CommandFrame:
    """One command frame (one UDP datagram); DecodeError naming what is wrong."""
    b = bytes(buf)
    if len(b) < 24:
        raise DecodeError(f"Livox command frame of {len(b)} bytes is shorter than 24")
    sof, version, length, seq, cmd_id, cmd_type, sender, _, c16, c32 = CMD_HEADER.unpack_from(b)
    if sof != SOF:
        raise DecodeError(f"Livox command frame starts with 0x{sof:02X}, not SOF 0xAA")
    if length != len(b):
        raise DecodeError(f"Livox command frame length field {length} != {len(b)} bytes")
    if crc16(b[:18]) != c16:
        raise DecodeError("Livox command frame header CRC-16 mismatch")
    data = b[24:]
    if (zlib.crc32(data) if data else 0) != c32:
        raise DecodeError("Livox command frame data CRC-32 mismatch")
    return CommandFrame(cmd_id, cmd_type, seq, data, sender, version)


def _ip(text: str) -> bytes:
    try:
        return ipaddress.IPv4Address(text).packed
    except ValueError as exc:
        raise InputError(f"IP address {text!r}: {exc}") from exc


@dataclass(frozen=True)
class DiscoveryAck:
    """ACK of discovery 0x0000: return code, device type, serial number, IP, command port."""

    ret_code: int
    dev_type: int
    serial: str
    lidar_ip: str
    cmd_port: int

    def encode(self) -> bytes:
        head = struct.pack("<BB16s", self.ret_code, self.dev_type, self.serial.encode("ascii"))
        return head + _ip(self.lidar_ip) + struct.pack("<H", self.cmd_port)

    @staticmethod
    def decode(payload: Bytes) -> DiscoveryAck:
        b = bytes(payload)
        if len(b) != 24:
            raise DecodeError(f"Livox discovery ACK has {len(b)} bytes, expected 24")
        serial = b[2:18].split(b"\0", 1)[0].decode("ascii", "replace")
        ip = str(ipaddress.IPv4Address(b[18:22]))
        return DiscoveryAck(b[0], b[1], serial, ip, struct.unpack_from("<H", b, 22)[0])


@dataclass(frozen=True)
class HostIpConfig:
    """Value of keys 0x0005-0x0007: where the LiDAR sends status, points or IMU data."""

    host_ip: str
    host_port: int
    lidar_port: int

    def encode(self) -> bytes:
        return _ip(self.host_ip) + struct.pack("<HH", self.host_port, self.lidar_port)

    @staticmethod
    def decode(value: Bytes) -> HostIpConfig:
        b = bytes(value)
        if len(b) != 8:
            raise DecodeError(f"Livox host IP configuration has {len(b)} bytes, expected 8")
        return HostIpConfig(str(ipaddress.IPv4Address(b[:4])), *struct.unpack_from("<HH", b, 4))


@dataclass(frozen=True)
class ParamAck:
    """ACK of 0x0100: return code and, on failure, the offending key."""

    ret_code: int
    error_key: int = 0

    def encode(self) -> bytes:
        return struct.pack("<BH", self.ret_code, self.error_key)

    @staticmethod
    def decode(payload: Bytes) -> ParamAck:
        if len(payload) != 3:
            raise DecodeError(f"Livox parameter ACK has {len(payload)} bytes, expected 3")
        return ParamAck(*struct.unpack("<BH", bytes(payload)))


def encode_key_values(items: list[tuple[int, bytes]]) -> bytes:
    """Data of 0x0100 / 0x0102: key_num u16, reserved u16, then {key u16, length u16, value}."""
    out = struct.pack("<HH", len(items), 0)
    for key, value in items:
        out += struct.pack("<HH", key, len(value)) + value
    return out


def decode_key_values(data: Bytes) -> list[tuple[int, bytes]]:
    b = bytes(data)
    if len(b) < 4:
        raise DecodeError(f"Livox key/value list of {len(b)} bytes is shorter than 4")
    (count,) = struct.unpack_from("<H", b)
    return _items(b, count, 4)


def _items(b: bytes, count: int, pos: int) -> list[tuple[int, bytes]]:
    """``count`` {key u16, length u16, value} items from ``b[pos:]``, filling it exactly."""
    items = []
    for i in range(count):
        if pos + 4 > len(b):
            raise DecodeError(f"Livox key/value list truncated at item {i} of {count}")
        key, size = struct.unpack_from("<HH", b, pos)
        if pos + 4 + size > len(b):
            raise DecodeError(f"Livox key 0x{key:04X} value of {size} bytes is truncated")
        items.append((key, b[pos + 4 : pos + 4 + size]))
        pos += 4 + size
    if pos != len(b):
        raise DecodeError(f"Livox key/value list has {len(b) - pos} bytes after {count} items")
    return items


def host_config_request(
    host_ip: str,
    state_port: int = 56201,
    point_port: int = 56301,
    imu_port: int = 56401,
    work_mode: int | None = WORK_MODE_SAMPLING,
) -> bytes:
    """Data of a 0x0100 request that sends status, points and IMU to the host and, unless
    ``work_mode`` is None, sets the LiDAR's work mode (0x01 sampling).  Livox-SDK2 sends
    the three addresses alone (``build_request.cpp`` BuildUpdateMid360LidarCfgRequest)
    and the work mode in a request of its own."""
    items = [
        (KEY_STATE_HOST, HostIpConfig(host_ip, state_port, PUSH_PORT).encode()),
        (KEY_POINT_HOST, HostIpConfig(host_ip, point_port, POINT_PORT).encode()),
        (KEY_IMU_HOST, HostIpConfig(host_ip, imu_port, IMU_PORT).encode()),
    ]
    if work_mode is not None:
        items.append((KEY_WORK_MODE, bytes([work_mode])))
    return encode_key_values(items)


def encode_key_list(keys: Sequence[int]) -> bytes:
    """Data of a 0x0101 query: key_num u16, reserved u16, then the keys u16."""
    return struct.pack(f"<HH{len(keys)}H", len(keys), 0, *keys)


def decode_key_list(data: Bytes) -> list[int]:
    b = bytes(data)
    if len(b) < 4 or len(b) % 2:
        raise DecodeError(f"Livox key list of {len(b)} bytes is not 4 + 2·N bytes")
    (count,) = struct.unpack_from("<H", b)
    if len(b) != 4 + 2 * count:
        raise DecodeError(f"Livox key list of {len(b)} bytes does not hold {count} keys")
    return list(struct.unpack_from(f"<{count}H", b, 4))


@dataclass(frozen=True)
class QueryAck:
    """ACK of 0x0101: ret_code u8, key_num u16, then {key u16, length u16, value}."""

    ret_code: int
    items: tuple[tuple[int, bytes], ...] = ()

    def encode(self) -> bytes:
        return struct.pack("<BH", self.ret_code, len(self.items)) + b"".join(
            struct.pack("<HH", key, len(value)) + value for key, value in self.items
        )

    @staticmethod
    def decode(payload: Bytes) -> QueryAck:
        b = bytes(payload)
        if len(b) < 3:
            raise DecodeError(f"Livox query ACK of {len(b)} bytes is shorter than 3")
        ret_code, count = struct.unpack_from("<BH", b)
        return QueryAck(ret_code, tuple(_items(b, count, 3)))


def _text(value: bytes) -> str:
    """A NUL-padded string value (sn, product_info)."""
    return value.split(b"\0", 1)[0].decode("ascii", "replace")


def _version(value: bytes) -> str:
    """A uint8_t[4] version aa.bb.cc.dd, version_info[0] = aa (as Livox-SDK2's
    livox_lidar_info_get sample prints it: decimal)."""
    return ".".join(str(b) for b in value)


# key → (field of DeviceInfo, value length (strings: at most), reading of the value)
_INFO_FIELDS: dict[int, tuple[str, int, Callable[[bytes], object]]] = {
    KEY_SERIAL: ("serial", 16, _text),
    KEY_PRODUCT_INFO: ("product", 64, _text),
    KEY_VERSION_APP: ("firmware", 4, _version),
    KEY_VERSION_LOADER: ("loader", 4, _version),
    KEY_VERSION_HARDWARE: ("hardware", 4, _version),
    KEY_MAC: ("mac", 6, lambda v: ":".join(f"{b:02x}" for b in v)),
    KEY_WORK_STATE: ("work_state", 1, lambda v: v[0]),
}


@dataclass(frozen=True)
class DeviceInfo:
    """What a device says of itself in the ACK of a 0x0101 query of ``INFO_KEYS``: serial
    number, product info ("LiDAR type + production date"), firmware version
    (``version_app``), loader and hardware versions, MAC address and current work
    state; None for a key the device left out."""

    serial: str | None = None
    product: str | None = None
    firmware: str | None = None
    loader: str | None = None
    hardware: str | None = None
    mac: str | None = None
    work_state: int | None = None

    @staticmethod
    def from_items(items: Sequence[tuple[int, bytes]]) -> DeviceInfo:
        """From a query ACK's key/value list; other keys are ignored.  DecodeError for a
        value whose length is not the document's (a string may be shorter)."""
        fields: dict[str, object] = {}
        for key, value in items:
            if key not in _INFO_FIELDS:
                continue
            name, size, read = _INFO_FIELDS[key]
            text = key in (KEY_SERIAL, KEY_PRODUCT_INFO)
            if len(value) > size if text else len(value) != size:
                raise DecodeError(
                    f"Livox key 0x{key:04X} ({name}) has {len(value)} bytes, expected {size}"
                )
            fields[name] = read(value)
        return DeviceInfo(**fields)  # type: ignore[arg-type]

    @property
    def work_state_name(self) -> str | None:
        if self.work_state is None:
            return None
        return WORK_STATES.get(self.work_state, "unknown")


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
