"""The emulated Livox SDK 1 device against command frames built here by hand from the
protocol table (Livox-SDK ``sdk_protocol.h``, ``livox_def.h``, ``device_discovery.cpp``)
with ``struct.pack`` and bitwise CRCs written from their definitions, never with the
codec module's encoder; its point packets are read back with ``struct`` too.

Every socket is on 127.0.0.1 with a port the kernel picks, every wait is bounded."""

from __future__ import annotations

import socket
import struct
import time
from collections.abc import Iterator

import numpy as np
import pytest

from dronetrack.sim.emulate.livox import (
    EmulatedLivox,
    GridSource,
    PointChunk,
    frame_chunks,
    grid_points,
)
from dronetrack.types import Frame
from livox_helpers import LOOP, assert_no_reply, drain_then_silence, loopback_udp, port_of

# device type → (data type, firings per packet, bytes per firing, Δt ns): livox_def.h
# point structs, livox_ros_driver lds.h tables
DEVICES = {7: (2, 96, 14, 4_167), 1: (0, 100, 13, 10_000)}


def _crc16(data: bytes, reg: int = 0x4C49) -> int:
    # MCRF4XX: reflected polynomial 0x1021 (0x8408), register 0x4C49, no final xor
    for b in data:
        reg ^= b
        for _ in range(8):
            reg = (reg >> 1) ^ 0x8408 if reg & 1 else reg >> 1
    return reg


def _crc32(data: bytes, seed: int = 0x564F580A) -> int:
    # reflected 0x04C11DB7, register seed ^ 0xFFFFFFFF, final xor 0xFFFFFFFF
    reg = seed ^ 0xFFFFFFFF
    for b in data:
        reg ^= b
        for _ in range(8):
            reg = (reg >> 1) ^ 0xEDB88320 if reg & 1 else reg >> 1
    return reg ^ 0xFFFFFFFF


def frame(cmd_type: int, seq: int, cmd_id: int, payload: bytes = b"", cmd_set: int = 0) -> bytes:
    pre = struct.pack("<BBHBH", 0xAA, 0, 15 + len(payload), cmd_type, seq)
    body = pre + struct.pack("<HBB", _crc16(pre), cmd_set, cmd_id) + payload
    return body + struct.pack("<I", _crc32(body))


def parse(buf: bytes) -> tuple[int, int, int, int, bytes]:
    """(cmd_type, seq, cmd_set, cmd_id, payload) of a frame whose checks all hold."""
    sof, version, length, cmd_type, seq, crc16 = struct.unpack_from("<BBHBHH", buf)
    assert (sof, version, length) == (0xAA, 0, len(buf))
    assert crc16 == _crc16(buf[:7])
    assert struct.unpack_from("<I", buf, len(buf) - 4)[0] == _crc32(buf[:-4])
    return cmd_type, seq, buf[9], buf[10], buf[11:-4]


def _device(dev_type: int, seconds: float = 2.0, **kw: object) -> EmulatedLivox:
    dt = DEVICES[dev_type][3]
    return EmulatedLivox(GridSource(dt, seconds), dev_type=dev_type, device_port=0, **kw)  # type: ignore[arg-type]


def _ask(
    cmd: socket.socket, dev: EmulatedLivox, request: bytes
) -> tuple[int, int, int, int, bytes]:
    cmd.sendto(request, dev.address)
    return parse(cmd.recv(2048))


def _handshake(cmd: socket.socket, data: socket.socket, seq: int = 17) -> bytes:
    # host IP in dotted order, then data, command and IMU ports (HandshakeRequest)
    payload = socket.inet_aton(LOOP) + struct.pack(
        "<HHH", port_of(data), port_of(cmd), port_of(data)
    )
    return frame(1, seq, 0x01, payload)  # cmd_type ACK, as the SDK sends it


@pytest.mark.parametrize("dev_type", [7, 1])
def test_the_broadcast_names_the_device_from_its_commandport_of(dev_type: int) -> None:
    listener = loopback_udp()
    with (
        listener,
        _device(dev_type, broadcast_to=(LOOP, port_of(listener)), broadcast_period_s=0.05) as dev,
    ):
        buf, (_, src_port) = listener.recvfrom(2048)
        cmd_type, _, cmd_set, cmd_id, payload = parse(buf)
        assert (cmd_type, cmd_set, cmd_id) == (2, 0, 0x00)  # MSG, general, broadcast
        code, kind, reserved = struct.unpack("<16sBH", payload)
        assert code == b"0EMULATEDLIVOX1\0"
        assert kind == dev_type
        assert reserved == 0
        # the SDK sends its handshake back to the broadcast's source address
        assert src_port == dev.address[1]
        listener.recv(2048)  # and it repeats
        # The device counts a broadcast once sendto returns, so the count may trail what
        # arrived; it has counted the second by the time the third arrives.
        listener.recv(2048)
        assert dev.broadcasts_sent >= 2


