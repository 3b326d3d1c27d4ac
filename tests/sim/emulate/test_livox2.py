"""The emulated Livox Mid-360 against command frames built here by hand from the
Mid-360 protocol document (``tests/livox_helpers.py``: ``struct.pack`` and a bitwise
CRC-16/CCITT-FALSE, never the codec's encoder); its replies and point packets are
read back with ``struct`` and their CRCs checked the same way.

Every socket is on 127.0.0.1 with a port the kernel picks, every wait is bounded."""

from __future__ import annotations

import socket
import struct
import time
import zlib

import numpy as np
import pytest

from dronetrack.errors import ConfigError
from dronetrack.sim.emulate.livox import GridSource, PointChunk, grid_points
from dronetrack.sim.emulate.livox2 import EmulatedLivox2
from dronetrack.sources.udp import udp_socket
from livox_helpers import (
    LOOP,
    assert_no_reply,
    ccitt_false,
    drain_then_silence,
    loopback_udp,
    port_of,
    sdk2_frame,
)

DT, N = 5_000, 96  # 200,000 points/s; 96 points a packet
P = DT * N  # ns a packet spans: 480 µs, 2083 packets/s


def parse(buf: bytes) -> tuple[int, int, int, int, bytes]:
    """(seq, cmd_id, cmd_type, sender, data) of a frame whose checks all hold."""
    sof, version, length, seq, cmd_id, cmd_type, sender = struct.unpack_from("<BBHIHBB", buf)
    assert (sof, version, length) == (0xAA, 0, len(buf))
    crc16, crc32 = struct.unpack_from("<HI", buf, 18)
    assert crc16 == ccitt_false(buf[:18])
    assert crc32 == (zlib.crc32(buf[24:]) if len(buf) > 24 else 0)
    return seq, cmd_id, cmd_type, sender, buf[24:]


def _device(source: object = None, **kw: object) -> EmulatedLivox2:
    src = GridSource(DT, 2.0) if source is None else source
    ports = {"discovery_port": 0, "cmd_port": 0, "push_port": 0, "point_port": 0}
    return EmulatedLivox2(src, **(ports | kw))  # type: ignore[arg-type]


def _ask(
    sock: socket.socket, to: tuple[str, int], request: bytes
) -> tuple[int, int, int, int, bytes]:
    sock.sendto(request, to)
    while True:  # skip status pushes (requests from the LiDAR) on the same socket
        reply = parse(sock.recv(2048))
        if reply[2] == 1:
            return reply


def _set(*items: tuple[int, bytes]) -> bytes:
    """0x0100 data: key_num, reserved, then {key, length, value}."""
    out = struct.pack("<HH", len(items), 0)
    for key, value in items:
        out += struct.pack("<HH", key, len(value)) + value
    return out


def _host(sock: socket.socket, lidar_port: int) -> bytes:
    # ip[4] dotted order, host port u16, LiDAR port u16
    return socket.inet_aton(LOOP) + struct.pack("<HH", port_of(sock), lidar_port)


def _configure(cmd: socket.socket, points: socket.socket, dev: EmulatedLivox2) -> None:
    data = _set((0x0005, _host(cmd, 56200)), (0x0006, _host(points, 56300)))
    assert _ask(cmd, dev.address, sdk2_frame(0x0100, 0, 7, data))[4] == b"\0\0\0"


def test_discovery_answers_type_serial_ip_and_commandport_of() -> None:
    probe = loopback_udp()
    with probe, _device() as dev:
        seq, cmd_id, cmd_type, sender, data = _ask(
            probe, dev.discovery_address, sdk2_frame(0x0000, 0, 41, b"")
        )
        assert (seq, cmd_id, cmd_type, sender) == (41, 0x0000, 1, 1)  # ACK from the LiDAR
        ret, dev_type, sn, ip, cmd_port = struct.unpack("<BB16s4sH", data)
        assert (ret, dev_type) == (0, 9)  # Mid-360
        assert sn == b"0EMULATEDMID360\0"
        assert socket.inet_ntoa(ip) == LOOP
        assert cmd_port == dev.address[1]


def test_a_host_on_the_same_machine_binds_the_detection_port_too() -> None:
    # Livox-SDK2 binds the host's detection socket to port 56000 on all interfaces
    # (device_manager.cpp, with port reuse), the port the LiDAR listens on: on one
    # machine the emulator shares it.  Its own address (127.0.0.3, not the host's
    # 127.0.0.1) keeps the answer, sent back to 127.0.0.1, away from its own socket.
    with _device(ip="127.0.0.3") as dev:
        port = dev.discovery_address[1]
        # 0.0.0.0:port, shared, as the client binds it
        with udp_socket(port, "discovery", shared=True) as host:
            host.settimeout(2.0)
            _seq, cmd_id, cmd_type, sender, data = _ask(
                host, dev.discovery_address, sdk2_frame(0x0000, 0, 5, b"")
            )
        assert (cmd_id, cmd_type, sender) == (0x0000, 1, 1)
        assert data[:2] == b"\x00\x09"  # ret_code 0, Mid-360
        assert dev.discoveries_answered == 1


