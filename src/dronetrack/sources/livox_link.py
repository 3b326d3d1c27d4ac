"""What the Livox SDK 1 and SDK 2 host clients share: the device URI, UDP sockets,
the command/ACK exchange with a keep-alive, the reader thread with its bounded packet
queue, the counters and the life cycle (``open``, ``read``, ``close``).

A client (``livox_udp.LivoxClient``, ``livox2_udp.Livox2Client``) is a ``LivoxLink``
that fills in its protocol: how to discover the device, the command that connects
the host (the SDK 1 handshake, the SDK 2 host-address configuration), the commands
that start and stop sampling, the keep-alive, the loss count and the decoding.

``open`` runs the same steps for both:

1. bind the sockets and find the host's address towards the device;
2. discover the device for up to ``discover_s`` (optional: without an answer the
   client goes on to the device's default command port);
3. start the control thread, which receives the command ACKs, sends the keep-alive
   every ``heartbeat_period_s`` and marks the link dead after
   ``heartbeat_timeout_s`` without an answer to it;
4. connect (the ACK's ret_code must be 0), start the reader thread, start sampling.

Threads: the control thread owns the command socket; the reader thread receives
point packets into a queue of at most ``max_packets`` (the oldest packet is dropped
and counted when the consumer falls behind).  Both wake at least every 50 ms to see
a stop request, so ``close`` joins them within a bounded time.
"""

from __future__ import annotations

import ipaddress
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from typing import Self, TypedDict
from urllib.parse import parse_qsl, urlsplit

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError, DecodeError, DeviceError
from dronetrack.formats.livox_common import LivoxPoints
from dronetrack.sources.assembly import PointBatch

__all__ = [
    "LinkOptions",
    "LivoxLink",
    "hits_in_time_order",
    "parse_device_uri",
    "route_source_ip",
    "udp_socket",
]

POLL_S = 0.05  # longest a thread blocks before it looks at the stop request
MAX_DATAGRAM = 2048  # the largest Livox datagram is 1400 bytes


def _ipv4(text: str, what: str, uri: str) -> str:
    try:
        return str(ipaddress.IPv4Address(text))
    except ValueError:
        raise ConfigError(f"{uri!r}: {what} {text!r} is not an IPv4 address") from None


