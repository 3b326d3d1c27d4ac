"""A live Livox SDK 1 LiDAR (Avia, Mid-40/70, Horizon, Tele) over UDP, host side.

The link, as the Livox SDK 1 runs it (``sdk_core/src/device_discovery.cpp``,
``command_handler/command_channel.cpp``):

1. discovery: the device broadcasts its broadcast code and device type (command 0x00)
   from its command port to the host's UDP port 55000;
2. handshake (0x01, sent with cmd_type ACK as the SDK sends it) to the device's
   command port 65000, carrying the host's IP and its command, data and IMU ports;
   the device answers with an ACK of the same sequence number, ret_code 0;
3. heartbeat (0x03) every second (the SDK: every > 800 ms); the SDK drops a device
   after 3 s without a heartbeat ACK, and so does this client;
4. start sampling (0x04, payload 1); point packets then stream to the host's data
   port; at the end stop sampling (0x04, payload 0) and disconnect (0x06).

Discovery is optional here: ``open`` waits ``discover_s`` for the broadcast from the
device's IP and records its type and code; if none comes (a device on another
subnet, or one already connected elsewhere) it sends the handshake straight to the
device's command port.  Without a device type, the time between firings is taken
from the points' data type: 10 µs for types 0 and 1 (Mid-40/70), else 4.167 µs.

Loss.  SDK 1 packets carry no sequence number, but the device stamps every packet
with its first firing's time and fires every Δt, so consecutive packets of one data
type are P = n·Δt apart (n firings per packet).  A gap g between the stamps of two
consecutive packets of one data type counts

    lost = round(g / P) − 1      when g > 1.5 P,   else 0

packets lost (livox_ros_driver ``lddc.cpp`` likewise takes a gap over 1.8 P as a
lost packet).  Only nanosecond stamps (types 0, 1, 4) are checked; a stamp that goes
back (the device resynchronised) restarts the check.  Lost packets at the very end
of a stream cannot be seen.

Sockets, threads, the bounded packet queue and the life cycle are those of
``livox_link.LivoxLink``: the heartbeat is its keep-alive, the handshake its connect
command.
"""

from __future__ import annotations

import struct
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Unpack

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError, DeviceError, InputError
from dronetrack.formats.livox import sdk1 as s1
from dronetrack.formats.livox.common import LivoxPoints
from dronetrack.sources.assembly import PointBatch
from dronetrack.sources.livox.link import LinkOptions, LivoxLink
from dronetrack.sources.livox.points import hits_in_time_order
from dronetrack.sources.livox.uri import parse_device_uri
from dronetrack.sources.udp import MAX_DATAGRAM
from dronetrack.sources.udp import POLL_S as POLL_S  # importable from here as before
from dronetrack.sources.udp import route_source_ip as route_source_ip

__all__ = ["LivoxClient", "LivoxEndpoint", "parse_livox_uri"]

# Host ports of the SDK's first LiDAR: 55000 + 500 + 1 and 55000 + 1000 + 1
# (device_discovery.h kCmdPortOffset, kDataPortOffset; IMU shares the data port).
HOST_CMD_PORT, HOST_DATA_PORT = 55501, 56001
ACK_WAIT_S = 0.5  # the SDK's command timeout (command_impl.h KDefaultTimeOut = 500 ms)
LINES = {2: 6, 3: 6, 7: 6}  # laser lines by device type (livox_ros_driver lds.h)
NS_STAMPS = (0, 1, 4)
PACKET_HEADER = struct.Struct("<B7xBBQ")  # version, timestamp type, data type, timestamp


@dataclass(frozen=True)
class LivoxEndpoint:
    """Where a Livox SDK 1 device and this host talk: the device's IP and command
    port, the host's IP (None: the address the host routes to the device from), the
    host's command and data ports (0: any free port) and the broadcast port."""

    device_ip: str
    host_ip: str | None = None
    cmd_port: int = HOST_CMD_PORT
    data_port: int = HOST_DATA_PORT
    broadcast_port: int = s1.BROADCAST_PORT
    device_port: int = s1.LIDAR_CMD_PORT


