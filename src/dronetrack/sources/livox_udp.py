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

Threads: a control thread receives the command ACKs, sends the heartbeat and
watches its ACKs (it is the heartbeat thread: one thread owns the command socket);
a reader thread receives point packets into a
bounded queue (the oldest packet is dropped and counted when the consumer falls
behind).  Both wake at least every 50 ms to see a stop request, so ``close`` joins
them within a bounded time.
"""

from __future__ import annotations

import ipaddress
import socket
import struct
import threading
import time
from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from types import TracebackType
from urllib.parse import parse_qsl, urlsplit

import numpy as np

from dronetrack.errors import ConfigError, DecodeError, DeviceError, InputError
from dronetrack.formats import livox_sdk1 as s1
from dronetrack.formats.livox_common import LivoxPoints
from dronetrack.sources.assembly import PointBatch

__all__ = ["LivoxClient", "LivoxEndpoint", "parse_livox_uri"]

# Host ports of the SDK's first LiDAR: 55000 + 500 + 1 and 55000 + 1000 + 1
# (device_discovery.h kCmdPortOffset, kDataPortOffset; IMU shares the data port).
HOST_CMD_PORT, HOST_DATA_PORT = 55501, 56001
ACK_WAIT_S = 0.5  # the SDK's command timeout (command_impl.h KDefaultTimeOut = 500 ms)
POLL_S = 0.05  # longest a thread blocks before it looks at the stop request
LINES = {2: 6, 3: 6, 7: 6}  # laser lines by device type (livox_ros_driver lds.h)
NS_STAMPS = (0, 1, 4)
MAX_DATAGRAM = 2048  # a point packet is at most 1362 bytes
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


_PORT_KEYS = ("cmd_port", "data_port", "broadcast_port", "device_port")


def _ipv4(text: str, what: str, uri: str) -> str:
    try:
        return str(ipaddress.IPv4Address(text))
    except ValueError:
        raise ConfigError(f"{uri!r}: {what} {text!r} is not an IPv4 address") from None


def parse_livox_uri(uri: str) -> LivoxEndpoint:
    """``livox://IP[?host=IP&cmd_port=N&data_port=N&broadcast_port=N&device_port=N]``;
    ConfigError naming the problem."""
    try:
        parts = urlsplit(uri)
    except ValueError as exc:
        raise ConfigError(f"{uri!r} is not a URI: {exc}") from None
    if parts.scheme != "livox":
        raise ConfigError(f"{uri!r}: a Livox SDK 1 device is given as livox://IP")
    if parts.path not in ("", "/") or parts.fragment:
        raise ConfigError(f"{uri!r}: livox://IP takes no path or fragment")
    netloc = parts.netloc
    if not netloc:
        raise ConfigError(f"{uri!r}: no device IP after livox://")
    if "@" in netloc or ":" in netloc:
        raise ConfigError(
            f"{uri!r}: give only the device's IPv4 address after livox:// "
            "(its command port is the query key device_port)"
        )
    fields: dict[str, object] = {"device_ip": _ipv4(netloc, "device IP", uri)}
    try:
        pairs = parse_qsl(parts.query, keep_blank_values=True, strict_parsing=bool(parts.query))
    except ValueError:
        raise ConfigError(f"{uri!r}: the query is not key=value pairs joined by &") from None
    for key, value in pairs:
        if key in fields or (key == "host" and "host_ip" in fields):
            raise ConfigError(f"{uri!r}: query key {key!r} is given twice")
        if key == "host":
            fields["host_ip"] = _ipv4(value, "host", uri)
        elif key in _PORT_KEYS:
            low = 1 if key == "device_port" else 0
            if not value.isdigit() or not low <= int(value) <= 65535:
                raise ConfigError(f"{uri!r}: {key}={value!r} is not a port in {low}..65535")
            fields[key] = int(value)
        else:
            known = ", ".join(("host", *_PORT_KEYS))
            raise ConfigError(f"{uri!r}: unknown query key {key!r} (known: {known})")
    return LivoxEndpoint(**fields)  # type: ignore[arg-type]


def _udp_socket(port: int, what: str, rcvbuf: int = 0) -> socket.socket:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if rcvbuf:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        sock.bind(("0.0.0.0", port))  # all interfaces, as the SDK binds (INADDR_ANY)
    except OSError as exc:
        sock.close()
        raise DeviceError(f"cannot bind UDP port {port} for Livox {what}: {exc}") from exc
    sock.settimeout(POLL_S)
    return sock


def route_source_ip(device_ip: str, device_port: int) -> str:
    """The local address the host sends to ``device_ip`` from (a connected UDP socket
    sends nothing; the kernel only picks the route)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
        try:
            probe.connect((device_ip, device_port))
        except OSError as exc:
            raise DeviceError(
                f"Livox device at {device_ip}: no route from this host: {exc}"
            ) from exc
        return str(probe.getsockname()[0])