def test_configuration_sampling_and_the_point_packets(
    host: tuple[socket.socket, socket.socket],
) -> None:
    cmd, points = host
    with _device() as dev:
        _configure(cmd, points, dev)
        # work_tgt_mode SAMPLING (0x01)
        start = sdk2_frame(0x0100, 0, 8, _set((0x001A, b"\x01")))
        assert _ask(cmd, dev.address, start)[:4] == (8, 0x0100, 1, 1)
        t0 = time.monotonic()
        packets = [points.recv(2048) for _ in range(400)]
        elapsed_ns = (time.monotonic() - t0) * 1e9
        for p, buf in enumerate(packets):
            version, length, interval, dot_num, udp_cnt, frame_cnt, data_type, time_type = (
                struct.unpack_from("<BHHHHBBB", buf)
            )
            # 96 Cartesian high points (14 B) after the 36-byte header; 95 gaps of 5 µs
            # in 0.1 µs; time type 0 (no sync); CRC-32 of timestamp and data
            assert (version, length, len(buf), interval, dot_num) == (0, 1380, 1380, 4750, 96)
            assert (data_type, time_type) == (1, 0)
            assert struct.unpack_from("<I", buf, 24)[0] == zlib.crc32(buf[28:])
            assert struct.unpack_from("<Q", buf, 28)[0] == p * P
            # frames of 100 ms: 0 for packets 0-208 (first point before 100 ms), then 1
            assert (frame_cnt, udp_cnt) == ((0, p) if p <= 208 else (1, p - 209))
        # packet p goes out once its first point's time p·P has come, never before
        assert elapsed_ns >= 399 * P - 5e6  # allowing the first packet's 5 ms head start
        x, y, z, refl, tag = struct.unpack_from("<iiiBB", packets[1], 36 + 14 * 5)
        k = N + 5
        assert (x, y, z) == tuple(np.rint(grid_points(np.array([k]))[0] * 1000).astype(int))
        assert (refl, tag) == (k % 251, 0)

        stop = sdk2_frame(0x0100, 0, 9, _set((0x001A, b"\x02")))  # IDLE
        assert _ask(cmd, dev.address, stop)[4] == b"\0\0\0"
        assert drain_then_silence(points)  # the packets on their way, then nothing
        assert not dev.sampling
        assert dev.commands_malformed == 0


# 10 m ahead: x = 1000 × 10 mm in data type 2; depth 10,000 mm at zenith 90°,
# azimuth 0° in data type 3
@pytest.mark.parametrize(
    ("data_type", "size", "fmt", "expected"),
    [(2, 8, "<hhh", (1000, 0, 0)), (3, 10, "<IHH", (10_000, 9000, 0))],
)
def test_the_data_type_key_switches_the_point_layout(
    host: tuple[socket.socket, socket.socket],
    data_type: int,
    size: int,
    fmt: str,
    expected: tuple[int, int, int],
) -> None:
    cmd, points = host
    one = PointChunk(np.array([[10.0, 0.0, 0.0]]), np.zeros(1, np.int64), np.array([9], np.uint8))
    with _device([one]) as dev:
        _configure(cmd, points, dev)
        data = _set((0x0000, bytes([data_type])), (0x001A, b"\x01"))
        assert _ask(cmd, dev.address, sdk2_frame(0x0100, 0, 3, data))[4] == b"\0\0\0"
        buf = points.recv(2048)
        assert (buf[10], len(buf)) == (data_type, 36 + 96 * size)
        assert struct.unpack_from(fmt, buf, 36) == expected


def test_queries_and_status_pushes_report_the_work_state(
    host: tuple[socket.socket, socket.socket],
) -> None:
    cmd, points = host
    with _device(push_period_s=0.1) as dev:
        # query: key_num, reserved, keys; a key it does not know (0x8007) is left out
        query = struct.pack("<HHHHH", 3, 0, 0x8006, 0x8007, 0x0000)
        data = _ask(cmd, dev.address, sdk2_frame(0x0101, 0, 4, query))[4]
        # ACK: ret_code, key_num, then key, length, value: IDLE (0x02), data type 1
        assert data == struct.pack("<BHHHBHHB", 0, 2, 0x8006, 1, 0x02, 0x0000, 1, 1)
        _configure(cmd, points, dev)
        _ask(cmd, dev.address, sdk2_frame(0x0100, 0, 5, _set((0x001A, b"\x01"))))
        count = key = size = state = -1
        deadline = time.monotonic() + 1.0
        while time.monotonic() < deadline:
            _seq, cmd_id, cmd_type, sender, data = parse(cmd.recv(2048))
            if (cmd_id, cmd_type, sender) == (0x0102, 0, 1):  # a push: request from the LiDAR
                count, _ = struct.unpack_from("<HH", data)
                key, size, state = struct.unpack_from("<HHB", data, 4)
                if state == 0x01:
                    break
        assert (count, key, size, state) == (2, 0x8006, 1, 0x01)  # SAMPLING