def parse_device_uri(
    uri: str,
    scheme: str,
    sdk: str,
    port_keys: Mapping[str, int],
    choice_keys: Mapping[str, Mapping[str, object]] | None = None,
) -> dict[str, object]:
    """``SCHEME://IP[?host=IP&KEY=N…]`` as keyword fields: ``device_ip``, ``host_ip``
    if given, each port key given (an integer from its lowest value in ``port_keys``
    to 65535) and each choice key given (its text's value in ``choice_keys[key]``);
    ConfigError naming the problem."""
    choices = choice_keys or {}
    try:
        parts = urlsplit(uri)
    except ValueError as exc:
        raise ConfigError(f"{uri!r} is not a URI: {exc}") from None
    if parts.scheme != scheme:
        raise ConfigError(f"{uri!r}: a Livox {sdk} device is given as {scheme}://IP")
    if parts.path not in ("", "/") or parts.fragment:
        raise ConfigError(f"{uri!r}: {scheme}://IP takes no path or fragment")
    netloc = parts.netloc
    if not netloc:
        raise ConfigError(f"{uri!r}: no device IP after {scheme}://")
    if "@" in netloc or ":" in netloc:
        raise ConfigError(
            f"{uri!r}: give only the device's IPv4 address after {scheme}:// "
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
        elif key in port_keys:
            low = port_keys[key]
            if not value.isdigit() or not low <= int(value) <= 65535:
                raise ConfigError(f"{uri!r}: {key}={value!r} is not a port in {low}..65535")
            fields[key] = int(value)
        elif key in choices:
            if value not in choices[key]:
                allowed = ", ".join(choices[key])
                raise ConfigError(f"{uri!r}: {key}={value!r} is not one of {allowed}")
            fields[key] = choices[key][value]
        else:
            known = ", ".join(("host", *port_keys, *choices))
            raise ConfigError(f"{uri!r}: unknown query key {key!r} (known: {known})")
    return fields


def udp_socket(port: int, what: str, rcvbuf: int = 0) -> socket.socket:
    """A UDP socket bound to ``port`` on all interfaces (as the SDKs bind), polling."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        if rcvbuf:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        sock.bind(("0.0.0.0", port))
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


def hits_in_time_order(
    parts: Sequence[LivoxPoints], lines: Sequence[NDArray[np.uint8]]
) -> PointBatch:
    """The points with a return of ``parts`` (with their ``lines``), sorted by time."""
    if not parts:
        u8 = np.zeros(0, np.uint8)
        return PointBatch(np.zeros((0, 3)), np.zeros(0, np.int64), u8, u8)
    pts = LivoxPoints.concat(parts)
    line = np.concatenate(lines)
    hit = pts.hit
    order = np.argsort(pts.t_ns[hit], kind="stable")
    return PointBatch(
        pts.points[hit][order], pts.t_ns[hit][order], pts.reflectivity[hit][order], line[hit][order]
    )


class LinkOptions(TypedDict, total=False):
    """The keyword options of every Livox client (see LivoxLink)."""

    max_packets: int
    heartbeat_period_s: float
    heartbeat_timeout_s: float
    stall_s: float
    discover_s: float


class LivoxLink:
    """The protocol-independent part of a Livox host client (see the module docstring).

    ``max_packets``: the queue bound between the reader thread and the consumer
    (5000 packets: 2 s of an Avia, 2.4 s of a Mid-360).  ``heartbeat_period_s`` /
    ``heartbeat_timeout_s``: the keep-alive and how long without an answer the link
    counts as dead (1 s and 3 s, as the SDK 1 heartbeat).  ``stall_s``: how long
    without a point packet after sampling started counts as a failure.
    ``discover_s``: how long ``open`` looks for the device before it connects anyway.

    Counters: ``packets_received``, ``packets_malformed`` (counted when decoded),
    ``packets_lost`` (by the protocol's rule), ``queue_dropped``, ``heartbeats_sent``
    and ``heartbeats_missed`` (keep-alives without an answer before the next one).

    A subclass sets ``sdk`` (names the device before discovery), ``connect_name``,
    ``keepalive_name``, ``ack_wait_s`` and ``seq_modulus``, and implements the hooks
    below the ``# -- protocol`` line.
    """

    sdk = "device"
    device_types: Mapping[int, str] = {}  # device type → model name
    connect_name = "connect"
    keepalive_name = "keep-alive"
    ack_wait_s = 0.5  # one try of a command
    seq_modulus = 0xFFFF  # seq runs 1 … seq_modulus and wraps to 1

    def __init__(
        self,
        device_ip: str,
        host_ip: str | None,
        *,
        max_packets: int = 5000,
        heartbeat_period_s: float = 1.0,
        heartbeat_timeout_s: float = 3.0,
        stall_s: float = 1.0,
        discover_s: float = 1.0,
    ) -> None:
        if max_packets < 1:
            raise ConfigError(f"the packet queue needs room for 1 packet, got {max_packets}")
        if not 0 < heartbeat_period_s < heartbeat_timeout_s:
            raise ConfigError(
                f"the {self.keepalive_name} period {heartbeat_period_s} s must be positive and "
                f"below its timeout {heartbeat_timeout_s} s"
            )
        self.device_ip = device_ip
        self.max_packets = max_packets
        self.heartbeat_period_s = heartbeat_period_s
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self.stall_s = stall_s
        self.discover_s = discover_s
        self.host_ip: str | None = host_ip
        self.dev_type: int | None = None  # from discovery
        self.packets_received = 0
        self.packets_malformed = 0
        self.packets_lost = 0
        self.queue_dropped = 0
        self.heartbeats_sent = 0
        self.heartbeats_missed = 0
        self._socks: dict[str, socket.socket] = {}
        self._queue: deque[bytes] = deque()
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)
        self._acks: dict[int, bytes] = {}
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
        self._closed = False

    # -- protocol: hooks of a subclass ------------------------------------------------

    @property
    def name(self) -> str:
        """The model once discovery named it, else the SDK, and the IP."""
        kind = self.device_types.get(self.dev_type, "") if self.dev_type is not None else ""
        return f"Livox {kind or self.sdk} at {self.device_ip}"

    def _ports(self) -> tuple[int, int, int]:
        """The host's discovery, command and point-data ports (0: any free port)."""
        raise NotImplementedError

    def _device_address(self) -> tuple[str, int]:
        """Where commands go."""
        raise NotImplementedError

    def _discover(self, until: float) -> None:
        raise NotImplementedError

    def _encode_command(self, cmd_id: int, payload: bytes, seq: int, cmd_type: int | None) -> bytes:
        raise NotImplementedError

    def _parse_reply(self, buf: bytes) -> tuple[bool, int, bytes] | None:
        """(answers the keep-alive, seq, ACK payload) of a datagram on the command
        socket, or None to ignore it."""
        raise NotImplementedError

    def _ret_code(self, payload: bytes) -> int | None:
        return payload[0] if payload else None

    def _connect_command(self) -> tuple[int, bytes, int | None]:
        """(cmd_id, payload, cmd_type or None for the usual request) that connects."""
        raise NotImplementedError

    def _sampling_command(self, start: bool) -> tuple[int, bytes]:
        raise NotImplementedError

    def _goodbye_commands(self) -> list[tuple[int, bytes]]:
        """Commands sent at ``close`` after stopping the sampling."""
        return []

    def _send_keepalive(self) -> None:
        raise NotImplementedError

    def _count_loss(self, buf: bytes) -> None:
        raise NotImplementedError

    def decode(self, packets: Sequence[bytes]) -> PointBatch:
        raise NotImplementedError

    # -- sockets ---------------------------------------------------------------------

    def _port(self, slot: str) -> int:
        sock = self._socks.get(slot)
        if sock is None:
            raise DeviceError(f"{self.name}: the client's sockets are not bound (call bind)")
        return int(sock.getsockname()[1])

    @property
    def cmd_port(self) -> int:
        return self._port("cmd")

    def bind(self) -> None:
        """Bind the sockets (``open`` does it if needed); with port 0 the kernel picks a
        free port, readable afterwards."""
        if self._closed:
            raise DeviceError(f"{self.name}: the client is closed")
        if self._socks:
            return
        discovery, cmd, data = self._ports()
        try:
            self._socks["discovery"] = udp_socket(discovery, "discovery")
            self._socks["cmd"] = udp_socket(cmd, "commands")
            self._socks["data"] = udp_socket(data, "point data", rcvbuf=4 << 20)
        except DeviceError:
            self._close_sockets()
            raise

    # -- opening ---------------------------------------------------------------------

    def open(self, timeout_s: float = 3.0) -> None:
        """Discover (optionally), connect, start the keep-alive and start sampling;
        DeviceError naming the device if it does not answer within ``timeout_s``."""
        if self._sampling_since is not None:
            return
        deadline = time.monotonic() + timeout_s
        try:
            if not self._connected:
                self._connect(deadline, timeout_s)
            self._start_thread(self._read_loop, "livox-reader")
            ret = self._request(*self._sampling_command(True), deadline)
            if ret != 0:
                what = "no ACK" if ret is None else f"ret_code {ret}"
                raise DeviceError(f"{self.name}: start sampling failed ({what})")
            with self._lock:
                self._sampling_since = time.monotonic()
        except BaseException:
            self.close()
            raise

    def connect(self, timeout_s: float = 3.0) -> None:
        """Discover (optionally) and connect, with the keep-alive running, but do not
        start sampling (``dronetrack info``: what the device says of itself)."""
        if self._connected:
            return
        try:
            self._connect(time.monotonic() + timeout_s, timeout_s)
        except BaseException:
            self.close()
            raise

    def _connect(self, deadline: float, timeout_s: float) -> None:
        """Steps 1-3 of ``open`` and the connect command; DeviceError if refused or
        unanswered by ``deadline``."""
        self.bind()
        if self.host_ip is None:
            self.host_ip = route_source_ip(*self._device_address())
        self._discover(min(deadline, time.monotonic() + self.discover_s))
        self._start_thread(self._control_loop, "livox-control")
        cmd_id, payload, cmd_type = self._connect_command()
        ret = self._request(cmd_id, payload, deadline, cmd_type)
        if ret is None:
            raise DeviceError(f"{self.name}: no {self.connect_name} ACK within {timeout_s} s")
        if ret != 0:
            raise DeviceError(f"{self.name}: {self.connect_name} refused with ret_code {ret}")
        self._last_hb_ack = time.monotonic()
        self._connected = True

    def _start_thread(self, target: Callable[[], None], name: str) -> None:
        thread = threading.Thread(target=target, name=name, daemon=True)
        self._threads.append(thread)
        thread.start()

    # -- commands --------------------------------------------------------------------

    def _send(self, cmd_id: int, payload: bytes, cmd_type: int | None = None) -> int:
        with self._seq_lock:
            self._seq = self._seq % self.seq_modulus + 1
            seq = self._seq
        frame = self._encode_command(cmd_id, payload, seq, cmd_type)
        sock = self._socks.get("cmd")
        if sock is None:
            raise DeviceError(f"{self.name}: the command socket is closed")
        try:
            sock.sendto(frame, self._device_address())
        except OSError as exc:
            raise DeviceError(f"{self.name}: cannot send a command: {exc}") from exc
        return seq

    def _request(
        self, cmd_id: int, payload: bytes, deadline: float, cmd_type: int | None = None
    ) -> int | None:
        """Send the command until its ACK comes (each try waits ``ack_wait_s``) or
        ``deadline`` passes; the ACK's ret_code, or None without an ACK."""
        ack = self._ask(cmd_id, payload, deadline, cmd_type)
        return None if ack is None else self._ret_code(ack)

    def _ask(
        self, cmd_id: int, payload: bytes, deadline: float, cmd_type: int | None = None
    ) -> bytes | None:
        """As ``_request``, but the ACK's whole payload (None without an ACK)."""
        while True:
            seq = self._send(cmd_id, payload, cmd_type)
            try_until = min(deadline, time.monotonic() + self.ack_wait_s)
            with self._acked:
                while seq not in self._acks and time.monotonic() < try_until:
                    self._acked.wait(max(try_until - time.monotonic(), 0.0))
                ack = self._acks.pop(seq, None)
            if ack is not None:
                return ack
            if time.monotonic() >= deadline or self._dead:
                return None

    def _keepalive_answered(self) -> None:
        self._last_hb_ack = time.monotonic()
        self._hb_pending = False

    def _control_loop(self) -> None:
        """Receive ACKs; send the keep-alive every period and watch its answers."""
        sock = self._socks["cmd"]
        next_beat = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            if self._connected and self._dead is None:
                if now - self._last_hb_ack > self.heartbeat_timeout_s:
                    self._dead = f"no {self.keepalive_name} ACK for {self.heartbeat_timeout_s:g} s"
                elif now >= next_beat:
                    if self._hb_pending:
                        self.heartbeats_missed += 1
                    try:
                        self._send_keepalive()
                        self.heartbeats_sent += 1
                        self._hb_pending = True
                    except DeviceError:
                        pass  # a send error shows up as missing answers
                    next_beat = now + self.heartbeat_period_s
            try:
                buf = sock.recv(MAX_DATAGRAM)
            except TimeoutError:
                continue
            except OSError:
                return  # socket closed under us
            try:
                reply = self._parse_reply(buf)
            except DecodeError:
                continue
            if reply is None:
                continue
            keepalive, seq, payload = reply
            if keepalive:
                self._keepalive_answered()
                continue
            with self._acked:
                self._acks[seq] = payload
                while len(self._acks) > 64:  # ACKs nobody waits for any more
                    self._acks.pop(next(iter(self._acks)))
                self._acked.notify_all()

    # -- point data -----------------------------------------------------------------

    def _read_loop(self) -> None:
        sock = self._socks["data"]
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

    def read(self, timeout_s: float = 0.1) -> PointBatch:
        """``decode(packets(timeout_s))``."""
        return self.decode(self.packets(timeout_s))

    # -- closing --------------------------------------------------------------------

    def close(self) -> None:
        """Stop sampling, say goodbye, stop the threads and close the sockets; safe to
        call more than once."""
        if self._closed:
            return
        self._closed = True
        if self._connected and "cmd" in self._socks:
            wait = 0.0 if self._dead else self.ack_wait_s
            for cmd_id, payload in [self._sampling_command(False), *self._goodbye_commands()]:
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
        for sock in self._socks.values():
            sock.close()
        self._socks.clear()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