class LivoxClient:
    """Host side of one Livox SDK 1 device: ``open``, then ``read`` (or ``packets`` and
    ``decode``) repeatedly, then ``close`` (or use it as a context manager).

    ``max_packets``: the queue bound between the reader thread and the consumer
    (5000 packets: 2 s of an Avia).  ``heartbeat_period_s`` / ``heartbeat_timeout_s``:
    the heartbeat and how long without its ACK the link counts as dead (1 s and 3 s,
    as the SDK).  ``stall_s``: how long without a point packet after sampling
    started counts as a failure.  ``discover_s``: how long ``open`` waits for the
    device's broadcast before it sends the handshake anyway.

    Counters: ``packets_received``, ``packets_malformed`` (counted when decoded),
    ``packets_lost`` (from the timestamp gaps, see the module docstring),
    ``queue_dropped``, ``heartbeats_sent``, ``heartbeats_missed``.
    """

    def __init__(
        self,
        endpoint: LivoxEndpoint | str,
        *,
        max_packets: int = 5000,
        heartbeat_period_s: float = 1.0,
        heartbeat_timeout_s: float = 3.0,
        stall_s: float = 1.0,
        discover_s: float = 1.0,
    ) -> None:
        self.endpoint = parse_livox_uri(endpoint) if isinstance(endpoint, str) else endpoint
        if max_packets < 1:
            raise ConfigError(f"the packet queue needs room for 1 packet, got {max_packets}")
        if not 0 < heartbeat_period_s < heartbeat_timeout_s:
            raise ConfigError(
                f"the heartbeat period {heartbeat_period_s} s must be positive and below "
                f"its timeout {heartbeat_timeout_s} s"
            )
        self.max_packets = max_packets
        self.heartbeat_period_s = heartbeat_period_s
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.stall_s = stall_s
        self.discover_s = discover_s
        self.dev_type: int | None = None
        self.broadcast_code: str | None = None
        self.host_ip: str | None = None
        self.packets_received = 0
        self.packets_malformed = 0
        self.packets_lost = 0
        self.queue_dropped = 0
        self.heartbeats_sent = 0
        self.heartbeats_missed = 0
        self._broadcast_sock: socket.socket | None = None
        self._cmd_sock: socket.socket | None = None
        self._data_sock: socket.socket | None = None
        self._queue: deque[bytes] = deque()
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)
        self._acks: dict[int, s1.CommandFrame] = {}
        self._acked = threading.Condition(threading.Lock())
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._seq = 0
        self._seq_lock = threading.Lock()
        self._connected = False
        self._sampling_since: float | None = None
        self._last_packet = 0.0
        self._last_hb_ack = 0.0
        self._hb_pending = False
        self._dead: str | None = None
        self._last_stamp: dict[int, int] = {}
        self._closed = False

    # -- names and ports ------------------------------------------------------------

    @property
    def name(self) -> str:
        kind = s1.DEVICE_TYPES.get(self.dev_type, "SDK 1 device") if self.dev_type else ""
        return f"Livox {kind or 'SDK 1 device'} at {self.endpoint.device_ip}"

    def _port(self, sock: socket.socket | None) -> int:
        if sock is None:
            raise DeviceError(f"{self.name}: the client's sockets are not bound (call bind)")
        return int(sock.getsockname()[1])

    @property
    def broadcast_port(self) -> int:
        return self._port(self._broadcast_sock)

    @property
    def cmd_port(self) -> int:
        return self._port(self._cmd_sock)

    @property
    def data_port(self) -> int:
        return self._port(self._data_sock)

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

    # -- opening ---------------------------------------------------------------------

    def bind(self) -> None:
        """Bind the broadcast, command and data sockets (``open`` does it if needed);
        with port 0 the kernel picks a free port, readable afterwards."""
        if self._closed:
            raise DeviceError(f"{self.name}: the client is closed")
        if self._cmd_sock is not None:
            return
        ep = self.endpoint
        try:
            self._broadcast_sock = _udp_socket(ep.broadcast_port, "broadcasts")
            self._cmd_sock = _udp_socket(ep.cmd_port, "commands")
            self._data_sock = _udp_socket(ep.data_port, "point data", rcvbuf=4 << 20)
        except DeviceError:
            self._close_sockets()
            raise

    def open(self, timeout_s: float = 3.0) -> None:
        """Discover (optionally), hand-shake, start the heartbeat and start sampling;
        DeviceError naming the device if it does not answer within ``timeout_s``."""
        if self._sampling_since is not None:
            return
        deadline = time.monotonic() + timeout_s
        try:
            self.bind()
            ep = self.endpoint
            self.host_ip = ep.host_ip or route_source_ip(ep.device_ip, ep.device_port)
            self._discover(min(deadline, time.monotonic() + self.discover_s))
            self._start_thread(self._control_loop, "livox-control")
            handshake = s1.Handshake(self.host_ip, self.data_port, self.cmd_port, self.data_port)
            ret = self._request(s1.HANDSHAKE, handshake.encode(), deadline, cmd_type=s1.ACK)
            if ret is None:
                raise DeviceError(f"{self.name}: no handshake ACK within {timeout_s} s")
            if ret != 0:
                raise DeviceError(f"{self.name}: handshake refused with ret_code {ret}")
            self._last_hb_ack = time.monotonic()
            self._connected = True
            self._start_thread(self._read_loop, "livox-reader")
            ret = self._request(s1.SAMPLING, s1.encode_sampling(True), deadline)
            if ret != 0:
                what = "no ACK" if ret is None else f"ret_code {ret}"
                raise DeviceError(f"{self.name}: start sampling failed ({what})")
            with self._lock:
                self._sampling_since = time.monotonic()
        except BaseException:
            self.close()
            raise

    def _discover(self, until: float) -> None:
        sock = self._broadcast_sock
        assert sock is not None
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

    def _start_thread(self, target: Callable[[], None], name: str) -> None:
        thread = threading.Thread(target=target, name=name, daemon=True)
        self._threads.append(thread)
        thread.start()

    # -- commands --------------------------------------------------------------------

    def _next_seq(self) -> int:
        # seq runs 1 … 0xFFFF and wraps to 1 (command_channel.cpp GenerateSeq)
        self._seq = self._seq % 0xFFFF + 1
        return self._seq

    def _send(self, cmd_id: int, payload: bytes, cmd_type: int = s1.CMD) -> int:
        with self._seq_lock:
            seq = self._next_seq()
        frame = s1.encode_frame(s1.CommandFrame(cmd_type, seq, s1.SET_GENERAL, cmd_id, payload))
        sock = self._cmd_sock
        if sock is None:
            raise DeviceError(f"{self.name}: the command socket is closed")
        try:
            sock.sendto(frame, (self.endpoint.device_ip, self.endpoint.device_port))
        except OSError as exc:
            raise DeviceError(f"{self.name}: cannot send a command: {exc}") from exc
        return seq

    def _request(
        self, cmd_id: int, payload: bytes, deadline: float, cmd_type: int = s1.CMD
    ) -> int | None:
        """Send the command until its ACK comes (each try waits 0.5 s) or ``deadline``
        passes; the ACK's ret_code, or None without an ACK."""
        while True:
            seq = self._send(cmd_id, payload, cmd_type)
            try_until = min(deadline, time.monotonic() + ACK_WAIT_S)
            with self._acked:
                while seq not in self._acks and time.monotonic() < try_until:
                    self._acked.wait(max(try_until - time.monotonic(), 0.0))
                ack = self._acks.pop(seq, None)
            if ack is not None:
                try:
                    return s1.decode_ret_code(ack.payload[:1])
                except DecodeError:
                    return None
            if time.monotonic() >= deadline or self._dead:
                return None

    def _control_loop(self) -> None:
        """Receive ACKs; send the heartbeat every period and watch its ACKs."""
        sock = self._cmd_sock
        assert sock is not None
        next_beat = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            if self._connected and self._dead is None:
                if now - self._last_hb_ack > self.heartbeat_timeout_s:
                    self._dead = f"no heartbeat ACK for {self.heartbeat_timeout_s:g} s"
                elif now >= next_beat:
                    if self._hb_pending:
                        self.heartbeats_missed += 1
                    try:
                        self._send(s1.HEARTBEAT, b"")
                        self.heartbeats_sent += 1
                        self._hb_pending = True
                    except DeviceError:
                        pass  # a send error shows up as missing ACKs
                    next_beat = now + self.heartbeat_period_s
            try:
                buf = sock.recv(MAX_DATAGRAM)
            except TimeoutError:
                continue
            except OSError:
                return  # socket closed under us
            try:
                frame = s1.decode_frame(buf)
            except DecodeError:
                continue
            if frame.cmd_type != s1.ACK or frame.cmd_set != s1.SET_GENERAL:
                continue
            if frame.cmd_id == s1.HEARTBEAT:
                self._last_hb_ack = time.monotonic()
                self._hb_pending = False
                continue
            with self._acked:
                self._acks[frame.seq] = frame
                while len(self._acks) > 64:  # ACKs nobody waits for any more
                    self._acks.pop(next(iter(self._acks)))
                self._acked.notify_all()

    # -- point data -----------------------------------------------------------------

    def _read_loop(self) -> None:
        sock = self._data_sock
        assert sock is not None
        while not self._stop.is_set():
            try:
                buf = sock.recv(MAX_DATAGRAM)
            except TimeoutError:
                continue
            except OSError:
                return
            self._count_loss(buf)
            with self._lock:
                self.packets_received += 1
                self._last_packet = time.monotonic()
                if len(self._queue) >= self.max_packets:
                    self._queue.popleft()
                    self.queue_dropped += 1
                self._queue.append(buf)
                self._arrived.notify()

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

    def _check(self) -> None:
        if self._dead is not None:
            raise DeviceError(f"{self.name}: {self._dead}")
        since = self._sampling_since
        if since is not None and not self._queue:
            quiet = time.monotonic() - max(since, self._last_packet)
            if quiet > self.stall_s:
                raise DeviceError(f"{self.name}: no point packet for {quiet:.1f} s")

    def packets(self, timeout_s: float = 0.1) -> list[bytes]:
        """The raw packets received so far (waiting up to ``timeout_s`` for the first);
        DeviceError if the link is dead or no packet came for ``stall_s``."""
        if self._sampling_since is None:
            raise DeviceError(f"{self.name}: not sampling (call open)")
        if self._dead is not None:
            raise DeviceError(f"{self.name}: {self._dead}")
        until = time.monotonic() + timeout_s
        with self._lock:
            while not self._queue:
                self._check()
                left = until - time.monotonic()
                if left <= 0:
                    return []
                self._arrived.wait(min(left, POLL_S))
            out = list(self._queue)
            self._queue.clear()
        return out

    def decode(self, packets: Sequence[bytes]) -> PointBatch:
        """The points with a return in ``packets``, in time order, t_ns the device's
        int64 ns; malformed packets are skipped and counted in ``packets_malformed``.
        ``line`` is the firing's index in its packet modulo the device's laser lines
        (6 for Avia, Horizon, Tele; livox_ros_driver ``lds.cpp``), 0 otherwise."""
        by_type: dict[int, list[bytes]] = {}
        for p in packets:
            by_type.setdefault(p[9] if len(p) > 9 else -1, []).append(p)
        parts: list[LivoxPoints] = []
        lines: list[np.ndarray] = []
        for data_type, group in by_type.items():
            decoded, bad = s1.decode_packets(group, self._interval_for(data_type))
            self.packets_malformed += bad
            pts = decoded.points
            if len(pts) == 0:
                continue
            layout, n = s1.LAYOUTS[data_type], s1.POINTS_PER_PACKET[data_type]
            firing = np.arange(len(pts)) // layout.returns % n  # firing j within its packet
            line = (firing % self._lines(data_type)).astype(np.uint8)
            parts.append(pts)
            lines.append(line)
        if not parts:
            return _empty_batch()
        pts = LivoxPoints.concat(parts)
        line = np.concatenate(lines)
        hit = pts.hit
        order = np.argsort(pts.t_ns[hit], kind="stable")
        return PointBatch(
            pts.points[hit][order],
            pts.t_ns[hit][order],
            pts.reflectivity[hit][order],
            line[hit][order],
        )

    def read(self, timeout_s: float = 0.1) -> PointBatch:
        """``decode(packets(timeout_s))``."""
        return self.decode(self.packets(timeout_s))

    # -- closing --------------------------------------------------------------------

    def close(self) -> None:
        """Stop sampling, disconnect, stop the threads and close the sockets; safe to
        call more than once."""
        if self._closed:
            return
        self._closed = True
        if self._connected and self._cmd_sock is not None:
            wait = 0.0 if self._dead else ACK_WAIT_S
            for cmd_id, payload in ((s1.SAMPLING, s1.encode_sampling(False)), (s1.DISCONNECT, b"")):
                try:
                    self._request(cmd_id, payload, time.monotonic() + wait)
                except DeviceError:
                    break
        self._connected = False
        self._sampling_since = None
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=1.0)
        self._close_sockets()

    def _close_sockets(self) -> None:
        for sock in (self._broadcast_sock, self._cmd_sock, self._data_sock):
            if sock is not None:
                sock.close()
        self._broadcast_sock = self._cmd_sock = self._data_sock = None

    def __enter__(self) -> LivoxClient:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


def _empty_batch() -> PointBatch:
    u8 = np.zeros(0, np.uint8)
    return PointBatch(np.zeros((0, 3)), np.zeros(0, np.int64), u8, u8)
