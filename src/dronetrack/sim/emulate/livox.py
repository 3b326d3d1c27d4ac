"""An emulated Livox SDK 1 LiDAR (Avia or Mid-40) on UDP, streaming given points.

The device side of the link ``sources.livox_udp`` drives (Livox-SDK
``sdk_core/src/device_discovery.cpp``, ``command_handler/command_channel.cpp``):

- it binds its command socket on (ip, device_port) (65000 on a real device) and,
  while no host is connected, broadcasts its broadcast code and device type
  (command 0x00, cmd_type MSG) from that socket every ``broadcast_period_s`` to
  ``broadcast_to`` (the host's port 55000; 255.255.255.255 on a real network);
- it answers every command with an ACK frame of the same sequence number to the
  address the command came from: handshake (0x01, accepted with cmd_type CMD or ACK,
  as the SDK sends it with ACK) stores the host's IP and ports, ret_code 0 (1 if
  another host holds the device); heartbeat (0x03) ret_code 0, state 1 (normal);
  sampling (0x04) starts or stops the stream (ret_code 1 with no host); disconnect
  (0x06) forgets the host.  Frames that do not decode are ignored and counted;
- it forgets a host that sent no heartbeat for ``host_timeout_s`` (3 s).

While sampling, it fires once per Δt (4 167 ns Avia, 10 000 ns Mid-40: livox_ros_driver
``lds.h``): firing k is at device time k·Δt, nanoseconds since the sampling started
(timestamp type 0, no sync).  A source point at time t (ns since the sampling
started) takes firing k = round(t / Δt); a second point on a taken firing, or one
older than the packets already built, is dropped and counted (``points_dropped``).
Firings without a point are sent with zero range (no return), as a real device
sends them.  Packets hold n firings (96 for data type 2, the Avia's; 100 for data
type 0, the Mid-40's) and packet p is sent when the wall clock since the start of
sampling reaches its first firing's time p·n·Δt, the thread sleeping at most 5 ms
at a time.  The stream ends with the packet of the source's last point.

Test hooks: ``drop_every`` = k withholds every k-th packet (k, 2k, … counted from 1;
``packets_dropped``), ``paused`` withholds all packets while set, and
``answer_heartbeats`` = False ignores heartbeats.
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
from types import TracebackType

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError, DecodeError, DeviceError, InputError
from dronetrack.formats import livox_sdk1 as s1
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Frame

__all__ = [
    "EmulatedLivox",
    "GridSource",
    "PointChunk",
    "PointSource",
    "frame_chunks",
    "grid_points",
]

AVIA, MID40 = 7, 1
DATA_TYPE = {AVIA: 2, MID40: 0}  # the Avia's extended Cartesian points; the Mid-40's Cartesian
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

    def __post_init__(self) -> None:
        n = len(self.t_ns)
        if self.xyz.shape != (n, 3) or self.reflectivity.shape != (n,):
            raise InputError(
                f"a point chunk needs xyz (N, 3), N times and N reflectivities; got "
                f"{self.xyz.shape}, {self.t_ns.shape}, {self.reflectivity.shape}"
            )


# An iterable of chunks (iterated anew at each sampling start: a list or GridSource
# restarts, a generator goes on), or a callable giving a fresh one at each start.
PointSource = Iterable[PointChunk] | Callable[[], Iterable[PointChunk]]


def frame_chunks(frames: Iterable[Frame], t0_s: float = 0.0) -> Iterator[PointChunk]:
    """Simulator frames as point chunks: the sensor-frame points, their times as ns
    since ``t0_s`` (t_ns = round((t − t0)·10⁹)), in time order, and their intensity
    (already in the Livox reflectivity scale) clipped to 0-255."""
    for frame in frames:
        order = np.argsort(frame.t, kind="stable")
        t_ns = np.rint((frame.t[order] - t0_s) * 1e9).astype(np.int64)
        refl = np.clip(np.rint(frame.intensity[order]), 0, 255).astype(np.uint8)
        yield PointChunk(np.asarray(frame.points[order], np.float64), t_ns, refl)


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


@dataclass
class _Host:
    ip: str
    cmd_port: int
    data_port: int
    last_heartbeat: float


class EmulatedLivox:
    """A Livox SDK 1 device on (ip, device_port) streaming the points of ``source``
    (see PointSource).

    ``dev_type`` 7 (Avia, data type 2) or 1 (Mid-40, data type 0); ``device_port`` 0
    takes a free port (``address`` tells which).  ``start`` runs it in a background
    thread; ``close`` stops it within about 1 s.  Counters: ``commands_received``,
    ``commands_malformed``, ``commands_unknown``, ``broadcasts_sent``,
    ``heartbeats_answered``, ``packets_sent``, ``packets_dropped``, ``points_built``,
    ``points_dropped``.
    """

    def __init__(
        self,
        source: PointSource,
        *,
        dev_type: int = AVIA,
        ip: str = "127.0.0.1",
        device_port: int = s1.LIDAR_CMD_PORT,
        broadcast_to: tuple[str, int] | None = None,
        broadcast_code: str = "0EMULATEDLIVOX1",
        broadcast_period_s: float = 1.0,
        host_timeout_s: float = 3.0,
    ) -> None:
        if dev_type not in DATA_TYPE:
            raise ConfigError(f"the emulated Livox is an Avia (7) or a Mid-40 (1), not {dev_type}")
        if len(broadcast_code.encode("ascii")) > 15:
            raise ConfigError(f"a broadcast code has at most 15 characters: {broadcast_code!r}")
        self.source = source
        self.dev_type = dev_type
        self.data_type = DATA_TYPE[dev_type]
        self.point_interval_ns = s1.POINT_INTERVAL_NS[dev_type]
        self.firings_per_packet = s1.POINTS_PER_PACKET[self.data_type]
        self.broadcast_to = broadcast_to
        self.broadcast_code = broadcast_code
        self.broadcast_period_s = broadcast_period_s
        self.host_timeout_s = host_timeout_s
        # test hooks
        self.drop_every = 0
        self.paused = False
        self.answer_heartbeats = True
        # counters
        self.commands_received = 0
        self.commands_malformed = 0
        self.commands_unknown = 0
        self.broadcasts_sent = 0
        self.heartbeats_answered = 0
        self.packets_sent = 0
        self.packets_dropped = 0
        self.points_built = 0
        self.points_dropped = 0
        self.host: _Host | None = None
        self.sampling = False
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            self._sock.bind((ip, device_port))
        except OSError as exc:
            self._sock.close()
            raise DeviceError(f"emulated Livox: cannot bind {ip}:{device_port}: {exc}") from exc
        self._sock.setblocking(False)
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._bseq = 0
        self._reset_stream()

    @property
    def address(self) -> tuple[str, int]:
        """(ip, port) of the command socket."""
        ip, port = self._sock.getsockname()[:2]
        return str(ip), int(port)

    # -- life cycle ------------------------------------------------------------------

    def start(self) -> EmulatedLivox:
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="emulated-livox", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop the thread (it wakes at least every 5 ms) and close the socket."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        self._sock.close()

    def __enter__(self) -> EmulatedLivox:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _run(self) -> None:
        next_broadcast = time.monotonic()
        while not self._stop.is_set():
            now = time.monotonic()
            wait = SLEEP_S
            if self.host is None and self.broadcast_to is not None:
                if now >= next_broadcast:
                    self._broadcast()
                    next_broadcast = now + self.broadcast_period_s
                wait = min(wait, next_broadcast - now)
            host = self.host
            if host is not None and now - host.last_heartbeat > self.host_timeout_s:
                self.host, self.sampling = None, False  # the host went silent
            if self.sampling:
                due = self._send_due(now)
                if due is not None:
                    wait = min(wait, due - now)
            try:
                ready, _, _ = select.select([self._sock], [], [], max(wait, 0.0))
            except (OSError, ValueError):
                return  # the socket was closed
            if ready:
                self._serve_commands()

    # -- commands ---------------------------------------------------------------------

    def _broadcast(self) -> None:
        assert self.broadcast_to is not None
        self._bseq = self._bseq % 0xFFFF + 1
        payload = s1.Broadcast(self.broadcast_code, self.dev_type).encode()
        frame = s1.CommandFrame(s1.MSG, self._bseq, s1.SET_GENERAL, s1.BROADCAST, payload)
        try:
            self._sock.sendto(s1.encode_frame(frame), self.broadcast_to)
            self.broadcasts_sent += 1
        except OSError:
            pass  # no route to the broadcast address: try again next period

    def _serve_commands(self) -> None:
        for _ in range(64):  # bounded: packets go out between bursts of commands
            try:
                buf, addr = self._sock.recvfrom(2048)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                return
            self.commands_received += 1
            try:
                frame = s1.decode_frame(buf)
                reply = self._answer(frame)
            except DecodeError:
                self.commands_malformed += 1
                continue
            if reply is not None:
                ack = s1.CommandFrame(s1.ACK, frame.seq, s1.SET_GENERAL, frame.cmd_id, reply)
                with contextlib.suppress(OSError):
                    self._sock.sendto(s1.encode_frame(ack), addr)

    def _answer(self, frame: s1.CommandFrame) -> bytes | None:
        """The ACK payload for ``frame``, or None to stay silent; DecodeError if its
        payload does not decode."""
        now = time.monotonic()
        if frame.cmd_set != s1.SET_GENERAL:
            self.commands_unknown += 1
            return None
        cid = frame.cmd_id
        if cid == s1.HANDSHAKE and frame.cmd_type in (s1.CMD, s1.ACK):
            hs = s1.Handshake.decode(frame.payload)
            if self.host is not None and self.host.ip != hs.host_ip:
                return bytes([1])  # another host holds the device
            self.host = _Host(hs.host_ip, hs.cmd_port, hs.data_port, now)
            return bytes([0])
        if frame.cmd_type != s1.CMD:
            self.commands_unknown += 1
            return None
        if cid == s1.HEARTBEAT:
            if not self.answer_heartbeats:
                return None
            if self.host is not None:
                self.host.last_heartbeat = now
            self.heartbeats_answered += 1
            return s1.HeartbeatAck(ret_code=0, state=1, feature=0, status=0).encode()
        if cid == s1.SAMPLING:
            start = s1.decode_sampling(frame.payload)
            if self.host is None:
                return bytes([1])
            if start and not self.sampling:
                self._reset_stream()
                self._t_start = now
            self.sampling = start
            return bytes([0])
        if cid == s1.DISCONNECT:
            self.host, self.sampling = None, False
            return bytes([0])
        self.commands_unknown += 1
        return None

    # -- points -----------------------------------------------------------------------

    def _reset_stream(self) -> None:
        self._t_start = time.monotonic()
        self._iter: Iterator[PointChunk] | None = None
        self._exhausted = False
        self._next_packet = 0
        self._pending: deque[tuple[float, int, bytes]] = deque()
        self._slots = np.zeros(0, np.int64)
        self._xyz = np.zeros((0, 3))
        self._refl = np.zeros(0, np.uint8)

    def _send_due(self, now: float) -> float | None:
        """Send the packets whose time has come; the next one's send time (None at the
        end of the stream)."""
        host = self.host
        if host is None:
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
                self._sock.sendto(packet, (host.ip, host.data_port))
            except OSError:
                continue
            self.packets_sent += 1
        return now

    def _pull(self, until_slot: int) -> None:
        """Take source chunks until a point at or beyond ``until_slot`` is held."""
        if self._iter is None:
            src = self.source
            self._iter = iter(src() if callable(src) else src)
        dt = self.point_interval_ns
        while not self._exhausted and (len(self._slots) == 0 or self._slots[-1] < until_slot):
            chunk = next(self._iter, None)
            if chunk is None:
                self._exhausted = True
                return
            t = np.asarray(chunk.t_ns, np.int64)
            # k = round(t / Δt)
            slots = (t + dt // 2) // dt
            self._slots = np.concatenate([self._slots, slots])
            self._xyz = np.concatenate([self._xyz, np.asarray(chunk.xyz, np.float64)])
            self._refl = np.concatenate([self._refl, np.asarray(chunk.reflectivity, np.uint8)])

    def _build_block(self) -> bool:
        """Encode the next BLOCK_S of packets into the pending queue; False at the end."""
        n, dt = self.firings_per_packet, self.point_interval_ns
        count = max(round(BLOCK_S * 1e9 / (n * dt)), 1)
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
        packets = s1.encode_point_packets(
            fire_xyz,
            fire_refl,
            data_type=self.data_type,
            t0_ns=first * dt,
            point_interval_ns=dt,
        )
        self.points_built += len(uniq)  # built; dropped packets are counted apart
        for i, packet in enumerate(packets):
            p = self._next_packet + i
            self._pending.append((self._t_start + p * n * dt * 1e-9, p, packet))
        self._next_packet += count
        return True
