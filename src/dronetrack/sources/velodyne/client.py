"""A live Velodyne VLP-16 over UDP, host side: ``velodyne://[IP:]PORT``.

A VLP-16 needs no command: once powered it streams its data packets (1206 bytes,
``formats.velodyne``) to the destination set in its web interface, by default
255.255.255.255 port 2368, about 754 a second.  The host only listens:

- ``velodyne://`` or ``velodyne://2368``: UDP port 2368 on every interface;
- ``velodyne://IP:PORT``: that port on the local address IP only (e.g.
  ``velodyne://192.168.1.100:2368``, or a loopback address for the emulator);
- query keys ``host=IP``, the local address as a key (what ``live --host-ip``
  adds; it must agree with an IP given before the port), and ``device=IP``, take
  packets from the sensor at IP only (others are ignored and counted).

Decoding.  Packets are checked and their headers read with numpy
(``formats.velodyne``): malformed ones (not 1206 bytes, a block not flagged FF EE, an
azimuth past 359.99°, an unknown return mode) are skipped and counted.  The points are
decoded by velodyne-decoder (``pip install 'dronetrack[velodyne]'``;
``ScanDecoder`` on each batch of packets, so nothing waits for a whole scan), which
applies the manual's elevations and vertical corrections; each point's time is its
packet's time (``velodyne_timing.PacketClock``: the hour-long stamps unwrapped, lost
packets counted from their gaps) plus its firing offset, and its ``line`` is its laser
ID (0-15, the firing order; velodyne-decoder's ring is the elevation order).  A
``head_rotation`` R (3 × 3) turns the points from the sensor head's frame into the
frame the pipeline uses, p = R p_head (a VLP-16 on its side, ``config.spinning``).
Each batch carries the times of its packets' first and last firings and where a
revolution starts in them (``PointBatch.cuts``, at azimuth ``cut_deg``).

Liveness: ``open`` waits for the first packet (DeviceError if none comes within its
time-out), and a stream with no packet for ``stall_s`` (1 s) raises DeviceError naming
the port.  Packets from another product than a VLP-16 (product ID 0x22, shared with
the Puck LITE) raise DeviceError: its elevations differ.  The port is bound without
SO_REUSEADDR: a second listener on it (another ``live`` or ``info``), which would take
every packet sent to this host's address, is refused with an error naming the port.
"""

from __future__ import annotations

import functools
import ipaddress
import socket
import threading
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Self
from urllib.parse import parse_qsl, urlsplit

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError, DeviceError, MissingExtraError
from dronetrack.formats import velodyne as fv
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sources.assembly import PointBatch
from dronetrack.sources.queues import PacketQueue
from dronetrack.sources.udp import POLL_S, PORT_IN_USE, port_in_use
from dronetrack.sources.velodyne.timing import PacketClock, RevolutionCuts, spin_advance

__all__ = ["VelodyneClient", "VelodyneEndpoint", "parse_velodyne_uri"]

SCHEME = "velodyne"
MAX_PACKETS = 8192  # about 11 s of packets
STALL_S = 1.0
MAX_DATAGRAM = 2048
_HINT = "velodyne:// needs velodyne-decoder: pip install 'dronetrack[velodyne]'"


@dataclass(frozen=True)
class VelodyneEndpoint:
    """Where the host listens for a VLP-16: the local address (0.0.0.0: every
    interface) and UDP port (0 here: a free one, for tests), and the sensor's address
    if packets are taken from it only."""

    bind_ip: str = "0.0.0.0"
    port: int = fv.DATA_PORT
    device_ip: str | None = None


def _ipv4(text: str, what: str, uri: str) -> str:
    try:
        return str(ipaddress.IPv4Address(text))
    except ValueError:
        raise ConfigError(f"{uri!r}: {what} {text!r} is not an IPv4 address") from None


def _port(text: str, uri: str) -> int:
    if not text.isdigit() or not 1 <= int(text) <= 65535:
        raise ConfigError(f"{uri!r}: {text!r} is not a UDP port in 1..65535")
    return int(text)


