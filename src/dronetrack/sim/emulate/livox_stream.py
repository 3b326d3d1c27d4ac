"""What the emulated Livox devices (SDK 1 and SDK 2) share: the points they are fed,
and the device thread that streams them as point packets at the device's rate.

A device fires once per Δt; firing k is at device time k·Δt, nanoseconds since the
sampling started (no time synchronisation).  A source point at time t (ns since the
sampling started) takes firing k = round(t / Δt); a second point on a taken firing,
or one older than the packets already built, is dropped and counted
(``points_dropped``).  Firings without a point are sent with zero range (no return),
as a real device sends them.  Packets hold n firings, and packet p is sent when the
wall clock since the start of sampling reaches its first firing's time p·n·Δt (plus
``send_delay_ns``: a device that sends a packet once its last firing is done), the
thread sleeping at most 5 ms at a time.  The stream ends with the packet of the
source's last point.

A chunk that says how far it covers (``PointChunk.end_ns``) lets the device build
the packets up to there without taking the next chunk, so a source can make each
chunk just before its time (``block_ns`` tells how much device time one build
spans, and ``stream_start`` when the current sampling started).

Test hooks: ``drop_every`` = k withholds every k-th packet (k, 2k, … counted from 1;
``packets_dropped``) and ``paused`` withholds all packets while set.
"""

from __future__ import annotations

import contextlib
import select
import socket
import threading
import time
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from typing import Self

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError, DecodeError, DeviceError, InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Frame

__all__ = [
    "GridSource",
    "PointChunk",
    "PointSource",
    "StreamingDevice",
    "bound_udp",
    "frame_chunks",
    "grid_points",
]

SLEEP_S = 0.005  # longest single wait of the device thread
BLOCK_S = 0.02  # packets are built this far ahead, in one vectorised call
MAX_BURST = 256  # packets sent in one pass before the thread looks at commands again


@dataclass(frozen=True)
class PointChunk:
    """Points for the emulated device: xyz (N, 3) [m] in the sensor frame (x forward),
    t_ns (N,) int64 ns since the sampling started, in time order, reflectivity (N,)."""

    xyz: FloatArray
    t_ns: NDArray[np.int64]
    reflectivity: NDArray[np.uint8]
    # No later chunk holds a point before end_ns (None: unknown).  A device can then
    # build the packets up to end_ns without waiting for the next chunk.
    end_ns: int | None = None
    # The scan line of each point (N,) uint8, where the source knows it (the Livox
    # packets do not carry it; a ROS 2 driver's messages do).
    line: NDArray[np.uint8] | None = None

    def __post_init__(self) -> None:
        n = len(self.t_ns)
        bad_line = self.line is not None and self.line.shape != (n,)
        if self.xyz.shape != (n, 3) or self.reflectivity.shape != (n,) or bad_line:
            raise InputError(
                f"a point chunk needs xyz (N, 3), N times, N reflectivities (and N lines); "
                f"got {self.xyz.shape}, {self.t_ns.shape}, {self.reflectivity.shape}"
            )


# An iterable of chunks (iterated anew at each sampling start: a list or GridSource
# restarts, a generator goes on), or a callable giving a fresh one at each start.
PointSource = Iterable[PointChunk] | Callable[[], Iterable[PointChunk]]


def frame_chunks(frames: Iterable[Frame], t0_s: float = 0.0) -> Iterator[PointChunk]:
    """Simulator frames as point chunks: the sensor-frame points, their times as ns
    since ``t0_s`` (t_ns = round((t − t0)·10⁹)), in time order, and their intensity
    (already in the Livox reflectivity scale) clipped to 0-255, with their scan lines."""
    for frame in frames:
        order = np.argsort(frame.t, kind="stable")
        t_ns = np.rint((frame.t[order] - t0_s) * 1e9).astype(np.int64)
        refl = np.clip(np.rint(frame.intensity[order]), 0, 255).astype(np.uint8)
        line = np.asarray(frame.line[order], np.uint8)
        yield PointChunk(np.asarray(frame.points[order], np.float64), t_ns, refl, line=line)


