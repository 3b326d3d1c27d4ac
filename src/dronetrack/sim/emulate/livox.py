"""An emulated Livox SDK 1 LiDAR (Avia or Mid-40) on UDP, streaming given points.

The device side of the link ``sources.livox.sdk1`` drives (Livox-SDK
``sdk_core/src/device_discovery.cpp``, ``command_handler/command_channel.cpp``):

- it binds its command socket on (ip, device_port) (65000 on a real device) and,
  while no host is connected, broadcasts its broadcast code and device type
  (command 0x00, cmd_type MSG) from that socket every ``broadcast_period_s`` to
  ``broadcast_to`` (the host's port 55000; 255.255.255.255 on a real network);
- it answers every command with an ACK frame of the same sequence number to the
  address the command came from: handshake (0x01, accepted with cmd_type CMD or ACK,
  as the SDK sends it with ACK) stores the host's IP and ports, ret_code 0 (1 if
  another host holds the device); heartbeat (0x03) ret_code 0, state 1 (normal);
  sampling (0x04) starts or stops the stream (ret_code 1 with no host); device
  information (0x02) ret_code 0 and ``firmware`` (four bytes); disconnect
  (0x06) forgets the host.  Frames that do not decode are ignored and counted;
- it forgets a host that sent no heartbeat for ``host_timeout_s`` (3 s).

While sampling, it streams its source as ``livox_stream.StreamingDevice`` does, firing
once per Δt (4 167 ns Avia, 10 000 ns Mid-40: livox_ros_driver ``lds.h``) with
timestamp type 0 (no sync), n firings a packet (96 for data type 2, the Avia's; 100
for data type 0, the Mid-40's).

Test hooks: ``drop_every`` and ``paused`` (``livox_stream``), and
``answer_heartbeats`` = False ignores heartbeats.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError
from dronetrack.formats.livox import sdk1 as s1
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.emulate.livox_stream import (
    GridSource,
    PointChunk,
    PointSource,
    StreamingDevice,
    bound_udp,
    frame_chunks,
    grid_points,
)

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


@dataclass
class _Host:
    ip: str
    cmd_port: int
    data_port: int
    last_heartbeat: float


class EmulatedLivox(StreamingDevice):
    """A Livox SDK 1 device on (ip, device_port) streaming the points of ``source``
    (see PointSource).

    ``dev_type`` 7 (Avia, data type 2) or 1 (Mid-40, data type 0); ``device_port`` 0
    takes a free port (``address`` tells which).  ``start`` runs it in a background
    thread; ``close`` stops it within about 1 s.  ``clock`` (seconds; time.monotonic by
    default) is the device's: its stream, broadcasts and heartbeats are timed on it.
    Counters: ``commands_received``, ``commands_malformed``, ``commands_unknown``,
    ``broadcasts_sent``, ``heartbeats_answered``, ``packets_sent``, ``packets_dropped``,
    ``points_built``, ``points_dropped``.
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
        firmware: tuple[int, int, int, int] = (3, 0, 0, 0),
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if dev_type not in DATA_TYPE:
            raise ConfigError(f"the emulated Livox is an Avia (7) or a Mid-40 (1), not {dev_type}")
        if len(broadcast_code.encode("ascii")) > 15:
            raise ConfigError(f"a broadcast code has at most 15 characters: {broadcast_code!r}")
        self.dev_type = dev_type
        self.data_type = DATA_TYPE[dev_type]
        super().__init__(
            source,
            s1.POINT_INTERVAL_NS[dev_type],
            s1.POINTS_PER_PACKET[self.data_type],
            clock=clock,
        )
        self.broadcast_to = broadcast_to
        self.broadcast_code = broadcast_code
        self.broadcast_period_s = broadcast_period_s
        self.host_timeout_s = host_timeout_s
        self.firmware = firmware
        self.answer_heartbeats = True  # test hook
        self.broadcasts_sent = 0
        self.heartbeats_answered = 0
        self.host: _Host | None = None
        self._sock = bound_udp(ip, device_port, "commands")
        self._bseq = 0
        self._next_broadcast = self.clock()

    @property
    def address(self) -> tuple[str, int]:
        """(ip, port) of the command socket."""
        ip, port = self._sock.getsockname()[:2]
        return str(ip), int(port)

    def _sockets(self) -> list[socket.socket]:
        return [self._sock]

    def _tick(self, now: float) -> float:
        wait = super()._tick(now)
        if self.host is None and self.broadcast_to is not None:
            if now >= self._next_broadcast:
                self._broadcast()
                self._next_broadcast = now + self.broadcast_period_s
            wait = min(wait, self._next_broadcast - now)
        host = self.host
        if host is not None and now - host.last_heartbeat > self.host_timeout_s:
            self.host, self.sampling = None, False  # the host went silent
        return wait

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

    def _reply(self, sock: socket.socket, buf: bytes) -> bytes | None:
        frame = s1.decode_frame(buf)
        payload = self._answer(frame)
        if payload is None:
            return None
        ack = s1.CommandFrame(s1.ACK, frame.seq, s1.SET_GENERAL, frame.cmd_id, payload)
        return s1.encode_frame(ack)

    def _answer(self, frame: s1.CommandFrame) -> bytes | None:
        """The ACK payload for ``frame``, or None to stay silent; DecodeError if its
        payload does not decode."""
        now = self.clock()
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
        if cid == s1.DEVICE_INFO:
            return s1.DeviceInfoAck(0, self.firmware).encode()
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
            if start:
                self._start_stream(now)
            else:
                self.sampling = False
            return bytes([0])
        if cid == s1.DISCONNECT:
            self.host, self.sampling = None, False
            return bytes([0])
        self.commands_unknown += 1
        return None

    # -- points -----------------------------------------------------------------------

    def _data_target(self) -> tuple[str, int] | None:
        host = self.host
        return None if host is None else (host.ip, host.data_port)

    def _data_socket(self) -> socket.socket:
        return self._sock

    def _encode(self, xyz: FloatArray, refl: NDArray[np.uint8], first_packet: int) -> list[bytes]:
        dt = self.point_interval_ns
        t0_ns = first_packet * self.firings_per_packet * dt
        return s1.encode_point_packets(
            xyz, refl, data_type=self.data_type, t0_ns=t0_ns, point_interval_ns=dt
        )
