"""DYNAMIXEL Protocol 2.0 packets, and the XM430-W350 control-table units.

Packet (ROBOTIS e-manual, ``docs/en/dxl/protocol2.md``)::

    FF FF FD 00 | ID | LEN_L LEN_H | INST | params … | CRC_L CRC_H

* ``FF FF FD`` is the header, ``00`` the reserved byte; ID 0–252, 0xFE broadcast
  (0xFD and 0xFF are never IDs, so that no ID looks like a header byte).
* LEN (u16, little-endian) counts the instruction, the *stuffed* parameters and
  the CRC: LEN = len(stuffed INST + params) + 2.
* A status packet is the instruction 0x55 whose first parameter is the error
  byte: bit 7 is the *alert* flag (the hardware-error status at address 70 is
  non-zero) and bits 0–6 hold one error **number** (not a bit mask): 1 result
  fail, 2 instruction, 3 CRC, 4 data range, 5 data length, 6 data limit,
  7 access.
* Byte stuffing: wherever ``FF FF FD`` occurs in INST + params, one ``FD`` is
  inserted after it (``FF FF FD`` → ``FF FF FD FD``), so a header can only appear
  where a packet starts.  The length and CRC are computed on the stuffed bytes.
* CRC-16: polynomial 0x8005, initial value 0, no reflection, no final xor, over
  every byte from the header to the last parameter.

Multi-byte control-table values are little-endian, signed where they can be
negative (present velocity, present position, goal position).

XM430-W350 units (e-manual ``docs/en/dxl/x/xm430-w350.md`` and its includes):
4096 position ticks per revolution (0.088°/tick); velocity 0.229 rev/min per
unit; profile acceleration 214.577 rev/min² per unit (velocity-based profile).
Angle convention here: tick 2048 is 0 rad, increasing ticks are counter-clockwise
seen from the horn (the servo's Normal drive mode), so

    θ = (p − 2048) · 2π / 4096
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from dronetrack.errors import DecodeError

__all__ = [
    "ACCEL_UNIT",
    "ADDR",
    "BAUD_RATE_CODES",
    "BROADCAST_ID",
    "ERROR_NAMES",
    "HEADER",
    "TICKS_PER_REV",
    "TICK_ZERO",
    "VELOCITY_UNIT",
    "BadPacket",
    "Err",
    "Inst",
    "Packet",
    "PacketParser",
    "accel_to_units",
    "crc16",
    "decode_packet",
    "encode_instruction",
    "encode_packet",
    "encode_status",
    "rad_to_ticks",
    "rate_to_units",
    "read_params",
    "stuff",
    "sync_read_params",
    "sync_write_params",
    "ticks_to_rad",
    "units_to_accel",
    "units_to_rate",
    "unstuff",
]

HEADER = b"\xff\xff\xfd\x00"  # three header bytes and the reserved byte
BROADCAST_ID = 0xFE
# The longest LEN accepted: the official SDK's packet buffer is 1 KiB.
MAX_LENGTH = 1024


class Inst:
    """Instruction codes."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    BULK_READ = 0x92
    BULK_WRITE = 0x93


class Err:
    """Error numbers of a status packet's error byte (bits 0–6), and the alert bit."""

    NONE = 0
    RESULT_FAIL = 1
    INSTRUCTION = 2
    CRC = 3
    DATA_RANGE = 4
    DATA_LENGTH = 5
    DATA_LIMIT = 6
    ACCESS = 7
    ALERT = 0x80


ERROR_NAMES = {
    Err.RESULT_FAIL: "result fail",
    Err.INSTRUCTION: "instruction error",
    Err.CRC: "CRC error",
    Err.DATA_RANGE: "data range error",
    Err.DATA_LENGTH: "data length error",
    Err.DATA_LIMIT: "data limit error",
    Err.ACCESS: "access error",
}


