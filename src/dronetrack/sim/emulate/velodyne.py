"""An emulated Velodyne VLP-16 on UDP, streaming given points.

The sensor side of the link ``sources.velodyne.client`` reads.  A VLP-16 takes no
command: it sends its data packets (``formats.velodyne``) from its address to the
destination set in its web interface (255.255.255.255, data port 2368, by default),
here ``dest``.

Firings.  Laser c of firing sequence s fires at device time s · 55.296 µs + c · 2.304
µs (ns since the stream started), as the simulator's VLP-16 fires at scenario time
(``sim.spinning``).  On ``livox_stream``'s grid of Δt = 2.304 µs that is slot
k = 24 s + c (55.296 = 24 × 2.304: slots 16-23 of a sequence are its recharge, never
fired), and a packet of 24 sequences is 576 slots.  Packet p's first firing is at
p · 1327.104 µs, and it is sent when its last firing is done, 1306.368 µs later (23
sequences and 15 firings), as a sensor sends what it has measured: 753.5 packets/s.

A packet from points.  The points are in the frame the simulator gives them (x
forward); for a head mounted on its side, ``head_rotation`` R (p = R p_head) turns
them back into the head's own frame, p_head = Rᵀ p.  The point of laser c in sequence
s' = s mod 24 of its packet goes to data point 16 (s' mod 2) + c of block ⌊s'/2⌋, with
its range along the beam r = |p_head − (0, 0, δ_c)| (``formats.velodyne.beam_range``;
2 mm steps) and its reflectivity; a firing without a point is sent with range 0, no
return.  A block's azimuth is the head's at its first firing,

    α(t) = (α₀ + 360° · rpm/60 · t) mod 360°

clockwise seen from above: the simulator's head turns as az(t) = −ω t from az = 0
(counter-clockwise positive, from x), so α = −az with α₀ = 0.  The timestamp is the
packet's first firing rounded to the µs, modulo the hour; the factory bytes say 0x37
(strongest return) and 0x22 (VLP-16).

The host.  A real VLP-16 streams from power-on, whoever listens.  So that the
scenario's clock starts with the host's run, the emulated one holds its stream at the
start until a host listens: every ``probe_s`` (50 ms) it sends the stream's packet 0,
with no return in it, from a UDP socket connected to ``dest``.  A datagram to a port
nobody listens on comes back refused (ICMP port unreachable; on this machine at once);
when packet 0 is not refused within 2 ms, the stream starts: device time 0 is packet
0's first firing, 1306.368 µs before it went, and packet 1 follows on time (packet
0's own points, made after it went, are dropped).  To a destination that refuses
nothing (another machine, a broadcast address) it starts at the first probe.  A
packet refused while streaming means the host stopped listening: the stream stops
and the device waits for a host again, and the next one gets the source from its
start (the emulated rig runs the scenario again).  After the stream's end the device is silent.

Test hooks: ``drop_every`` and ``paused`` (``livox_stream``).
"""

from __future__ import annotations

import socket
import time

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError, DeviceError
from dronetrack.formats import velodyne as fv
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.emulate.livox_stream import SLEEP_S, PointSource, StreamingDevice

__all__ = ["SEQUENCES_PER_PACKET", "SLOTS_PER_SEQUENCE", "EmulatedVelodyne"]

SLOTS_PER_SEQUENCE = fv.FIRING_CYCLE_NS // fv.FIRING_INTERVAL_NS  # 24
SEQUENCES_PER_PACKET = 2 * fv.BLOCKS  # 24, single-return mode
SLOTS_PER_PACKET = SLOTS_PER_SEQUENCE * SEQUENCES_PER_PACKET  # 576
PROBE_CHECK_S = 0.002  # a probe not refused after this long found a host