def test_the_parameter_inquiry_reports_what_the_device_is(
    host: tuple[socket.socket, socket.socket],
) -> None:
    cmd, _ = host
    with _device(serial="47MDL9W0020022", firmware=(10, 11, 6, 35)) as dev:
        keys = (0x8000, 0x8001, 0x8002, 0x8003, 0x8004, 0x8005, 0x8006)
        query = struct.pack("<HH7H", 7, 0, *keys)
        data = _ask(cmd, dev.address, sdk2_frame(0x0101, 0, 8, query))[4]
    # ACK: ret_code 0, key_num 7, then key, length, value in the order asked
    ret, count = struct.unpack_from("<BH", data)
    values, pos = {}, 3
    for _ in range(count):
        key, size = struct.unpack_from("<HH", data, pos)
        values[key] = data[pos + 4 : pos + 4 + size]
        pos += 4 + size
    assert (ret, count, pos, list(values)) == (0, 7, len(data), list(keys))
    assert values[0x8000] == b"47MDL9W0020022\0\0"  # sn, NUL-padded to 16
    assert values[0x8001] == b"Mid-360 emulated".ljust(64, b"\0")  # product_info char[64]
    assert values[0x8002] == bytes([10, 11, 6, 35])  # version_app aa.bb.cc.dd
    assert (len(values[0x8003]), len(values[0x8004]), len(values[0x8005])) == (4, 4, 6)
    assert values[0x8005][0] & 0x03 == 0x02  # a locally administered, unicast MAC
    assert values[0x8006] == b"\x02"  # IDLE


def test_a_firmware_version_is_four_bytes() -> None:
    with pytest.raises(ConfigError, match="four bytes"):
        _device(firmware=(1, 256, 0, 0))


@pytest.mark.parametrize(
    ("items", "ret_key"),
    [
        ([(0x001A, b"\x01")], (0x02, 0x001A)),  # sampling with nowhere to send: not now
        ([(0x001A, b"\x07")], (0x03, 0x001A)),  # no such work mode: out of range
        ([(0x0000, b"\x04")], (0x03, 0x0000)),  # no such data type
        ([(0x0006, b"\x00" * 7)], (0x23, 0x0006)),  # wrong value length
        ([(0x8006, b"\x01")], (0x22, 0x8006)),  # read-only
        ([(0x0001, b"\x00"), (0x001C, b"\x00")], (0x20, 0x0001)),  # unsupported here
    ],
)
def test_refused_parameters_name_the_key(
    host: tuple[socket.socket, socket.socket],
    items: list[tuple[int, bytes]],
    ret_key: tuple[int, int],
) -> None:
    cmd, _ = host
    with _device() as dev:
        data = _ask(cmd, dev.address, sdk2_frame(0x0100, 0, 6, _set(*items)))[4]
        assert struct.unpack("<BH", data) == ret_key
        assert not dev.sampling


def test_malformed_frames_get_no_reply_and_are_counted(
    host: tuple[socket.socket, socket.socket],
) -> None:
    cmd, _ = host
    good = sdk2_frame(0x0101, 0, 5, struct.pack("<HHH", 1, 0, 0x8006))
    bad = [
        good[:-1] + bytes([good[-1] ^ 1]),  # data CRC-32
        good[:5] + bytes([good[5] ^ 1]) + good[6:],  # header CRC-16
        b"\x55" + good[1:],  # SOF
        good[:-1],  # shorter than its length field
        sdk2_frame(0x0100, 0, 6, b"\x01\x00\x00\x00\x1a\x00"),  # a truncated key list
    ]
    with _device() as dev:
        assert_no_reply(cmd, dev.address, bad)
        assert dev.commands_malformed == len(bad)
        assert _ask(cmd, dev.address, good)[:3] == (5, 0x0101, 1)  # still answering


def test_close_stops_the_device_within_a_bounded_time() -> None:
    """close joins the device thread (ended when close returns) and closes its sockets."""
    dev = _device().start()
    dev.close()
    assert dev._thread is not None
    assert not dev._thread.is_alive()
    assert [sock.fileno() for sock in dev._sockets()] == [-1] * len(dev._sockets())