class ADDR:
    """XM430-W350 control-table addresses used here (EEPROM below 64, RAM from 64)."""

    MODEL_NUMBER = 0  # 2 B, R, 1020
    FIRMWARE_VERSION = 6  # 1 B, R
    ID = 7  # 1 B
    BAUD_RATE = 8  # 1 B, code: 0 9600, 1 57600, 2 115200, 3 1M, 4 2M, 5 3M, 6 4M, 7 4.5M
    RETURN_DELAY = 9  # 1 B, 2 µs units
    DRIVE_MODE = 10  # 1 B, bit 0 reverse, bit 2 time-based profile
    OPERATING_MODE = 11  # 1 B, 3 = position control
    PROTOCOL = 13  # 1 B
    VELOCITY_LIMIT = 44  # 4 B, 0.229 rpm
    MAX_POSITION = 48  # 4 B, ticks
    MIN_POSITION = 52  # 4 B, ticks
    TORQUE_ENABLE = 64  # 1 B; 1 locks the EEPROM area
    LED = 65
    STATUS_RETURN_LEVEL = 68  # 0 ping only, 1 ping and read, 2 all
    HARDWARE_ERROR = 70  # 1 B, R
    PROFILE_ACCELERATION = 108  # 4 B, 214.577 rev/min²
    PROFILE_VELOCITY = 112  # 4 B, 0.229 rpm
    GOAL_POSITION = 116  # 4 B, ticks
    REALTIME_TICK = 120  # 2 B, ms
    MOVING = 122  # 1 B
    PRESENT_VELOCITY = 128  # 4 B, signed, 0.229 rpm
    PRESENT_POSITION = 132  # 4 B, signed, ticks
    EEPROM_END = 64


# The rate [baud] each code of the Baud Rate item (address 8) sets, code 0 first.
BAUD_RATE_CODES = (9600, 57600, 115200, 1_000_000, 2_000_000, 3_000_000, 4_000_000, 4_500_000)
TICKS_PER_REV = 4096
TICK_ZERO = 2048
# ω [rad/s] per velocity unit: 0.229 rev/min · 2π rad/rev / 60 s/min
VELOCITY_UNIT = 0.229 * 2.0 * math.pi / 60.0
# α [rad/s²] per acceleration unit: 214.577 rev/min² · 2π rad/rev / 3600 s²/min²
ACCEL_UNIT = 214.577 * 2.0 * math.pi / 3600.0


def ticks_to_rad(ticks: int) -> float:
    """θ = (p − 2048) · 2π / 4096."""
    return (ticks - TICK_ZERO) * 2.0 * math.pi / TICKS_PER_REV


def rad_to_ticks(angle: float) -> int:
    """p = round(θ · 4096 / 2π) + 2048 (no clamping: the caller bounds it)."""
    return round(angle * TICKS_PER_REV / (2.0 * math.pi)) + TICK_ZERO


def rate_to_units(rate: float) -> int:
    """Profile or present velocity units for ω [rad/s]: v = round(ω / (0.229 · 2π/60))."""
    return round(rate / VELOCITY_UNIT)


def units_to_rate(units: int) -> float:
    """ω = v · 0.229 · 2π / 60 [rad/s]."""
    return units * VELOCITY_UNIT


def accel_to_units(accel: float) -> int:
    """Profile acceleration units for α [rad/s²]: a = round(α / (214.577 · 2π/3600))."""
    return round(accel / ACCEL_UNIT)


def units_to_accel(units: int) -> float:
    """α = a · 214.577 · 2π / 3600 [rad/s²]."""
    return units * ACCEL_UNIT


def _crc_table() -> tuple[int, ...]:
    # Table of the MSB-first CRC of each byte value shifted into the top of a zero register.
    table = []
    for byte in range(256):
        c = byte << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x8005) if c & 0x8000 else (c << 1)
        table.append(c & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray | memoryview, crc: int = 0) -> int:
    """CRC-16 (poly 0x8005, init 0, MSB first, no reflection, no final xor) of ``data``."""
    for b in bytes(data):
        crc = ((crc << 8) ^ _CRC_TABLE[((crc >> 8) ^ b) & 0xFF]) & 0xFFFF
    return crc