@pytest.mark.parametrize("dev_type", [7, 1])
def test_handshake_heartbeat_sampling_and_disconnect(
    host: tuple[socket.socket, socket.socket], dev_type: int
) -> None:
    cmd, data = host
    data_type, n, rec, dt = DEVICES[dev_type]
    with _device(dev_type) as dev:
        assert _ask(cmd, dev, _handshake(cmd, data, seq=17)) == (1, 17, 0, 0x01, b"\0")
        assert dev.host is not None
        assert dev.host.data_port == port_of(data)
        # heartbeat ACK: ret_code 0, state 1 (normal), feature 0, status code 0
        ack = _ask(cmd, dev, frame(0, 18, 0x03))
        assert ack[:4] == (1, 18, 0, 0x03)
        assert struct.unpack("<BBBI", ack[4]) == (0, 1, 0, 0)
        assert _ask(cmd, dev, frame(0, 19, 0x04, b"\x01")) == (1, 19, 0, 0x04, b"\0")

        packets = [data.recv(2048) for _ in range(20)]
        assert {len(p) for p in packets} == {18 + n * rec}  # 1362 Avia, 1318 Mid-40
        heads = [struct.unpack_from("<BBBBIBBQ", p) for p in packets]
        # version 5, slot 0, lidar id 1, status 0, timestamp type 0 (no sync), data type
        assert {h[:7] for h in heads} == {(5, 0, 1, 0, 0, 0, data_type)}
        # packet p stamps its first firing p·n·Δt after the start of sampling
        assert [h[7] for h in heads] == [p * n * dt for p in range(20)]
        # firings 0 and 1 of the grid source, in mm; data type 2 adds a tag byte
        fmt = "<iiiBB" if data_type == 2 else "<iiiB"
        for k in (0, 1):
            x, y, z, refl = struct.unpack_from(fmt, packets[0], 18 + k * rec)[:4]
            assert (x, y, z) == tuple(np.rint(grid_points(np.array([k]))[0] * 1000).astype(int))
            assert refl == k % 251

        assert _ask(cmd, dev, frame(0, 20, 0x04, b"\x00")) == (1, 20, 0, 0x04, b"\0")
        assert drain_then_silence(data)  # the packets on their way, then nothing
        assert _ask(cmd, dev, frame(0, 21, 0x06)) == (1, 21, 0, 0x06, b"\0")
        assert dev.host is None
        assert not dev.sampling
        assert dev.commands_malformed == 0


def test_malformed_frames_get_no_reply_and_are_counted(
    host: tuple[socket.socket, socket.socket],
) -> None:
    cmd, _ = host
    good = frame(0, 5, 0x03)
    bad = [
        good[:-1] + bytes([good[-1] ^ 1]),  # CRC-32
        good[:7] + bytes([good[7] ^ 1]) + good[8:],  # CRC-16
        b"\x55" + good[1:],  # SOF
        good[:12],  # shorter than its length field
        frame(0, 6, 0x01, b"\x7f\x00"),  # a handshake with a 2-byte payload
    ]
    with _device(7) as dev:
        assert_no_reply(cmd, dev.address, bad)
        assert dev.commands_malformed == len(bad)
        assert _ask(cmd, dev, good)[:4] == (1, 5, 0, 0x03)  # still answering


def test_sampling_without_a_host_is_refused(host: tuple[socket.socket, socket.socket]) -> None:
    cmd, _ = host
    with _device(7) as dev:
        assert _ask(cmd, dev, frame(0, 9, 0x04, b"\x01")) == (1, 9, 0, 0x04, b"\x01")
        assert not dev.sampling


class TurnClock:
    """The device's clock, moved by hand; it counts its reads, so that a test can wait
    for the device thread's turns (it reads the clock once a turn)."""

    def __init__(self) -> None:
        self.t = 0.0
        self.reads = 0

    def __call__(self) -> float:
        self.reads += 1
        return self.t

    def set(self, t: float) -> None:
        """Set the time and wait (at most 2 s) until a whole turn of the thread has run
        on it: two more reads, the second at the start of the turn after."""
        self.t = t
        turned = self.reads + 2
        deadline = time.monotonic() + 2.0
        while self.reads < turned and time.monotonic() < deadline:
            time.sleep(0.001)
        assert self.reads >= turned, "the device thread did not turn"


def test_the_device_drops_a_host_that_sends_no_heartbeat(
    host: tuple[socket.socket, socket.socket],
) -> None:
    """On the device's clock: the host is kept up to 0.3 s after its handshake, and
    dropped (sampling stops) on the first turn 5 ms later, one wait of the thread."""
    cmd, data = host
    clock = TurnClock()
    with _device(7, host_timeout_s=0.3, clock=clock) as dev:
        _ask(cmd, dev, _handshake(cmd, data))
        _ask(cmd, dev, frame(0, 2, 0x04, b"\x01"))
        data.recv(2048)
        clock.set(0.3)
        assert dev.host is not None
        assert dev.sampling
        clock.set(0.305)
        assert dev.host is None
        assert not dev.sampling


