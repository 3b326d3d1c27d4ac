"""An emulated Livox SDK 2 LiDAR (Mid-360) on UDP, streaming given points.

The device side of the link ``sources.livox.sdk2`` drives, as the Mid-360 protocol
document (livox_wiki_en ``livox_eth_protocol_mid360.md``) describes it:

- discovery: a request 0x0000 to its detection socket (port 56000 on a real device)
  gets an ACK with ret_code 0, device type 9 (Mid-360), serial number, the device's
  IP and its command port.  A real device broadcasts this ACK; the emulator sends it
  to the requester, which on loopback is the same;
- commands to its command socket (56100) get an ACK of the same sequence number,
  sender LiDAR, to the address they came from:
  0x0100 sets parameters: keys 0x0005, 0x0006, 0x0007 (where status pushes, points
  and IMU data go), 0x0000 (point data type 1, 2 or 3), 0x001A (work_tgt_mode:
  0x01 SAMPLING starts the stream, refused with ret_code 0x02 "not permitted now"
  while no point destination is set; 0x02 IDLE stops it) and 0x001C (IMU on/off,
  kept but unused: the emulator sends no IMU data).  Keys are applied in order up
  to the first that fails; the ACK names it (ret_code 0x20 unsupported key, 0x22
  read-only, 0x23 bad length, 0x03 out of range).
  0x0101 queries answer ret_code 0 and the keys it knows (0x0000, 0x001A, and the
  read-only 0x8000 serial number, 0x8001 product info, 0x8002 firmware
  ``version_app``, 0x8003 loader and 0x8004 hardware versions, 0x8005 MAC, 0x8006
  current work state), leaving out the others.
  Frames that do not decode are counted and get no reply;
- every ``push_period_s`` (1 s) it pushes its status (0x0102, a request from the
  LiDAR: work state and data type) from its push socket (56200) to the status host.

A fresh emulator is IDLE (0x02) with no destinations: it sends nothing until a host
configures it.  There is no host time-out (SDK 2 has no heartbeat).

While sampling, it streams its source as ``livox_stream.StreamingDevice`` does from
its point socket (56300) at 200,000 points/s (Δt = 5 µs, the Mid-360's point rate
on Livox's specification), 96 points a packet (the document's N for every point
data type): 2,083 packets/s, each spanning 95 · 5 µs (time_interval 4750).  Device
time is ns since sampling started, time type 0.  Point-cloud frames of
``frame_period_ns`` (100 ms) count the packets: packet p, first point at p·P
(P = 96 · Δt), is in frame f = ⌊p·P / T⌋, with frame_cnt = f mod 256 and udp_cnt =
p − ⌈f·T / P⌉ its index in the frame (cleared at each frame start, as the document
says).

Test hooks: ``drop_every`` and ``paused`` (``livox_stream``), and ``answer_commands``
= False ignores every command and stops the status pushes.
"""

from __future__ import annotations

import socket
import time

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError
from dronetrack.formats.livox import sdk2 as s2
from dronetrack.formats.livox import sdk2_control as c2
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.emulate.livox_stream import PointSource, StreamingDevice, bound_udp

__all__ = ["MID360", "MID360_POINT_INTERVAL_NS", "EmulatedLivox2"]

MID360 = 9  # livox_lidar_def.h kLivoxLidarTypeMid360
MID360_POINT_INTERVAL_NS = 5_000  # 200,000 points/s
FRAME_PERIOD_NS = 100_000_000  # 10 Hz point-cloud frames
_HOST_KEYS = (c2.KEY_STATE_HOST, c2.KEY_POINT_HOST, c2.KEY_IMU_HOST)
_READ_ONLY = c2.INFO_KEYS
PRODUCT_INFO = "Mid-360 emulated"  # the document's example: "Mid-360 2021/12/01"
MAC = bytes([0x02, 0, 0, 0, 0x03, 0x60])  # a locally administered address (bit 1 set)