def grid_points(k: NDArray[np.int64]) -> FloatArray:
    """A known point for firing k: a raster 10-11 m ahead, whole millimetres, so
    that it survives the packets' mm quantisation exactly:
        x = 10 + (k mod 1000)·1 mm,  y = ((⌊k/1000⌋ mod 200) − 100)·1 cm,
        z = (⌊k/200000⌋ mod 50)·2 cm − 0.5 m."""
    k = np.asarray(k, np.int64)
    x = 10.0 + (k % 1000) * 1e-3
    y = ((k // 1000) % 200 - 100) * 1e-2
    z = ((k // 200_000) % 50) * 2e-2 - 0.5
    return np.stack([x, y, z], axis=1)


class GridSource:
    """A synthetic point source: the point ``grid_points(k)`` with reflectivity
    k mod 251 at every ``stride``-th firing k·Δt for ``duration_s``, in chunks of
    ``chunk_s``.  With stride 1 an Avia's source gives 1/Δt = 239 981 points/s.
    Iterable again and again (each sampling start restarts it)."""

    def __init__(
        self, point_interval_ns: int, duration_s: float, stride: int = 1, chunk_s: float = 0.01
    ) -> None:
        if point_interval_ns < 1 or stride < 1 or not chunk_s > 0:
            raise ConfigError("a grid source needs Δt ≥ 1 ns, stride ≥ 1 and chunk_s > 0")
        self.point_interval_ns = point_interval_ns
        self.stride = stride
        self.firings = int(duration_s * 1e9) // point_interval_ns
        self.chunk = max(int(chunk_s * 1e9) // point_interval_ns, 1)

    def firing_indices(self) -> NDArray[np.int64]:
        """Every firing k that holds a point."""
        return np.arange(0, self.firings, self.stride, dtype=np.int64)

    def __iter__(self) -> Iterator[PointChunk]:
        for start in range(0, self.firings, self.chunk):
            k = np.arange(start, min(start + self.chunk, self.firings), dtype=np.int64)
            k = k[k % self.stride == 0]
            yield PointChunk(grid_points(k), k * self.point_interval_ns, (k % 251).astype(np.uint8))


def bound_udp(ip: str, port: int, what: str, *, shared: bool = False) -> socket.socket:
    """A non-blocking UDP socket bound to (ip, port) that may broadcast; ``shared``: with
    SO_REUSEADDR, so that a host on the same machine may bind the same port on all
    interfaces (as Livox-SDK2 binds its detection port 56000 with port reuse)."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
        if shared:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((ip, port))
    except OSError as exc:
        sock.close()
        raise DeviceError(f"emulated Livox: cannot bind {ip}:{port} for {what}: {exc}") from exc
    sock.setblocking(False)
    return sock


class StreamingDevice:
    """The thread and point stream of an emulated Livox device (see the module
    docstring); a subclass gives its sockets, answers its commands and encodes its
    packets.  ``start`` runs the thread; ``close`` stops it within about 1 s.
    ``clock`` (seconds; time.monotonic by default) is the device's: the thread's ticks
    and the stream's send times are on it.

    Counters: ``commands_received``, ``commands_malformed``, ``commands_unknown``,
    ``packets_sent``, ``packets_dropped``, ``points_built``, ``points_dropped``.
    """

    def __init__(
        self,
        source: PointSource,
        point_interval_ns: int,
        firings_per_packet: int,
        *,
        clock: Callable[[], float] = time.monotonic,
    ):
        self.source = source
        self.clock = clock
        self.point_interval_ns = point_interval_ns
        self.firings_per_packet = firings_per_packet
        self.send_delay_ns = 0  # a packet goes this long after its first firing
        # test hooks
        self.drop_every = 0
        self.paused = False
        # counters
        self.commands_received = 0
        self.commands_malformed = 0
        self.commands_unknown = 0
        self.packets_sent = 0
        self.packets_dropped = 0
        self.points_built = 0
        self.points_dropped = 0
        self.sampling = False
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._reset_stream()

    # -- hooks of a subclass ----------------------------------------------------------

    def _sockets(self) -> list[socket.socket]:
        """Every socket the device holds; the thread answers what comes to them."""
        raise NotImplementedError

    def _reply(self, sock: socket.socket, buf: bytes) -> bytes | None:
        """The reply to a datagram that came to ``sock`` (None: stay silent);
        DecodeError if it does not decode."""
        raise NotImplementedError

    def _tick(self, now: float) -> float:
        """Periodic work (broadcasts, status pushes, host time-outs); how long the
        thread may sleep before the next."""
        return SLEEP_S

    def _data_target(self) -> tuple[str, int] | None:
        """Where point packets go (None: nowhere yet)."""
        raise NotImplementedError

    def _data_socket(self) -> socket.socket:
        raise NotImplementedError

    def _send_failed(self, exc: OSError) -> bool:
        """A point packet could not be sent; True stops this round of sending (the
        packet is skipped either way)."""
        return False

    def _encode(self, xyz: FloatArray, refl: NDArray[np.uint8], first_packet: int) -> list[bytes]:
        """Packets of firings ``xyz`` (a whole number of packets), the first being
        packet ``first_packet`` of the stream."""
        raise NotImplementedError

    @property
    def block_ns(self) -> int:
        """Device time [ns] one build of packets spans: the whole packets nearest BLOCK_S.
        Blocks start at 0, so block b spans [b·block_ns, (b + 1)·block_ns)."""
        n, dt = self.firings_per_packet, self.point_interval_ns
        return max(round(BLOCK_S * 1e9 / (n * dt)), 1) * n * dt

    @property
    def stream_start(self) -> float:
        """``clock()`` when the current (or last) sampling started: device time 0."""
        return self._t_start

    # -- life cycle ------------------------------------------------------------------

    def start(self) -> Self:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="emulated-livox", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop the thread (it wakes at least every 5 ms) and close the sockets."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        for sock in self._sockets():
            sock.close()

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _run(self) -> None:
        socks = self._sockets()
        while not self._stop.is_set():
            now = self.clock()
            wait = min(SLEEP_S, self._tick(now))
            if self.sampling:
                due = self._send_due(now)
                if due is not None:
                    wait = min(wait, due - now)
            try:
                ready, _, _ = select.select(socks, [], [], max(wait, 0.0))
            except (OSError, ValueError):
                return  # a socket was closed
            for sock in ready:
                self._serve(sock)

    # -- commands ---------------------------------------------------------------------

    def _serve(self, sock: socket.socket) -> None:
        """Answer the datagrams waiting at ``sock``, to where each came from."""
        for _ in range(64):  # bounded: packets go out between bursts of commands
            try:
                buf, addr = sock.recvfrom(2048)
            except OSError:  # none left (BlockingIOError), or the socket closed
                return
            self.commands_received += 1
            try:
                reply = self._reply(sock, buf)
            except DecodeError:
                self.commands_malformed += 1
                continue
            if reply is not None:
                with contextlib.suppress(OSError):
                    sock.sendto(reply, addr)

    # -- points -----------------------------------------------------------------------

    def _start_stream(self, now: float) -> None:
        """Start sampling from the source's beginning; the device clock starts now."""
        if not self.sampling:
            self._reset_stream()
            self._t_start = now
        self.sampling = True

    def _reset_stream(self) -> None:
        self._t_start = self.clock()
        self._iter: Iterator[PointChunk] | None = None
        self._exhausted = False
        self._covered = 0  # no point to come maps to a firing below this
        self._next_packet = 0
        self._pending: deque[tuple[float, int, bytes]] = deque()
        self._slots = np.zeros(0, np.int64)
        self._xyz = np.zeros((0, 3))
        self._refl = np.zeros(0, np.uint8)

    def _send_due(self, now: float) -> float | None:
        """Send the packets whose time has come; the next one's send time (None at the
        end of the stream)."""
        target = self._data_target()
        if target is None:
            return None
        for _ in range(MAX_BURST):
            if not self._pending and not self._build_block():
                self.sampling = False  # the source is exhausted: the stream ends
                return None
            due, index, packet = self._pending[0]
            if due > now:
                return due
            self._pending.popleft()
            if self.paused:
                continue
            if self.drop_every and (index + 1) % self.drop_every == 0:
                self.packets_dropped += 1
                continue
            try:
                self._data_socket().sendto(packet, target)
            except OSError as exc:
                if self._send_failed(exc):
                    return None
                continue
            self.packets_sent += 1
        return now

    def _pull(self, until_slot: int) -> None:
        """Take source chunks until a point at or beyond ``until_slot`` is held, or a
        chunk's ``end_ns`` says no point before it is to come."""
        if self._iter is None:
            src = self.source
            self._iter = iter(src() if callable(src) else src)
        dt = self.point_interval_ns
        while (
            not self._exhausted
            and self._covered < until_slot
            and (len(self._slots) == 0 or self._slots[-1] < until_slot)
        ):
            chunk = next(self._iter, None)
            if chunk is None:
                self._exhausted = True
                return
            t = np.asarray(chunk.t_ns, np.int64)
            # k = round(t / Δt) = ⌊(t + ⌊Δt/2⌋) / Δt⌋, non-decreasing in t: a point at or
            # after end_ns takes a firing at or after the one end_ns maps to
            slots = (t + dt // 2) // dt
            if chunk.end_ns is not None:
                self._covered = max(self._covered, (chunk.end_ns + dt // 2) // dt)
            self._slots = np.concatenate([self._slots, slots])
            self._xyz = np.concatenate([self._xyz, np.asarray(chunk.xyz, np.float64)])
            self._refl = np.concatenate([self._refl, np.asarray(chunk.reflectivity, np.uint8)])

    def _build_block(self) -> bool:
        """Encode the next BLOCK_S of packets into the pending queue; False at the end."""
        n, dt = self.firings_per_packet, self.point_interval_ns
        count = self.block_ns // (n * dt)
        first = self._next_packet * n
        end = first + count * n
        self._pull(end)
        take = self._slots < end
        slots, xyz, refl = self._slots[take], self._xyz[take], self._refl[take]
        self._slots, self._xyz, self._refl = (
            self._slots[~take],
            self._xyz[~take],
            self._refl[~take],
        )
        # one point per firing: the first on each firing, none before this block
        late = slots < first
        uniq, where = np.unique(slots[~late], return_index=True)
        self.points_dropped += int(late.sum()) + (int((~late).sum()) - len(uniq))
        if self._exhausted and len(self._slots) == 0:
            if len(uniq) == 0:
                return False
            count = int(uniq[-1]) // n - self._next_packet + 1  # end with the last point
            end = first + count * n
        fire_xyz = np.zeros((count * n, 3))
        fire_refl = np.zeros(count * n, np.uint8)
        fire_xyz[uniq - first] = xyz[~late][where]
        fire_refl[uniq - first] = refl[~late][where]
        packets = self._encode(fire_xyz, fire_refl, self._next_packet)
        self.points_built += len(uniq)  # built; dropped packets are counted apart
        for i, packet in enumerate(packets):
            p = self._next_packet + i
            due = self._t_start + (p * n * dt + self.send_delay_ns) * 1e-9
            self._pending.append((due, p, packet))
        self._next_packet += count
        return True