def test_points_take_the_nearest_firing_and_one_per_firing(
    host: tuple[socket.socket, socket.socket],
) -> None:
    cmd, data = host
    dt = 4_167
    t = np.array([0, 5 * dt + 1000, 5 * dt + 2000, 7 * dt - 2000], np.int64)  # 0, 5, 5, 7
    xyz = np.array([[1.0, 0, 0], [2.0, 0, 0], [3.0, 0, 0], [4.0, 0, 0]])
    chunk = PointChunk(xyz, t, np.array([10, 20, 30, 40], np.uint8))
    with EmulatedLivox([chunk], device_port=0) as dev:
        _ask(cmd, dev, _handshake(cmd, data))
        _ask(cmd, dev, frame(0, 2, 0x04, b"\x01"))
        packet = data.recv(2048)
        xs = [struct.unpack_from("<iiiBB", packet, 18 + 14 * k)[0] for k in range(96)]
        assert [k for k, x in enumerate(xs) if x] == [0, 5, 7]
        assert [xs[0], xs[5], xs[7]] == [1000, 2000, 4000]  # the first point of firing 5
        assert dev.points_dropped == 1
        assert dev.points_built == 3
        data.settimeout(0.3)
        with pytest.raises(TimeoutError):  # the stream ends with the last point's packet
            data.recv(2048)


def test_close_stops_the_device_within_a_bounded_time() -> None:
    """close joins the device thread (ended when close returns) and closes its socket."""
    dev = _device(7).start()
    dev.close()
    assert dev._thread is not None
    assert not dev._thread.is_alive()
    assert dev._sock.fileno() == -1


def test_simulator_frames_become_time_ordered_chunks() -> None:
    pts = np.array([[5.0, 0, 0], [6.0, 0, 0], [7.0, 0, 0]])
    frame = Frame(
        stamp=1.0,
        duration=0.1,
        points=pts,
        t=np.array([1.05, 1.0, 1.000004167]),
        line=np.zeros(3, np.uint8),
        intensity=np.array([10.4, 300.0, -2.0], np.float32),
        pose_t=np.array([1.0]),
        poses=np.eye(4)[None],
    )
    (chunk,) = frame_chunks([frame], t0_s=1.0)
    # t_ns = round((t − t0)·10⁹), sorted by time; intensity clipped to 0-255
    np.testing.assert_array_equal(chunk.t_ns, [0, 4_167, 50_000_000])
    np.testing.assert_array_equal(chunk.xyz, pts[[1, 2, 0]])
    np.testing.assert_array_equal(chunk.reflectivity, [255, 0, 10])


def test_a_callable_source_is_called_afresh_at_each_start(
    host: tuple[socket.socket, socket.socket],
) -> None:
    cmd, data = host
    calls: list[int] = []

    def source() -> list[PointChunk]:
        calls.append(1)
        one = np.array([len(calls) * 1.0, 0.0, 0.0])[None]  # x = 1 m, then 2 m
        return [PointChunk(one, np.zeros(1, np.int64), np.zeros(1, np.uint8))]

    with EmulatedLivox(source, device_port=0) as dev:
        _ask(cmd, dev, _handshake(cmd, data))
        for seq, x_mm in ((2, 1000), (4, 2000)):
            _ask(cmd, dev, frame(0, seq, 0x04, b"\x01"))
            assert struct.unpack_from("<i", data.recv(2048), 18)[0] == x_mm
            _ask(cmd, dev, frame(0, seq + 1, 0x04, b"\x00"))
    assert len(calls) == 2


@pytest.mark.parametrize("covers", [False, True])
def test_a_chunk_that_says_how_far_it_covers_is_sent_before_the_next_is_taken(
    host: tuple[socket.socket, socket.socket], covers: bool
) -> None:
    # Chunk A holds a point in block 0, chunk B one in block 1.  Without end_ns the
    # device must see B's point to know block 0 is complete, so it takes B before it
    # sends anything; with end_ns = one block, it sends block 0's packets first.
    cmd, data = host
    devices: list[EmulatedLivox] = []
    sent_when_b_taken: list[int] = []

    def source() -> Iterator[PointChunk]:
        block = devices[0].block_ns
        one = np.array([[10.0, 0.0, 0.0]])
        end = block if covers else None
        yield PointChunk(one, np.zeros(1, np.int64), np.ones(1, np.uint8), end)
        sent_when_b_taken.append(devices[0].packets_sent)
        yield PointChunk(one, np.array([block + 10], np.int64), np.ones(1, np.uint8))

    with EmulatedLivox(source, device_port=0) as dev:
        devices.append(dev)
        # 50 Avia packets of 96 firings of 4 167 ns: 20.0016 ms, the one nearest 20 ms
        assert dev.block_ns == 50 * 96 * 4_167
        _ask(cmd, dev, _handshake(cmd, data))
        before = time.monotonic()
        _ask(cmd, dev, frame(0, 2, 0x04, b"\x01"))
        after = time.monotonic()
        assert before <= dev.stream_start <= after  # device time 0: the start command
        deadline = time.monotonic() + 2.0
        while not sent_when_b_taken and time.monotonic() < deadline:
            time.sleep(0.01)
    assert sent_when_b_taken == [50 if covers else 0]
