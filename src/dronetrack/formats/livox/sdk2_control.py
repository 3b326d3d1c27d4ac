"""Livox SDK 2 wire protocol (Mid-360), the control side: command frames, discovery,
parameter key/value lists and what a device says of itself.  The point and IMU
packets are in ``formats/livox/sdk2.py``.

Source: Livox "Communication Protocol -- Mid360" (livox_wiki_en
``livox_eth_protocol_mid360.md``) and Livox-SDK2 ``include/livox_lidar_def.h``.
Little-endian.

Command frame, a 24-byte header then data::

    0 sof 0xAA | 1 version 0 | 2 length u16 (whole frame, ≤ 1400) | 4 seq u32 | 8 cmd_id u16
    | 10 cmd_type (0 REQ, 1 ACK) | 11 sender (0 host, 1 LiDAR) | 12 reserved 6 B
    | 18 crc16 of bytes 0-17 (CRC-16/CCITT-FALSE) | 20 crc32 of data (0 if none) | 24 data
"""

from __future__ import annotations

import binascii
import ipaddress
import struct
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from dronetrack.errors import DecodeError, InputError
from dronetrack.formats.livox.common import Bytes

__all__ = [
    "DISCOVERY",
    "INFO_KEYS",
    "KEY_IMU_HOST",
    "KEY_POINT_HOST",
    "KEY_STATE_HOST",
    "KEY_WORK_MODE",
    "KEY_WORK_STATE",
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
    "encode_frame",
    "encode_key_list",
    "encode_key_values",
    "host_config_request",
]

SOF = 0xAA
REQ, ACK = 0, 1  # cmd_type
HOST, LIDAR = 0, 1  # sender
DISCOVERY, SET_PARAMS, QUERY_PARAMS, PUSH, REBOOT = 0x0000, 0x0100, 0x0101, 0x0102, 0x0200
MAX_FRAME_BYTES = 1400
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