# query key → lowest port it takes (0: any free port)
_PORT_KEYS = {"cmd_port": 0, "data_port": 0, "broadcast_port": 0, "device_port": 1}


def parse_livox_uri(uri: str) -> LivoxEndpoint:
    """``livox://IP[?host=IP&cmd_port=N&data_port=N&broadcast_port=N&device_port=N]``;
    ConfigError naming the problem."""
    return LivoxEndpoint(**parse_device_uri(uri, "livox", "SDK 1", _PORT_KEYS))  # type: ignore[arg-type]


class LivoxClient(LivoxLink):
    """Host side of one Livox SDK 1 device: ``open``, then ``read`` (or ``packets`` and
    ``decode``) repeatedly, then ``close`` (or use it as a context manager).

    Options (``LinkOptions``) as LivoxLink says; the keep-alive is the heartbeat, its
    period and time-out 1 s and 3 s as the SDK's.

    Counters: ``packets_received``, ``packets_malformed`` (counted when decoded),
    ``packets_lost`` (from the timestamp gaps, see the module docstring),
    ``queue_dropped``, ``heartbeats_sent``, ``heartbeats_missed``.
    """

    sdk = "SDK 1 device"
    device_types = s1.DEVICE_TYPES
    connect_name = "handshake"
    keepalive_name = "heartbeat"
    ack_wait_s = ACK_WAIT_S

    def __init__(self, endpoint: LivoxEndpoint | str, **options: Unpack[LinkOptions]) -> None:
        self.endpoint = parse_livox_uri(endpoint) if isinstance(endpoint, str) else endpoint
        super().__init__(self.endpoint.device_ip, self.endpoint.host_ip, **options)
        self.broadcast_code: str | None = None
        self._last_stamp: dict[int, int] = {}

    # -- names and ports ------------------------------------------------------------

    @property
    def broadcast_port(self) -> int:
        return self._port("discovery")

    @property
    def data_port(self) -> int:
        return self._port("data")

    @property
    def point_interval_ns(self) -> int | None:
        """Δt between firings from the device type, if the broadcast gave one."""
        return s1.POINT_INTERVAL_NS.get(self.dev_type) if self.dev_type is not None else None

    def _interval_for(self, data_type: int) -> int:
        known = self.point_interval_ns
        if known is not None:
            return known
        return s1.POINT_INTERVAL_NS[1] if data_type in (0, 1) else s1.POINT_INTERVAL_NS[7]

    def _lines(self, data_type: int) -> int:
        if self.dev_type is not None:
            return LINES.get(self.dev_type, 1)
        return 1 if data_type in (0, 1) else 6  # Mid-40/70 types, else an Avia-like device

    # -- the protocol ---------------------------------------------------------------

    def _ports(self) -> tuple[int, int, int]:
        return self.endpoint.broadcast_port, self.endpoint.cmd_port, self.endpoint.data_port

    def _device_address(self) -> tuple[str, int]:
        return self.endpoint.device_ip, self.endpoint.device_port

    def _discover(self, until: float) -> None:
        sock = self._socks["discovery"]
        while time.monotonic() < until:
            try:
                buf, (ip, _) = sock.recvfrom(MAX_DATAGRAM)
            except TimeoutError:
                continue
            if ip != self.endpoint.device_ip:
                continue
            try:
                frame = s1.decode_frame(buf)
                if (frame.cmd_set, frame.cmd_id) != (s1.SET_GENERAL, s1.BROADCAST):
                    continue
                info = s1.Broadcast.decode(frame.payload)
            except (DecodeError, InputError):
                continue
            self.dev_type, self.broadcast_code = info.dev_type, info.code
            return

    def _encode_command(self, cmd_id: int, payload: bytes, seq: int, cmd_type: int | None) -> bytes:
        kind = s1.CMD if cmd_type is None else cmd_type
        return s1.encode_frame(s1.CommandFrame(kind, seq, s1.SET_GENERAL, cmd_id, payload))

    def _parse_reply(self, buf: bytes) -> tuple[bool, int, bytes] | None:
        frame = s1.decode_frame(buf)
        if frame.cmd_type != s1.ACK or frame.cmd_set != s1.SET_GENERAL:
            return None
        return frame.cmd_id == s1.HEARTBEAT, frame.seq, frame.payload

    def _connect_command(self) -> tuple[int, bytes, int | None]:
        # sent with cmd_type ACK, as the SDK sends it (device_discovery.cpp)
        assert self.host_ip is not None
        hs = s1.Handshake(self.host_ip, self.data_port, self.cmd_port, self.data_port)
        return s1.HANDSHAKE, hs.encode(), s1.ACK

    def _sampling_command(self, start: bool) -> tuple[int, bytes]:
        return s1.SAMPLING, s1.encode_sampling(start)

    def _goodbye_commands(self) -> list[tuple[int, bytes]]:
        return [(s1.DISCONNECT, b"")]

    def query_firmware(self, timeout_s: float = 1.0) -> str | None:
        """The firmware version the connected device reports (command 0x02), as
        "a.b.c.d"; None if it does not answer within ``timeout_s``."""
        if not self._connected:
            raise DeviceError(f"{self.name}: not connected (call connect or open)")
        ack = self._ask(s1.DEVICE_INFO, b"", time.monotonic() + timeout_s)
        if ack is None:
            return None
        try:
            info = s1.DeviceInfoAck.decode(ack)
        except DecodeError as exc:
            raise DeviceError(f"{self.name}: device information: {exc}") from exc
        if info.ret_code != 0:
            raise DeviceError(f"{self.name}: device information refused, ret_code {info.ret_code}")
        return info.version

    def _send_keepalive(self) -> None:
        self._send(s1.HEARTBEAT, b"")

    def _count_loss(self, buf: bytes) -> None:
        """lost += round(g / P) − 1 when the stamp gap g > 1.5 P, P = n·Δt."""
        if len(buf) < PACKET_HEADER.size:
            return
        version, kind, data_type, stamp = PACKET_HEADER.unpack_from(buf)
        n = s1.POINTS_PER_PACKET.get(data_type)
        if version != s1.PACKET_VERSION or kind not in NS_STAMPS or n is None:
            return
        if data_type == s1.IMU_DATA_TYPE:  # IMU samples come at their own rate
            return
        if len(buf) != s1.PACKET_BYTES[data_type]:
            return
        prev = self._last_stamp.get(data_type)
        self._last_stamp[data_type] = stamp
        if prev is None or stamp <= prev:
            return
        period = n * self._interval_for(data_type)
        gap = stamp - prev
        if 2 * gap > 3 * period:
            self.packets_lost += round(gap / period) - 1

    # -- decoding --------------------------------------------------------------------

    def decode(self, packets: Sequence[bytes]) -> PointBatch:
        """The points with a return in ``packets``, in time order, t_ns the device's
        int64 ns; malformed packets are skipped and counted in ``packets_malformed``.
        ``line`` is the firing's index in its packet modulo the device's laser lines
        (6 for Avia, Horizon, Tele; livox_ros_driver ``lds.cpp``), 0 otherwise.
        ``firings``: the first and last firing's times in the packets, with a return
        or not (None if no packet decoded)."""
        by_type: dict[int, list[bytes]] = {}
        for p in packets:
            by_type.setdefault(p[9] if len(p) > 9 else -1, []).append(p)
        parts: list[LivoxPoints] = []
        lines: list[NDArray[np.uint8]] = []
        for data_type, group in by_type.items():
            decoded, bad = s1.decode_packets(group, self._interval_for(data_type))
            self.packets_malformed += bad
            pts = decoded.points
            if len(pts) == 0:
                continue
            layout, n = s1.LAYOUTS[data_type], s1.POINTS_PER_PACKET[data_type]
            firing = np.arange(len(pts)) // layout.returns % n  # firing j within its packet
            parts.append(pts)
            lines.append((firing % self._lines(data_type)).astype(np.uint8))
        batch = hits_in_time_order(parts, lines)
        if not parts:
            return batch
        first = min(int(p.t_ns.min()) for p in parts)
        return replace(batch, firings=(first, max(int(p.t_ns.max()) for p in parts)))