def stuff(body: bytes) -> bytes:
    """``body`` (instruction and parameters) with an ``FD`` after every ``FF FF FD``."""
    out = bytearray()
    for i, b in enumerate(body):
        out.append(b)
        if b == 0xFD and i >= 2 and body[i - 1] == 0xFF and body[i - 2] == 0xFF:
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes) -> bytes:
    """Inverse of :func:`stuff`; DecodeError where an ``FF FF FD`` lacks its stuffed ``FD``."""
    out = bytearray()
    i, n = 0, len(body)
    while i < n:
        b = body[i]
        out.append(b)
        # the inserted FD is never an FF, so the two bytes before are the original ones
        if b == 0xFD and i >= 2 and body[i - 1] == 0xFF and body[i - 2] == 0xFF:
            if i + 1 >= n or body[i + 1] != 0xFD:
                raise DecodeError(f"packet body has FF FF FD without its stuffed FD at byte {i}")
            i += 1
        i += 1
    return bytes(out)


@dataclass(frozen=True, slots=True)
class Packet:
    """One decoded packet: an instruction, or a status (``instruction == 0x55``)."""

    ident: int
    instruction: int
    params: bytes = b""

    @property
    def is_status(self) -> bool:
        return self.instruction == Inst.STATUS

    @property
    def error(self) -> int:
        """A status packet's error byte (alert bit 7, error number in bits 0–6)."""
        if not self.is_status:
            raise DecodeError(f"instruction 0x{self.instruction:02X} has no error byte")
        return self.params[0]

    @property
    def error_number(self) -> int:
        return self.error & 0x7F

    @property
    def alert(self) -> bool:
        return bool(self.error & Err.ALERT)

    @property
    def data(self) -> bytes:
        """A status packet's parameters after the error byte."""
        return self.params[1:] if self.is_status else self.params


@dataclass(frozen=True, slots=True)
class BadPacket:
    """Framed bytes that are not a valid packet: the stream parser reports them as such.

    ident and instruction are as read from the (untrusted) frame, -1 where absent;
    ``crc`` is True when the frame was whole and only the CRC disagreed.
    """

    raw: bytes
    reason: str
    ident: int = -1
    instruction: int = -1
    crc: bool = False


def encode_packet(ident: int, instruction: int, params: bytes = b"") -> bytes:
    """A whole packet: header, ID, length, stuffed instruction and parameters, CRC."""
    if not 0 <= ident <= 0xFE or ident == 0xFD:
        raise DecodeError(f"packet ID must be 0–252 or 254 (broadcast), got {ident}")
    if not 0 <= instruction <= 0xFF:
        raise DecodeError(f"instruction must be a byte, got {instruction}")
    body = stuff(bytes([instruction]) + bytes(params))
    length = len(body) + 2
    if length > 0xFFFF:
        raise DecodeError(f"packet too long: LEN {length} > 65535")
    head = HEADER + bytes([ident]) + length.to_bytes(2, "little")
    framed = head + body
    return framed + crc16(framed).to_bytes(2, "little")


def encode_instruction(ident: int, instruction: int, params: bytes = b"") -> bytes:
    """An instruction packet (any instruction but status)."""
    if instruction == Inst.STATUS:
        raise DecodeError("0x55 is the status instruction; use encode_status")
    return encode_packet(ident, instruction, params)


def encode_status(ident: int, error: int = 0, data: bytes = b"") -> bytes:
    """A status packet: instruction 0x55, the error byte, then ``data``."""
    if not 0 <= error <= 0xFF:
        raise DecodeError(f"error byte must be 0–255, got {error}")
    return encode_packet(ident, Inst.STATUS, bytes([error]) + bytes(data))


def _frame_problem(raw: bytes) -> tuple[str, bool] | None:
    """Why ``raw`` (exactly one frame) is not a packet, and whether only its CRC is bad."""
    if len(raw) < 10:
        return f"packet has {len(raw)} bytes, fewer than the 10 of the shortest", False
    if raw[:4] != HEADER:
        return f"packet does not start with FF FF FD 00 (got {raw[:4].hex(' ').upper()})", False
    ident = raw[4]
    if ident in (0xFD, 0xFF):
        return f"packet ID 0x{ident:02X} is reserved", False
    length = int.from_bytes(raw[5:7], "little")
    if length < 3:
        return f"packet LEN {length} < 3 (instruction and CRC)", False
    if len(raw) != 7 + length:
        return f"packet LEN {length} says {7 + length} bytes, has {len(raw)}", False
    expected = crc16(raw[:-2])
    got = int.from_bytes(raw[-2:], "little")
    if expected != got:
        return f"CRC mismatch: packet has 0x{got:04X}, bytes give 0x{expected:04X}", True
    return None


