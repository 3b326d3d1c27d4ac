"""A live Livox SDK 2 LiDAR (Mid-360) over UDP, host side.

The link, as the Mid-360 protocol document (livox_wiki_en
``livox_eth_protocol_mid360.md``) and Livox-SDK2 (``sdk_core/device_manager.cpp``,
``command_handler/*.cpp``) run it:

1. discovery (command 0x0000): the host sends the request from its detection socket
   to the LiDAR's port 56000 (the SDK broadcasts it to 255.255.255.255 every second
   from a socket bound to 56000); the LiDAR answers with return code, device type
   (9: Mid-360), serial number, IP and command port (by broadcast, so that a host on
   another subnet still hears it);
2. configuration (0x0100 with keys 0x0005, 0x0006, 0x0007): the host's IP and the
   ports the status pushes, point data and IMU data go to, and key 0x0000 when a
   point data type is asked for (the SDK: ``build_request.cpp``
   BuildUpdateMid360LidarCfgRequest); the ACK's ret_code must be 0;
3. start: 0x0100 with work_tgt_mode (key 0x001A) = 0x01 SAMPLING; stop: 0x02 IDLE
   (document "LiDAR Working Status", ``livox_lidar_def.h`` LivoxLidarWorkMode);
4. keep-alive: SDK 2 has no heartbeat command.  The LiDAR pushes its status
   (0x0102, a request from the LiDAR) to the status port, and the SDK times out
   each command after 1 s (``comm/define.h`` KDefaultTimeOut).  This client asks
   for the current work state (0x0101 query of key 0x8006) every
   ``heartbeat_period_s`` and counts the link dead after ``heartbeat_timeout_s``
   with neither an answer nor a status push; ``work_state`` keeps the last one seen;
5. device information (``query_info``, for ``dronetrack info``): a 0x0101 query of
   the read-only keys 0x8000-0x8006: serial number, product info, firmware
   (``version_app``), loader and hardware versions, MAC, work state.

Ports: the status pushes go to the host's command port (default 56101) and the IMU
packets to its point port (default 56301), so one socket takes ACKs and pushes and
another all data (``decode`` skips IMU samples); the document lets the host choose
all of them.  Discovery is optional, as for SDK 1: without an answer within
``discover_s`` the client configures the device at its command port 56100.

Points.  Each packet stamps its first point (u64 ns for every time type) and spans
``time_interval`` (0.1 µs) from first to last point, the points equally spaced:

    t_i = timestamp + i · time_interval · 100 ns / (dot_num − 1)

``line`` is the point's index in its packet modulo 4, the Mid-360's lines
(livox_ros_driver2 ``pub_handler.cpp``, ``kLineNumberMid360``).

Loss.  ``udp_cnt`` counts the packets, cleared to 0 at the start of each point-cloud
frame, which ``frame_cnt`` counts (document, point cloud format).  For consecutive
point packets of one data type

    lost = udp_cnt − udp_cnt_prev − 1   in one frame (when udp_cnt > udp_cnt_prev)
    lost = udp_cnt                      when frame_cnt changed

and 0 for a counter that went back (a frame start that frame_cnt, "invalid for
non-repeating scans", does not show).  Packets lost at the end of a frame, or at the
very end of the stream, cannot be seen.
"""

from __future__ import annotations

import contextlib
import socket
import struct
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Unpack

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError, DecodeError, DeviceError
from dronetrack.formats.livox import sdk2 as s2
from dronetrack.formats.livox import sdk2_control as c2
from dronetrack.sources.assembly import PointBatch
from dronetrack.sources.livox.link import LinkOptions, LivoxLink
from dronetrack.sources.livox.points import hits_in_time_order
from dronetrack.sources.livox.uri import parse_device_uri
from dronetrack.sources.udp import MAX_DATAGRAM

__all__ = ["Livox2Client", "Livox2Endpoint", "parse_livox2_uri"]

HOST_CMD_PORT, HOST_POINT_PORT = 56101, 56301  # define.h kMid360HostCmdPort, …PointCloudPort
ACK_WAIT_S = 1.0  # the SDK's command timeout (define.h KDefaultTimeOut = 1000 ms)
DISCOVERY_RESEND_S = 0.5  # the SDK asks every 1 s; twice as often finds the device sooner
LINES = 4  # livox_ros_driver2 comm.h kLineNumberMid360
DEVICE_TYPES = {9: "Mid-360", 10: "HAP", 35: "Mid-360s", 40: "Avia2"}  # livox_lidar_def.h
POINT_HEADER = struct.Struct("<BHHHHBB")  # version, length, interval, dot_num, udp_cnt, frame, type


@dataclass(frozen=True)
class Livox2Endpoint:
    """Where a Livox SDK 2 device and this host talk: the device's IP, the host's IP
    (None: the address the host routes to the device from), the host's command and
    point ports (0: any free port), the host's discovery port, the device's command
    and discovery ports, whether discovery is also broadcast, and the point data type
    to ask for (None: the device's own)."""

    device_ip: str
    host_ip: str | None = None
    cmd_port: int = HOST_CMD_PORT
    point_port: int = HOST_POINT_PORT
    discovery_port: int = c2.DISCOVERY_PORT
    device_port: int = c2.CMD_PORT
    device_discovery_port: int = c2.DISCOVERY_PORT
    broadcast: bool = True
    data_type: int | None = None


