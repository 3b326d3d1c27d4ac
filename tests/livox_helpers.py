"""Test helpers for the Livox links: Livox SDK 2 (Mid-360) command frames and point
packets built by hand from the protocol document (livox_wiki_en
``livox_eth_protocol_mid360.md``) with ``struct.pack`` and a bitwise CRC-16 written
from its definition, never with dronetrack's encoders; the hypothesis strategy of
damaged packets both SDKs' fuzz tests feed their decoders; loopback sockets;
reading a client for a bounded time; and a client refused on a port another holds."""

from __future__ import annotations

import socket
import struct
import time
import zlib
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np
import pytest
from hypothesis import strategies as st

from dronetrack.errors import DeviceError
from dronetrack.sources.assembly import PointBatch

LOOP = "127.0.0.1"

T0 = 1_700_000_000_123_456_789  # ns: a PTP-like device time


def ccitt_false(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: polynomial 0x1021, init 0xFFFF, not reflected, no final xor."""
    reg = 0xFFFF
    for b in data:
        reg ^= b << 8
        for _ in range(8):
            reg = ((reg << 1) ^ 0x1021) & 0xFFFF if reg & 0x8000 else (reg << 1) & 0xFFFF
    return reg


def sdk2_frame(cmd_id: int, cmd_type: int, seq: int, data: bytes, sender: int = 0) -> bytes:
    """A command frame: sof 0xAA, version 0, length, seq u32, cmd_id u16, cmd_type,
    sender, 6 reserved bytes, CRC-16 of bytes 0-17, CRC-32 of the data (0 without
    data; the document's CRC-32 is zlib's), data."""
    head = struct.pack(
        "<BBHIHBB6s", 0xAA, 0, 24 + len(data), seq, cmd_id, cmd_type, sender, bytes(6)
    )
    data_crc = zlib.crc32(data) if data else 0
    return head + struct.pack("<HI", ccitt_false(head), data_crc) + data


def sdk2_packet(
    data_type: int,
    records: bytes,
    dot_num: int,
    interval: int = 950,
    time_type: int = 0,
    udp_cnt: int = 3,
    frame_cnt: int = 1,
    stamp: int = T0,
) -> bytes:
    """A point/IMU packet: version 0, length, time_interval (0.1 µs), dot_num, udp_cnt,
    frame_cnt, data_type, time_type, 12 reserved bytes, CRC-32 of timestamp and data,
    timestamp u64 ns, records."""
    head = struct.pack(
        "<BHHHHBBB12s",
        0,
        36 + len(records),
        interval,
        dot_num,
        udp_cnt,
        frame_cnt,
        data_type,
        time_type,
        bytes(12),
    )
    body = struct.pack("<Q", stamp) + records
    return head + struct.pack("<I", zlib.crc32(body)) + body


@st.composite
def damaged_packets(draw: st.DrawFn, good: Sequence[bytes], header_bytes: int) -> bytes:
    """A good packet truncated, extended, with one header byte changed, or random bytes."""
    packet = draw(st.sampled_from(list(good)))
    kind = draw(st.sampled_from(["truncate", "extend", "random", "flip"]))
    if kind == "truncate":
        return packet[: draw(st.integers(0, len(packet) - 1))]
    if kind == "extend":
        return packet + draw(st.binary(min_size=1, max_size=40))
    if kind == "flip":  # any header byte changed
        i = draw(st.integers(0, header_bytes - 1))
        return packet[:i] + bytes([draw(st.integers(0, 255))]) + packet[i + 1 :]
    return draw(st.binary(max_size=1400))


def loopback_udp() -> socket.socket:
    """A UDP socket on 127.0.0.1 at a port the kernel picks, waiting up to 1 s."""
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind((LOOP, 0))
    s.settimeout(1.0)
    return s


def port_of(s: socket.socket) -> int:
    return int(s.getsockname()[1])


def drain_then_silence(sock: socket.socket, most: int = 2000) -> bool:
    """Receive the datagrams already on their way (at most ``most``, each within
    0.2 s of the last); True if none came for 0.2 s after them."""
    sock.settimeout(0.2)
    for _ in range(most):
        try:
            sock.recv(2048)
        except TimeoutError:
            return True
    return False


def assert_no_reply(sock: socket.socket, to: tuple[str, int], requests: Sequence[bytes]) -> None:
    """Each request sent to ``to`` gets no reply within 0.2 s."""
    sock.settimeout(0.2)
    for buf in requests:
        sock.sendto(buf, to)
        try:
            reply = sock.recv(2048)
        except TimeoutError:
            continue
        raise AssertionError(f"{buf.hex()} got the reply {reply.hex()}")
    sock.settimeout(1.0)


class Reader(Protocol):
    def read(self, timeout_s: float = 0.1) -> PointBatch: ...


def collect(client: Reader, count: int, limit_s: float = 4.0) -> PointBatch:
    """Read until ``count`` points came or ``limit_s`` passed."""
    parts: list[PointBatch] = []
    got, t0 = 0, time.monotonic()
    while got < count and time.monotonic() - t0 < limit_s:
        batch = client.read(0.1)
        parts.append(batch)
        got += len(batch)
    return PointBatch(
        np.concatenate([p.xyz for p in parts]).reshape(-1, 3),
        np.concatenate([p.t_ns for p in parts]),
        np.concatenate([p.reflectivity for p in parts]),
        np.concatenate([p.line for p in parts]),
    )


def settled(count: Callable[[], int], target: int, limit_s: float = 1.0) -> int:
    """``count()`` once it equals ``target``, or after ``limit_s``: a device's thread
    counts a packet just after it sends it, so a client may hold the last packet a
    moment before the device has counted it."""
    t0 = time.monotonic()
    while count() != target and time.monotonic() - t0 < limit_s:
        time.sleep(0.005)
    return count()


def read_for(client: Reader, seconds: float) -> None:
    """Read (and discard) for ``seconds``."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < seconds:
        client.read(0.05)


class Link(Reader, Protocol):
    @property
    def packets_received(self) -> int: ...

    def open(self, timeout_s: float = 3.0) -> None: ...


def assert_refused_beside(
    first: Link, second: Link, sdk: int, port: int, what: str, key: str
) -> None:
    """``second`` (a Livox SDK ``sdk`` client on ``first``'s host port ``port``, for
    ``what``, moved by URI key ``key``) fails to open with the one-line error naming the
    port as in use, and ``first`` still receives over 1000 packets in the next 1.5 s
    (both devices send over 2,000 a second) and no silence of 1 s."""
    in_use = (
        rf"Livox SDK {sdk} device at 127\.0\.0\.1: UDP port {port} \({what}\) is in use on "
        rf"this host, most likely by another dronetrack live or info on this LiDAR; a "
        rf"second LiDAR needs its own \(the URI's {key}=\)$"
    )
    with pytest.raises(DeviceError, match=in_use):
        second.open(timeout_s=1.0)
    before = first.packets_received
    read_for(first, 1.5)  # raises if no point packet comes for 1 s
    assert first.packets_received - before > 1000