class EmulatedLivox2(StreamingDevice):
    """A Livox Mid-360 on ``ip`` streaming the points of ``source`` (see PointSource).

    Its detection, command, push and point sockets bind ``discovery_port``,
    ``cmd_port``, ``push_port`` and ``point_port`` (0: a free port; ``address`` and
    ``discovery_address`` tell which).  It reports ``serial`` (discovery, key 0x8000)
    and ``firmware`` (key 0x8002).  ``start`` runs it in a background thread;
    ``close`` stops it within about 1 s.  Counters: ``commands_received``,
    ``commands_malformed``, ``commands_unknown``, ``discoveries_answered``,
    ``queries_answered``, ``pushes_sent``, ``packets_sent``, ``packets_dropped``,
    ``points_built``, ``points_dropped``.
    """

    def __init__(
        self,
        source: PointSource,
        *,
        ip: str = "127.0.0.1",
        discovery_port: int = c2.DISCOVERY_PORT,
        cmd_port: int = c2.CMD_PORT,
        push_port: int = c2.PUSH_PORT,
        point_port: int = c2.POINT_PORT,
        serial: str = "0EMULATEDMID360",
        firmware: tuple[int, int, int, int] = (0, 1, 0, 0),
        data_type: int = 1,
        push_period_s: float = 1.0,
        frame_period_ns: int = FRAME_PERIOD_NS,
    ) -> None:
        if len(serial.encode("ascii")) > 16:
            raise ConfigError(f"a serial number has at most 16 characters: {serial!r}")
        if len(firmware) != 4 or not all(0 <= v <= 255 for v in firmware):
            raise ConfigError(f"a firmware version is four bytes, got {firmware!r}")
        if data_type not in s2.LAYOUTS:
            raise ConfigError(f"the Mid-360's point data types are 1, 2, 3, not {data_type}")
        super().__init__(source, MID360_POINT_INTERVAL_NS, s2.POINTS_PER_PACKET)
        self.ip = ip
        self.serial = serial
        self.firmware = firmware
        self.data_type = data_type
        self.push_period_s = push_period_s
        self.frame_period_ns = frame_period_ns
        self.answer_commands = True  # test hook
        self.discoveries_answered = 0
        self.queries_answered = 0
        self.pushes_sent = 0
        self.hosts: dict[int, c2.HostIpConfig] = {}  # key 0x0005/6/7 → its destination
        self.imu_enabled = True
        socks: list[socket.socket] = []
        try:
            for port, what in (
                (discovery_port, "discovery"),
                (cmd_port, "commands"),
                (push_port, "status pushes"),
                (point_port, "point data"),
            ):
                # the host binds the detection port too (0.0.0.0:56000): it is shared
                socks.append(bound_udp(ip, port, what, shared=what == "discovery"))
        except BaseException:
            for sock in socks:
                sock.close()
            raise
        self._detect, self._cmd, self._push, self._points = socks
        self._push_seq = 0
        self._next_push = time.monotonic()

    @property
    def address(self) -> tuple[str, int]:
        """(ip, port) of the command socket."""
        return _name(self._cmd)

    @property
    def discovery_address(self) -> tuple[str, int]:
        """(ip, port) of the detection socket."""
        return _name(self._detect)

    @property
    def work_state(self) -> int:
        return c2.WORK_MODE_SAMPLING if self.sampling else c2.WORK_MODE_IDLE

    def _sockets(self) -> list[socket.socket]:
        return [self._detect, self._cmd, self._push, self._points]

    def _tick(self, now: float) -> float:
        wait = super()._tick(now)
        status = self.hosts.get(c2.KEY_STATE_HOST)
        if status is None or not self.answer_commands:
            return wait
        if now >= self._next_push:
            self._push_status(status)
            self._next_push = now + self.push_period_s
        return min(wait, self._next_push - now)

    def _push_status(self, status: c2.HostIpConfig) -> None:
        self._push_seq += 1
        data = c2.encode_key_values(
            [
                (c2.KEY_WORK_STATE, bytes([self.work_state])),
                (c2.KEY_DATA_TYPE, bytes([self.data_type])),
            ]
        )
        frame = c2.CommandFrame(c2.PUSH, c2.REQ, self._push_seq, data, sender=c2.LIDAR)
        try:
            self._push.sendto(c2.encode_frame(frame), (status.host_ip, status.host_port))
            self.pushes_sent += 1
        except OSError:
            pass  # no route: try again next period

    # -- commands ---------------------------------------------------------------------

    def _reply(self, sock: socket.socket, buf: bytes) -> bytes | None:
        frame = c2.decode_frame(buf)
        if not self.answer_commands:
            return None
        data: bytes | None = None
        if frame.cmd_type == c2.REQ and sock is self._detect and frame.cmd_id == c2.DISCOVERY:
            ip, port = self.address
            data = c2.DiscoveryAck(0, MID360, self.serial, ip, port).encode()
            self.discoveries_answered += 1
        elif frame.cmd_type == c2.REQ and sock is self._cmd:
            if frame.cmd_id == c2.SET_PARAMS:
                data = self._set(c2.decode_key_values(frame.payload)).encode()
            elif frame.cmd_id == c2.QUERY_PARAMS:
                data = self._query(c2.decode_key_list(frame.payload)).encode()
                self.queries_answered += 1
        if data is None:
            self.commands_unknown += 1
            return None
        ack = c2.CommandFrame(frame.cmd_id, c2.ACK, frame.seq, data, sender=c2.LIDAR)
        return c2.encode_frame(ack)

    def _set(self, items: list[tuple[int, bytes]]) -> c2.ParamAck:
        """Apply the keys in order up to the first that fails."""
        for key, value in items:
            ret = self._set_one(key, value)
            if ret != c2.RET_OK:
                return c2.ParamAck(ret, key)
        return c2.ParamAck(c2.RET_OK)

    def _set_one(self, key: int, value: bytes) -> int:
        if key in _READ_ONLY:
            return c2.RET_READ_ONLY
        if key not in (*_HOST_KEYS, c2.KEY_DATA_TYPE, c2.KEY_WORK_MODE, c2.KEY_IMU_ENABLE):
            return c2.RET_KEY_UNSUPPORTED
        if len(value) != (8 if key in _HOST_KEYS else 1):
            return c2.RET_BAD_LENGTH
        if key in _HOST_KEYS:
            self.hosts[key] = c2.HostIpConfig.decode(value)
            return c2.RET_OK
        v = value[0]
        if key == c2.KEY_DATA_TYPE:
            if v not in s2.LAYOUTS:
                return c2.RET_OUT_OF_RANGE
            self.data_type = v
        elif key == c2.KEY_IMU_ENABLE:
            self.imu_enabled = bool(v)
        elif v == c2.WORK_MODE_SAMPLING:
            if c2.KEY_POINT_HOST not in self.hosts:
                return c2.RET_NOT_PERMITTED
            self._start_stream(time.monotonic())
        elif v == c2.WORK_MODE_IDLE:
            self.sampling = False
        else:
            return c2.RET_OUT_OF_RANGE
        return c2.RET_OK

    def _query(self, keys: list[int]) -> c2.QueryAck:
        known = {
            c2.KEY_DATA_TYPE: bytes([self.data_type]),
            c2.KEY_WORK_MODE: bytes([self.work_state]),
            c2.KEY_SERIAL: self.serial.encode("ascii").ljust(16, b"\0"),
            c2.KEY_PRODUCT_INFO: PRODUCT_INFO.encode("ascii").ljust(64, b"\0"),
            c2.KEY_VERSION_APP: bytes(self.firmware),
            c2.KEY_VERSION_LOADER: bytes([0, 1, 0, 0]),
            c2.KEY_VERSION_HARDWARE: bytes([0, 0, 0, 1]),
            c2.KEY_MAC: MAC,
            c2.KEY_WORK_STATE: bytes([self.work_state]),
        }
        return c2.QueryAck(c2.RET_OK, tuple((k, known[k]) for k in keys if k in known))

    # -- points -----------------------------------------------------------------------

    def _data_target(self) -> tuple[str, int] | None:
        host = self.hosts.get(c2.KEY_POINT_HOST)
        return None if host is None else (host.host_ip, host.host_port)

    def _data_socket(self) -> socket.socket:
        return self._points

    def _encode(self, xyz: FloatArray, refl: NDArray[np.uint8], first_packet: int) -> list[bytes]:
        n, dt, T = self.firings_per_packet, self.point_interval_ns, self.frame_period_ns
        P = n * dt  # ns a packet spans
        packets = s2.encode_point_packets(
            xyz, refl, data_type=self.data_type, t0_ns=first_packet * P, point_interval_ns=dt
        )
        out = []
        for i, packet in enumerate(packets):
            p = first_packet + i
            f = p * P // T  # the frame of the packet's first point
            udp_cnt = p + (f * T // -P)  # p − ⌈f·T / P⌉
            # udp_cnt and frame_cnt lie outside the CRC-32 (timestamp and data)
            out.append(packet[:7] + udp_cnt.to_bytes(2, "little") + bytes([f & 0xFF]) + packet[10:])
        return out


def _name(sock: socket.socket) -> tuple[str, int]:
    ip, port = sock.getsockname()[:2]
    return str(ip), int(port)