def parse_velodyne_uri(uri: str) -> VelodyneEndpoint:
    """``velodyne://[PORT | IP:PORT][?host=IP&device=IP]`` (module docstring);
    ConfigError naming the problem."""
    try:
        parts = urlsplit(uri)
    except ValueError as exc:
        raise ConfigError(f"{uri!r} is not a URI: {exc}") from None
    if parts.scheme != SCHEME:
        raise ConfigError(f"{uri!r}: a VLP-16 is given as velodyne://PORT or velodyne://IP:PORT")
    if parts.path not in ("", "/") or parts.fragment or "@" in parts.netloc:
        raise ConfigError(f"{uri!r}: velodyne://[IP:]PORT takes no path, user or fragment")
    fields: dict[str, Any] = {}
    netloc = parts.netloc
    if netloc:
        ip, colon, port = netloc.rpartition(":")
        if not colon:
            if not netloc.isdigit():
                raise ConfigError(
                    f"{uri!r}: give the UDP port the sensor sends to, velodyne://{fv.DATA_PORT}, "
                    f"or a local address with it, velodyne://{netloc}:{fv.DATA_PORT} (the "
                    "sensor's own address is the query key device=IP)"
                )
            port = netloc
        fields["port"] = _port(port, uri)
        if ip:
            fields["bind_ip"] = _ipv4(ip, "local address", uri)
    try:
        pairs = parse_qsl(parts.query, keep_blank_values=True, strict_parsing=bool(parts.query))
    except ValueError:
        raise ConfigError(f"{uri!r}: the query is not key=value pairs joined by &") from None
    seen: set[str] = set()
    for key, value in pairs:
        if key in seen:
            raise ConfigError(f"{uri!r}: query key {key!r} is given twice")
        seen.add(key)
        if key == "host":
            host = _ipv4(value, "host", uri)
            if fields.get("bind_ip", host) != host:
                raise ConfigError(
                    f"{uri!r}: host={host} and the address {fields['bind_ip']} disagree"
                )
            fields["bind_ip"] = host
        elif key == "device":
            fields["device_ip"] = _ipv4(value, "device", uri)
        else:
            raise ConfigError(f"{uri!r}: unknown query key {key!r} (known: host, device)")
    return VelodyneEndpoint(**fields)


def _decoder_module() -> Any:
    try:
        import velodyne_decoder
    except ImportError as exc:
        raise MissingExtraError(_HINT) from exc
    return velodyne_decoder