def decode_packet(raw: bytes | bytearray | memoryview) -> Packet:
    """One whole packet (header to CRC), checked and unstuffed; DecodeError names the problem."""
    data = bytes(raw)
    problem = _frame_problem(data)
    if problem is not None:
        raise DecodeError(problem[0])
    body = unstuff(data[7:-2])
    if body[0] == Inst.STATUS and len(body) < 2:
        raise DecodeError("status packet has no error byte")
    return Packet(ident=data[4], instruction=body[0], params=body[1:])


class PacketParser:
    """Finds packets in a byte stream fed in arbitrary pieces.

    ``feed`` returns what the new bytes completed, in order: ``Packet`` for a valid
    one, ``BadPacket`` for a framed one that fails (bad CRC, bad length, bad
    stuffing).  Bytes before a header are skipped and counted in ``skipped``.  After
    a bad frame the search resumes one byte after its header, so a corrupted length
    cannot swallow the packets that follow.
    """

    def __init__(self, max_length: int = MAX_LENGTH) -> None:
        self.max_length = max_length
        self.buffer = bytearray()
        self.skipped = 0

    @property
    def pending(self) -> int:
        """Bytes held, waiting for the rest of a packet."""
        return len(self.buffer)

    def reset(self) -> None:
        """Drop a partial packet (a device does so after an inter-byte timeout)."""
        self.skipped += len(self.buffer)
        self.buffer.clear()

    def feed(self, data: bytes | bytearray | memoryview) -> list[Packet | BadPacket]:
        self.buffer += data
        out: list[Packet | BadPacket] = []
        buf = self.buffer
        while True:
            start = buf.find(HEADER)
            if start < 0:
                # keep a tail that may be the start of a header
                keep = next((k for k in (3, 2, 1) if buf.endswith(HEADER[:k])), 0)
                self.skipped += len(buf) - keep
                del buf[: len(buf) - keep]
                return out
            if start:
                self.skipped += start
                del buf[:start]
            if len(buf) < 7:
                return out
            ident, length = buf[4], int.from_bytes(buf[5:7], "little")
            if ident in (0xFD, 0xFF) or length < 3 or length > self.max_length:
                why = (
                    f"packet ID 0x{ident:02X} is reserved"
                    if ident in (0xFD, 0xFF)
                    else f"packet LEN {length} outside 3–{self.max_length}"
                )
                out.append(BadPacket(bytes(buf[:7]), why, ident=ident))
                del buf[:1]
                continue
            if len(buf) < 7 + length:
                return out
            frame = bytes(buf[: 7 + length])
            try:
                out.append(decode_packet(frame))
            except DecodeError as exc:
                crc_bad = str(exc).startswith("CRC mismatch")
                out.append(
                    BadPacket(frame, str(exc), ident=ident, instruction=frame[7], crc=crc_bad)
                )
                del buf[:1]
                continue
            del buf[: 7 + length]


def read_params(address: int, length: int) -> bytes:
    """READ parameters: address u16, length u16."""
    return address.to_bytes(2, "little") + length.to_bytes(2, "little")


def sync_read_params(address: int, length: int, ids: Iterable[int]) -> bytes:
    """SYNC READ parameters: address u16, length u16, then one ID byte per servo."""
    return read_params(address, length) + bytes(ids)


def sync_write_params(address: int, length: int, data: Mapping[int, bytes]) -> bytes:
    """SYNC WRITE parameters: address u16, length u16, then ``ID, data[length]`` per servo."""
    out = bytearray(read_params(address, length))
    for ident, values in data.items():
        if len(values) != length:
            raise DecodeError(
                f"sync write data for ID {ident} has {len(values)} bytes, not {length}"
            )
        out.append(ident)
        out += values
    return bytes(out)