class EmulatedVelodyne(StreamingDevice):
    """A VLP-16 sending the points of ``source`` (see PointSource) from ``ip`` (any
    port) to ``dest`` (see the module docstring), spinning at ``rpm`` from azimuth
    ``azimuth0_deg``.  ``start`` runs it in a background thread; ``close`` stops it
    within about 1 s.  Counters: ``probes_sent``, ``hosts`` (streams started),
    ``hosts_lost`` (streams stopped by a refusal), ``packets_sent``,
    ``packets_dropped``, ``points_built``, ``points_dropped``; ``waiting`` is True
    while it waits for a host."""

    def __init__(
        self,
        source: PointSource,
        *,
        ip: str = "127.0.0.1",
        dest: tuple[str, int] = ("127.0.0.1", fv.DATA_PORT),
        rpm: float = 600.0,
        head_rotation: FloatArray | None = None,
        azimuth0_deg: float = 0.0,
        probe_s: float = 0.05,
    ) -> None:
        if not 300.0 <= rpm <= 1200.0:
            raise ConfigError(f"a VLP-16 spins at 300-1200 rpm, not {rpm:g}")
        if not probe_s > PROBE_CHECK_S:
            raise ConfigError(f"the probe period must be over {PROBE_CHECK_S} s, got {probe_s}")
        super().__init__(source, fv.FIRING_INTERVAL_NS, SLOTS_PER_PACKET)
        self.send_delay_ns = int(fv.firing_offsets_ns()[-1, -1])  # its last firing
        self.ip = ip
        self.dest = (str(dest[0]), int(dest[1]))
        self.rpm = float(rpm)
        self.azimuth0_deg = float(azimuth0_deg)
        self.rotation = None if head_rotation is None else np.asarray(head_rotation, np.float64)
        self.probe_s = probe_s
        self.probes_sent = 0
        self.hosts = 0
        self.hosts_lost = 0
        self.waiting = True
        self._probe_sent: float | None = None  # when the pending probe went (monotonic)
        self._next_probe = time.monotonic()
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            sock.bind((ip, 0))
            sock.connect(self.dest)
        except OSError as exc:
            sock.close()
            raise DeviceError(
                f"emulated VLP-16: cannot send from {ip} to {self.dest[0]}:{self.dest[1]}: {exc}"
            ) from exc
        sock.setblocking(False)
        self._sock = sock
        self._probe = self._encode(
            np.zeros((SLOTS_PER_PACKET, 3)), np.zeros(SLOTS_PER_PACKET, np.uint8), 0
        )[0]

    @property
    def address(self) -> tuple[str, int]:
        """(ip, port) the packets come from."""
        ip, port = self._sock.getsockname()[:2]
        return str(ip), int(port)

    # -- the device thread's hooks -------------------------------------------------------

    def _sockets(self) -> list[socket.socket]:
        # Nothing comes in; a refusal is left pending on the socket for the probe to see.
        return []

    def close(self) -> None:
        super().close()
        self._sock.close()

    def _reply(self, sock: socket.socket, buf: bytes) -> bytes | None:
        return None

    def _tick(self, now: float) -> float:
        if not self.waiting:
            return SLEEP_S
        if self._probe_sent is not None:
            if now - self._probe_sent < PROBE_CHECK_S:
                return PROBE_CHECK_S - (now - self._probe_sent)
            refused = self._sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR) != 0
            if not refused:
                self._begin(self._probe_sent)
                return 0.0
            self._probe_sent = None
        if now >= self._next_probe:
            self._sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)  # clear an old refusal
            try:
                self._sock.send(self._probe)
                self._probe_sent = now
                self.probes_sent += 1
            except OSError:
                pass  # refused at once, or no route: try again next period
            self._next_probe = now + self.probe_s
            return PROBE_CHECK_S
        return min(SLEEP_S, self._next_probe - now)

    def _begin(self, sent: float) -> None:
        """Start the stream: packet 0 went at ``sent``, after its last firing."""
        self.waiting = False
        self._probe_sent = None
        self._start_stream(sent - self.send_delay_ns * 1e-9)
        self._next_packet = 1  # packet 0 went as the probe
        self.hosts += 1

    def _send_failed(self, exc: OSError) -> bool:
        if not isinstance(exc, ConnectionRefusedError) or not self.sampling:
            return False
        self.sampling = False
        self.waiting = True
        self.hosts_lost += 1
        self._next_probe = time.monotonic() + self.probe_s
        return True

    def _data_target(self) -> tuple[str, int] | None:
        return self.dest

    def _data_socket(self) -> socket.socket:
        return self._sock

    # -- packets --------------------------------------------------------------------------

    def _encode(self, xyz: FloatArray, refl: NDArray[np.uint8], first_packet: int) -> list[bytes]:
        n = len(xyz) // SLOTS_PER_PACKET
        shape = (n, SEQUENCES_PER_PACKET, SLOTS_PER_SEQUENCE)
        p = np.asarray(xyz, np.float64).reshape(*shape, 3)[:, :, : fv.LASERS]
        r = np.asarray(refl, np.uint8).reshape(shape)[:, :, : fv.LASERS]
        hit = np.any(p != 0.0, axis=-1)
        if self.rotation is not None:
            p = p @ self.rotation  # p_head = Rᵀ p, row vectors
        dist = np.where(hit, fv.beam_range(p, np.arange(fv.LASERS)), 0.0)
        # sequence s' of the packet → block ⌊s'/2⌋, channels 16 (s' mod 2) + c
        dist = dist.reshape(n, fv.BLOCKS, fv.CHANNELS)
        r = np.where(hit, r, 0).reshape(n, fv.BLOCKS, fv.CHANNELS)
        span = SLOTS_PER_PACKET * fv.FIRING_INTERVAL_NS
        t_pkt = (first_packet + np.arange(n, dtype=np.int64)) * span
        t_block = t_pkt[:, None] + fv.block_offsets_ns()[None, :]
        # α(t) = α₀ + 360° · rpm/60 · t
        azimuth = self.azimuth0_deg + 6.0 * self.rpm * (t_block.astype(np.float64) * 1e-9)
        stamp_us = np.rint(t_pkt / 1000.0).astype(np.int64)
        return fv.encode_packets(dist, r.astype(np.uint8), azimuth, stamp_us)