class VelodyneClient:
    """Host side of one VLP-16: ``open``, then ``read`` (or ``packets`` and ``decode``)
    repeatedly, then ``close`` (or use it as a context manager).  See the module
    docstring.

    Counters: ``packets_received``, ``packets_malformed`` (counted when decoded),
    ``packets_lost``, ``packets_ignored`` (from another address than ``device=``),
    ``queue_dropped``.  What the packets said: ``source_ip``, ``product``,
    ``return_mode`` and ``rpm`` (the spin rate from the azimuths, None before 1 ms
    of blocks).
    """

    def __init__(
        self,
        endpoint: VelodyneEndpoint | str,
        *,
        head_rotation: FloatArray | None = None,
        cut_deg: float = 0.0,
        max_packets: int = MAX_PACKETS,
        stall_s: float = STALL_S,
    ) -> None:
        self.endpoint = parse_velodyne_uri(endpoint) if isinstance(endpoint, str) else endpoint
        self._vd = _decoder_module()
        self.rotation = None if head_rotation is None else np.asarray(head_rotation, np.float64)
        if self.rotation is not None and self.rotation.shape != (3, 3):
            raise ConfigError(f"a head rotation is 3 × 3, got {self.rotation.shape}")
        self.stall_s = stall_s
        self.packets_malformed = 0
        self.packets_lost = 0
        self.packets_ignored = 0
        self.source_ip: str | None = None
        self.product: int | None = None
        self.return_mode: int | None = None
        self._queue = PacketQueue(max_packets)
        self._clock = PacketClock()
        self._cuts = RevolutionCuts(cut_deg)
        self._decoder = self._vd.ScanDecoder(
            self._vd.Config(model=self._vd.Model.VLP16, timestamp_first_packet=True)
        )
        self._spin = [0, 0]  # azimuth advance [0.01°] and time [ns] between blocks
        self._last_block: tuple[int, int] | None = None
        self._sock: socket.socket | None = None
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._first = threading.Event()
        self._opened_at: float | None = None
        self._closed = False

    @property
    def name(self) -> str:
        e = self.endpoint
        source = f" from {e.device_ip}" if e.device_ip else ""
        return f"VLP-16 on UDP {e.bind_ip}:{e.port}{source}"

    @property
    def address(self) -> tuple[str, int]:
        """(ip, port) the client listens on (the port the kernel gave for port 0)."""
        if self._sock is None:
            return self.endpoint.bind_ip, self.endpoint.port
        ip, port = self._sock.getsockname()[:2]
        return str(ip), int(port)

    @property
    def packets_received(self) -> int:
        return self._queue.received

    @property
    def queue_dropped(self) -> int:
        return self._queue.dropped

    @property
    def rpm(self) -> float | None:
        advance, span = self._spin
        if span < 1_000_000:
            return None
        return advance / 36_000 / (span * 1e-9) * 60.0

    # -- the link ---------------------------------------------------------------------

    def bind(self) -> None:
        """Bind the port and start the reader (``open`` does it if needed);
        DeviceError if the port cannot be bound, naming it as in use if another
        socket (another dronetrack live or info) holds it."""
        if self._closed:
            raise DeviceError(f"{self.name}: the client is closed")
        if self._sock is not None:
            return
        e = self.endpoint
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            # no SO_REUSEADDR: a second listener would take every unicast packet
            # (``livox_net``); it is refused instead
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4 << 20)
            sock.bind((e.bind_ip, e.port))
        except OSError as exc:
            sock.close()
            if port_in_use(exc):
                raise DeviceError(f"{self.name}: UDP port {e.port} {PORT_IN_USE}") from exc
            raise DeviceError(f"{self.name}: cannot bind the port: {exc}") from exc
        sock.settimeout(POLL_S)
        self._sock = sock
        self._thread = threading.Thread(target=self._read_loop, name="velodyne-reader", daemon=True)
        self._thread.start()

    def open(self, timeout_s: float = 3.0) -> None:
        """Listen, and wait for the first packet; DeviceError if none comes within
        ``timeout_s`` or the port cannot be bound."""
        if self._opened_at is not None:
            return
        self.bind()
        self._opened_at = time.monotonic()
        if not self._first.wait(timeout_s):
            self.close()
            raise DeviceError(
                f"{self.name}: no packet within {timeout_s:g} s (is the sensor's destination "
                f"this host's address, port {self.endpoint.port}?)"
            )

    def _read_loop(self) -> None:
        sock = self._sock
        assert sock is not None
        want = self.endpoint.device_ip
        while not self._stop.is_set():
            try:
                buf, (ip, _) = sock.recvfrom(MAX_DATAGRAM)
            except TimeoutError:
                continue
            except OSError:
                return
            if want is not None and ip != want:
                self.packets_ignored += 1
                continue
            if self.source_ip is None:
                self.source_ip = str(ip)
            self._queue.put(buf)
            self._first.set()

    def _check(self) -> None:
        since = self._opened_at
        if since is not None and self._queue.empty():
            quiet = time.monotonic() - max(since, self._queue.last_arrival)
            if quiet > self.stall_s:
                raise DeviceError(f"{self.name}: no data packet for {quiet:.1f} s")

    def packets(self, timeout_s: float = 0.1) -> list[bytes]:
        """The packets received so far (waiting up to ``timeout_s`` for the first);
        DeviceError if none came for ``stall_s``."""
        if self._opened_at is None or self._closed:
            raise DeviceError(f"{self.name}: not listening (call open)")
        return self._queue.take(timeout_s, self._check)

    def read(self, timeout_s: float = 0.1) -> PointBatch:
        """``decode(packets(timeout_s))``."""
        return self.decode(self.packets(timeout_s))

    def close(self) -> None:
        """Stop the reader and close the socket; safe to call more than once."""
        if self._closed:
            return
        self._closed = True
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        if self._sock is not None:
            self._sock.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- decoding ---------------------------------------------------------------------

    def decode(self, packets: Sequence[bytes]) -> PointBatch:
        """The points of ``packets`` (module docstring), sorted by time; malformed
        packets are skipped and counted."""
        heads, ok = fv.decode_packets(packets)
        self.packets_malformed += int((~ok).sum())
        if len(heads) == 0:
            return _empty()
        self._check_product(heads.product)
        mode = heads.return_mode
        self.return_mode = int(mode[-1])
        span = np.where(mode == fv.DUAL, 12, 24).astype(np.int64) * fv.FIRING_CYCLE_NS
        t_pkt = self._clock.times_ns(heads.stamp_us, span)
        self.packets_lost = self._clock.lost
        offsets = np.stack([_offsets(int(m)) for m in mode])  # (n, 12, 32)
        block_t = (t_pkt[:, None] + offsets[:, :, 0]).ravel()
        order = np.argsort(block_t, kind="stable")
        self._count_spin(block_t[order], heads.azimuth.ravel()[order])
        cuts = self._cuts.cuts(block_t[order], heads.azimuth.ravel()[order])
        good = [p for p, k in zip(packets, ok, strict=True) if k]
        xyz, t_ns, refl, line = self._points(good, heads.stamp_us, t_pkt)
        if self.rotation is not None:
            xyz = xyz @ self.rotation.T  # p = R p_head, row vectors
        srt = np.argsort(t_ns, kind="stable")
        last = t_pkt + offsets[:, -1, -1]
        return PointBatch(
            xyz[srt],
            t_ns[srt],
            refl[srt],
            line[srt],
            firings=(int(t_pkt.min()), int(last.max())),
            cuts=tuple(cuts),
        )

    def _check_product(self, product: NDArray[np.uint8]) -> None:
        other = product[product != fv.VLP16]
        if len(other):
            p = int(other[0])
            what = fv.PRODUCTS.get(p, "an unknown product")
            raise DeviceError(
                f"{self.name}: the packets come from a {what} (product ID 0x{p:02X}); "
                f"velodyne:// reads a VLP-16 (0x{fv.VLP16:02X})"
            )
        self.product = int(product[-1])

    def _count_spin(self, t: NDArray[np.int64], azimuth: NDArray[np.uint16]) -> None:
        if self._last_block is not None:
            t = np.r_[self._last_block[0], t]
            azimuth = np.r_[self._last_block[1], azimuth]
        self._last_block = (int(t[-1]), int(azimuth[-1]))
        advance, span = spin_advance(t, azimuth)
        self._spin[0] += advance
        self._spin[1] += span

    def _points(
        self, packets: list[bytes], stamp_us: NDArray[np.int64], t_pkt: NDArray[np.int64]
    ) -> tuple[FloatArray, NDArray[np.int64], NDArray[np.uint8], NDArray[np.uint8]]:
        """velodyne-decoder's points of ``packets``, one call per hour of their stamps
        (its relative times do not cross an hour), with their times on our clock."""
        vd = self._vd
        hour = t_pkt // (fv.HOUR_US * 1000)
        cuts = np.flatnonzero(np.diff(hour)) + 1
        parts = []
        for seg in np.split(np.arange(len(packets)), cuts):
            vec = vd.PacketVector()
            for i in seg:
                # the host stamp (s) in the packet's own hour, so the decoder keeps that hour
                vec.append(vd.VelodynePacket(float(stamp_us[i]) * 1e-6, packets[i]))
            _, pts = self._decoder.decode(vec)
            pts = np.asarray(pts, np.float64).reshape(-1, 8)
            t0 = int(t_pkt[seg[0]])
            parts.append((pts, t0 + np.rint(pts[:, 4] * 1e9).astype(np.int64)))
        pts = np.concatenate([p for p, _ in parts])
        t_ns = np.concatenate([t for _, t in parts])
        ring = np.clip(pts[:, 6].astype(np.int64), 0, fv.LASERS - 1)
        line = np.asarray(fv.LASER_OF_RING, np.uint8)[ring]
        refl = np.clip(np.rint(pts[:, 3]), 0, 255).astype(np.uint8)
        return np.ascontiguousarray(pts[:, :3]), t_ns, refl, line


@functools.cache
def _offsets(return_mode: int) -> NDArray[np.int64]:
    """``fv.firing_offsets_ns``, made once per return mode."""
    return fv.firing_offsets_ns(return_mode)


def _empty() -> PointBatch:
    u8 = np.zeros(0, np.uint8)
    return PointBatch(np.zeros((0, 3)), np.zeros(0, np.int64), u8, u8)
