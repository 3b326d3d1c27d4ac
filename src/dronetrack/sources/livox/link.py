"""What the Livox SDK 1 and SDK 2 host clients share: the sockets, the reader thread
with its bounded packet queue, the counters and the life cycle (``open``, ``read``,
``close``), on top of the command/ACK exchange and keep-alive of ``livox_commands``.

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
point packets into a queue of at most ``max_packets`` (``livox_queues.PacketQueue``:
the oldest packet is dropped and counted when the consumer falls behind).  Both wake
at least every 50 ms to see a stop request, so ``close`` joins them within a bounded
time.

The parts live in modules of their own: the device URI (``livox_uri``), the sockets
(``livox_net``), the queues between the threads (``livox_queues``), the keep-alive's
clock (``livox_keepalive``), the commands (``livox_commands``) and the decoded
points' order (``livox_points``).
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Sequence
from typing import Self, TypedDict

from dronetrack.errors import ConfigError, DeviceError
from dronetrack.sources.assembly import PointBatch
from dronetrack.sources.livox.commands import LivoxCommands
from dronetrack.sources.queues import PacketQueue
from dronetrack.sources.udp import (
    MAX_DATAGRAM,
    is_local_address,
    route_source_ip,
    udp_socket,
)

__all__ = ["LinkOptions", "LivoxLink"]


class LinkOptions(TypedDict, total=False):
    """The keyword options of every Livox client (see LivoxLink)."""

    max_packets: int
    heartbeat_period_s: float
    heartbeat_timeout_s: float
    stall_s: float
    discover_s: float


class LivoxLink(LivoxCommands):
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

    A subclass sets what ``LivoxCommands`` asks for and ``connect_name``, and
    implements the hooks below the ``# -- protocol`` lines of both classes.
    """

    connect_name = "connect"
    data_key = "data_port"  # the URI key of the host's point-data port

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
        super().__init__(device_ip, heartbeat_period_s, heartbeat_timeout_s)
        self.max_packets = max_packets
        self.stall_s = stall_s
        self.discover_s = discover_s
        self.host_ip: str | None = host_ip
        self._host_given = host_ip is not None  # by the user, not routed
        self.packets_malformed = 0
        self.packets_lost = 0
        self._packets = PacketQueue(max_packets)
        self._threads: list[threading.Thread] = []
        self._sampling_since: float | None = None
        self._closed = False

    @property
    def packets_received(self) -> int:
        return self._packets.received

    @property
    def queue_dropped(self) -> int:
        return self._packets.dropped

    # -- protocol: hooks of a subclass ------------------------------------------------

    def _ports(self) -> tuple[int, int, int]:
        """The host's discovery, command and point-data ports (0: any free port)."""
        raise NotImplementedError

    def _discover(self, until: float) -> None:
        raise NotImplementedError

    def _connect_command(self) -> tuple[int, bytes, int | None]:
        """(cmd_id, payload, cmd_type or None for the usual request) that connects."""
        raise NotImplementedError

    def _sampling_command(self, start: bool) -> tuple[int, bytes]:
        raise NotImplementedError

    def _goodbye_commands(self) -> list[tuple[int, bytes]]:
        """Commands sent at ``close`` after stopping the sampling."""
        return []

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
        free port, readable afterwards.  DeviceError naming a port another process
        holds: the command and point-data ports are this client's alone
        (``livox_net``)."""
        if self._closed:
            raise DeviceError(f"{self.name}: the client is closed")
        if self._socks:
            return
        discovery, cmd, data = self._ports()
        try:
            # the ports one client holds first (livox_net): a client refused there has
            # not touched the shared discovery port
            self._socks["cmd"] = udp_socket(cmd, "commands", key="cmd_port")
            self._socks["data"] = udp_socket(data, "point data", 4 << 20, key=self.data_key)
            self._socks["discovery"] = udp_socket(discovery, "discovery", shared=True)
        except DeviceError as exc:
            self._close_sockets()
            raise DeviceError(f"{self.name}: {exc}") from exc

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
        self._beat.answered(time.monotonic())
        self._connected = True

    def _start_thread(self, target: Callable[[], None], name: str) -> None:
        thread = threading.Thread(target=target, name=name, daemon=True)
        self._threads.append(thread)
        thread.start()

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
            self._packets.put(buf)

    def _check(self) -> None:
        if self._dead is not None:
            raise DeviceError(f"{self.name}: {self._dead}")
        since = self._sampling_since
        if since is not None and self._packets.empty():
            quiet = time.monotonic() - max(since, self._packets.last_arrival)
            if quiet > self.stall_s:
                hint = self._host_hint() if self._packets.received == 0 else ""
                raise DeviceError(f"{self.name}: no point packet for {quiet:.1f} s{hint}")

    def _host_hint(self) -> str:
        """Why no point packet came at all, when the host address the device sends to
        was given (``--host-ip``, the URI's ``host=``) rather than routed: it names the
        address and whether this host has it and routes to the device from it."""
        if not self._host_given or self.host_ip is None:
            return ""
        detail = ""
        if not is_local_address(self.host_ip):
            detail = ", not an address of this host"
        else:
            with contextlib.suppress(DeviceError):
                routed = route_source_ip(*self._device_address())
                if routed != self.host_ip:
                    detail = f" (this host reaches {self.device_ip} from {routed})"
        sent = f"{self.host_ip}:{self._port('data')}"
        return f"; it was told to send to {sent}{detail}: check --host-ip (the URI's host=)"

    def packets(self, timeout_s: float = 0.1) -> list[bytes]:
        """The raw packets received so far (waiting up to ``timeout_s`` for the first);
        DeviceError if the link is dead or no packet came for ``stall_s``."""
        if self._sampling_since is None:
            raise DeviceError(f"{self.name}: not sampling (call open)")
        if self._dead is not None:
            raise DeviceError(f"{self.name}: {self._dead}")
        return self._packets.take(timeout_s, self._check)

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