# query key → lowest port it takes (0: any free port)
_PORT_KEYS = {
    "cmd_port": 0,
    "point_port": 0,
    "discovery_port": 0,
    "device_port": 1,
    "device_discovery_port": 1,
}

_CHOICE_KEYS: dict[str, dict[str, object]] = {
    "broadcast": {"0": False, "1": True},
    "data_type": {"1": 1, "2": 2, "3": 3},
}


def parse_livox2_uri(uri: str) -> Livox2Endpoint:
    """``livox2://IP[?host=IP&cmd_port=N&point_port=N&discovery_port=N&device_port=N
    &device_discovery_port=N&broadcast=0|1&data_type=1|2|3]``; ConfigError naming the
    problem."""
    fields = parse_device_uri(uri, "livox2", "SDK 2", _PORT_KEYS, _CHOICE_KEYS)
    return Livox2Endpoint(**fields)  # type: ignore[arg-type]


class Livox2Client(LivoxLink):
    """Host side of one Livox SDK 2 device (Mid-360): ``open``, then ``read`` (or
    ``packets`` and ``decode``) repeatedly, then ``close`` (or use it as a context
    manager).

    Options (``LinkOptions``) as LivoxLink says; the keep-alive is the work-state
    query, and a status push answers it as well.

    Counters: ``packets_received``, ``packets_malformed`` (counted when decoded),
    ``packets_lost`` (from ``udp_cnt``, see the module docstring), ``queue_dropped``,
    ``heartbeats_sent``, ``heartbeats_missed``, ``pushes_received``.
    """

    sdk = "SDK 2 device"
    device_types = DEVICE_TYPES
    connect_name = "host configuration"
    data_key = "point_port"
    keepalive_name = "work-state"
    ack_wait_s = ACK_WAIT_S

    def __init__(self, endpoint: Livox2Endpoint | str, **options: Unpack[LinkOptions]) -> None:
        self.endpoint = parse_livox2_uri(endpoint) if isinstance(endpoint, str) else endpoint
        if self.endpoint.data_type not in (None, *s2.LAYOUTS):
            raise ConfigError(f"point data type {self.endpoint.data_type} is not 1, 2 or 3")
        super().__init__(self.endpoint.device_ip, self.endpoint.host_ip, **options)
        self.serial: str | None = None
        self.work_state: int | None = None
        self.pushes_received = 0
        self._device_cmd_port = self.endpoint.device_port
        self._last_count: dict[int, tuple[int, int]] = {}  # data type → (frame_cnt, udp_cnt)

    # -- names and ports ------------------------------------------------------------

    @property
    def discovery_port(self) -> int:
        return self._port("discovery")

    @property
    def point_port(self) -> int:
        return self._port("data")

    # -- the protocol ---------------------------------------------------------------

    def _ports(self) -> tuple[int, int, int]:
        return self.endpoint.discovery_port, self.endpoint.cmd_port, self.endpoint.point_port

    def _device_address(self) -> tuple[str, int]:
        return self.endpoint.device_ip, self._device_cmd_port

    def _discover(self, until: float) -> None:
        ep = self.endpoint
        sock = self._socks["discovery"]
        request = c2.encode_frame(c2.CommandFrame(c2.DISCOVERY, c2.REQ, 1))
        targets = [(ep.device_ip, ep.device_discovery_port)]
        if ep.broadcast:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_BROADCAST, 1)
            targets.append(("255.255.255.255", ep.device_discovery_port))
        next_send = time.monotonic()
        while time.monotonic() < until:
            if time.monotonic() >= next_send:
                for target in targets:
                    with contextlib.suppress(OSError):  # no route: only the other target
                        sock.sendto(request, target)
                next_send = time.monotonic() + DISCOVERY_RESEND_S
            try:
                buf, (ip, _) = sock.recvfrom(MAX_DATAGRAM)
            except TimeoutError:
                continue
            try:
                frame = c2.decode_frame(buf)
                if (frame.cmd_id, frame.cmd_type) != (c2.DISCOVERY, c2.ACK):
                    continue  # e.g. our own broadcast request coming back
                ack = c2.DiscoveryAck.decode(frame.payload)
            except DecodeError:
                continue
            if ack.ret_code == 0 and ep.device_ip in (ip, ack.lidar_ip):
                self.dev_type, self.serial = ack.dev_type, ack.serial
                self._device_cmd_port = ack.cmd_port
                return

    def _encode_command(self, cmd_id: int, payload: bytes, seq: int, cmd_type: int | None) -> bytes:
        kind = c2.REQ if cmd_type is None else cmd_type
        return c2.encode_frame(c2.CommandFrame(cmd_id, kind, seq, payload))

    def _parse_reply(self, buf: bytes) -> tuple[bool, int, bytes] | None:
        frame = c2.decode_frame(buf)
        if frame.cmd_type == c2.REQ and frame.cmd_id == c2.PUSH:  # the LiDAR's status
            self.pushes_received += 1
            self._note_state(c2.decode_key_values(frame.payload))
            return True, frame.seq, b""
        if frame.cmd_type != c2.ACK:
            return None
        if frame.cmd_id == c2.QUERY_PARAMS:
            ack = c2.QueryAck.decode(frame.payload)
            if ack.ret_code == 0:
                # any answered query shows the link alive; the ACK still goes to a
                # caller waiting for it (query_info)
                self._keepalive_answered()
                self._note_state(list(ack.items))
        return False, frame.seq, frame.payload

    def _note_state(self, items: list[tuple[int, bytes]]) -> None:
        for key, value in items:
            if key == c2.KEY_WORK_STATE and len(value) == 1:
                self.work_state = value[0]

    def _connect_command(self) -> tuple[int, bytes, int | None]:
        assert self.host_ip is not None
        # status pushes to the command port, IMU packets to the point port
        cmd, point = self.cmd_port, self.point_port
        hosts = c2.host_config_request(self.host_ip, cmd, point, point, work_mode=None)
        items = c2.decode_key_values(hosts)
        if self.endpoint.data_type is not None:
            items.append((c2.KEY_DATA_TYPE, bytes([self.endpoint.data_type])))
        return c2.SET_PARAMS, c2.encode_key_values(items), None

    def _sampling_command(self, start: bool) -> tuple[int, bytes]:
        mode = c2.WORK_MODE_SAMPLING if start else c2.WORK_MODE_IDLE
        return c2.SET_PARAMS, c2.encode_key_values([(c2.KEY_WORK_MODE, bytes([mode]))])

    def query_info(self, timeout_s: float = 1.0) -> c2.DeviceInfo | None:
        """What the connected device says of itself: a parameter inquiry (0x0101) of
        serial number, product info, firmware (``version_app``, key 0x8002; Livox-SDK2
        ``QueryLivoxLidarFirmwareVer`` asks for it alone), loader and hardware versions,
        MAC and work state.  None if it does not answer within ``timeout_s``;
        DeviceError if it refuses or answers what does not decode."""
        if not self._connected:
            raise DeviceError(f"{self.name}: not connected (call connect or open)")
        query = c2.encode_key_list(list(c2.INFO_KEYS))
        ack = self._ask(c2.QUERY_PARAMS, query, time.monotonic() + timeout_s)
        if ack is None:
            return None
        try:
            answer = c2.QueryAck.decode(ack)
            if answer.ret_code != 0:
                raise DeviceError(
                    f"{self.name}: parameter inquiry refused, ret_code 0x{answer.ret_code:02X}"
                )
            return c2.DeviceInfo.from_items(answer.items)
        except DecodeError as exc:
            raise DeviceError(f"{self.name}: parameter inquiry: {exc}") from exc

    def _send_keepalive(self) -> None:
        self._send(c2.QUERY_PARAMS, c2.encode_key_list([c2.KEY_WORK_STATE]))

    def _count_loss(self, buf: bytes) -> None:
        """lost from the udp_cnt sequence (see the module docstring)."""
        if len(buf) < s2.HEADER_BYTES:
            return
        version, length, _, _, udp_cnt, frame_cnt, data_type = POINT_HEADER.unpack_from(buf)
        if version != 0 or length != len(buf) or data_type not in s2.LAYOUTS:
            return  # IMU packets (type 0) keep a count of their own; not checked
        prev = self._last_count.get(data_type)
        self._last_count[data_type] = (frame_cnt, udp_cnt)
        if prev is None:
            return
        prev_frame, prev_cnt = prev
        if frame_cnt != prev_frame:
            self.packets_lost += udp_cnt
        elif udp_cnt > prev_cnt:
            self.packets_lost += udp_cnt - prev_cnt - 1

    # -- decoding --------------------------------------------------------------------

    def decode(self, packets: Sequence[bytes]) -> PointBatch:
        """The points with a return in ``packets``, in time order, t_ns the device's
        int64 ns; malformed packets are skipped and counted in ``packets_malformed``,
        IMU packets skipped.  ``line``: the point's index in its packet mod 4.
        ``firings``: the first and last point's times in the point packets, with a
        return or not (None if no point packet decoded)."""
        good = [p for p in packets if s2.packet_problem(p) is None]
        self.packets_malformed += len(packets) - len(good)
        points = [p for p in good if p[10] != s2.IMU_DATA_TYPE]
        if not points:
            return hits_in_time_order([], [])
        decoded, _ = s2.decode_packets(points)
        counts = [int.from_bytes(p[5:7], "little") for p in points]
        line: NDArray[np.uint8] = np.concatenate(
            [np.arange(n, dtype=np.int64) % LINES for n in counts]
        ).astype(np.uint8)
        batch = hits_in_time_order([decoded.points], [line])
        t_ns = decoded.points.t_ns
        return replace(batch, firings=(int(t_ns.min()), int(t_ns.max())))
