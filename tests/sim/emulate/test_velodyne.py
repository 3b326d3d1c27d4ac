"""The emulated VLP-16: its packets read back with ``struct`` as the VLP-16 User Manual
lays them out, and simulated points round-tripped through its encoder, UDP and
velodyne-decoder (``VelodyneClient``).

Every socket is on 127.0.0.1, every wait is bounded."""

from __future__ import annotations

import math
import socket
import struct
import time
from collections.abc import Callable, Iterator

import numpy as np
import pytest

from dronetrack.errors import ConfigError
from dronetrack.sim.emulate.livox_stream import PointChunk
from dronetrack.sim.emulate.velodyne import EmulatedVelodyne
from dronetrack.sim.mounted import RotatedPattern, side_mount
from dronetrack.sim.spinning import vlp16_pattern
from dronetrack.sources.assembly import PointBatch
from dronetrack.sources.velodyne.client import VelodyneClient, VelodyneEndpoint
from livox_helpers import LOOP, collect

PACKET_US = 24 * 55.296  # a packet's span [µs]


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((LOOP, 0))
        return int(s.getsockname()[1])


def _listener(port: int) -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    s.bind((LOOP, port))
    s.settimeout(1.0)
    return s


def _fields(packet: bytes) -> tuple[list[int], list[int], int, int, int]:
    """(azimuths [0.01°], distances [2 mm], stamp [µs], return mode, product) of a
    packet, read as the manual lays it out; its flags checked."""
    assert len(packet) == 1206
    az, dist = [], []
    for b in range(12):
        flag, a = struct.unpack_from("<2sH", packet, 100 * b)
        assert flag == b"\xff\xee"
        az.append(a)
        dist += [struct.unpack_from("<H", packet, 100 * b + 4 + 3 * k)[0] for k in range(32)]
    stamp, mode, product = struct.unpack_from("<IBB", packet, 1200)
    return az, dist, stamp, mode, product


def _until_silent(rx: socket.socket, most: int = 1000) -> list[bytes]:
    """The datagrams that come, each within 0.3 s of the last (at most ``most``)."""
    rx.settimeout(0.3)
    out = []
    for _ in range(most):
        try:
            out.append(rx.recv(2048))
        except TimeoutError:
            break
    return out


def sim_points(
    duration_s: float, side: bool = False, seed: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Noise-free returns of the simulator's VLP-16 (upright, or on its side): for a
    random 60 % of its pulses, p = o + r d (the simulator's return point) at a random
    range r of 1-100 m.  (xyz, t_ns, line, reflectivity), in time order."""
    base = vlp16_pattern(600.0)
    pattern = RotatedPattern(base, side_mount()) if side else base
    pulses = pattern.pulses(0.0, duration_s)
    rng = np.random.default_rng(seed)
    keep = rng.random(len(pulses.t)) < 0.6
    r = rng.uniform(1.0, 100.0, len(pulses.t))
    xyz = (pulses.origins + r[:, None] * pulses.dirs)[keep]
    t_ns = np.rint(pulses.t[keep] * 1e9).astype(np.int64)
    refl = rng.integers(1, 256, len(t_ns)).astype(np.uint8)
    return xyz, t_ns, pulses.line[keep], refl


def chunks(
    xyz: np.ndarray, t_ns: np.ndarray, refl: np.ndarray
) -> Callable[[], Iterator[PointChunk]]:
    """A fresh source at each start: the points in chunks of 20 ms."""

    def source() -> Iterator[PointChunk]:
        end = int(t_ns[-1]) + 1
        for lo in range(0, end, 20_000_000):
            sel = (t_ns >= lo) & (t_ns < lo + 20_000_000)
            yield PointChunk(xyz[sel], t_ns[sel], refl[sel], end_ns=lo + 20_000_000)

    return source


def test_it_waits_for_a_host_then_streams_packets_as_the_manual_lays_them_out() -> None:
    xyz, t_ns, _, refl = sim_points(1.0)
    port = _free_port()
    with EmulatedVelodyne(chunks(xyz, t_ns, refl), ip=LOOP, dest=(LOOP, port)) as dev:
        time.sleep(0.3)
        # nobody listens: refused probes, no stream
        assert dev.waiting
        assert dev.hosts == 0
        assert dev.packets_sent == 0
        assert dev.probes_sent >= 3
        with _listener(port) as rx:
            got = [rx.recv(2048)]
            started = time.monotonic()
            while time.monotonic() - started < 0.5:
                got.append(rx.recv(2048))
        assert dev.hosts == 1
    fields = [_fields(p) for p in got]
    # packet 0 (the probe that found the host) holds no return, then the stream goes on
    assert fields[0][2] == 0
    assert fields[0][0][0] == 0  # 0.00° at device time 0
    assert not any(fields[0][1])
    stamps = [f[2] for f in fields]
    assert stamps == [round(i * PACKET_US) for i in range(len(fields))]
    assert {(f[3], f[4]) for f in fields} == {(0x37, 0x22)}
    # 753.5 packets/s
    assert len(got) == pytest.approx(0.5 * 1e6 / PACKET_US, rel=0.1)
    # the azimuth grows 3600°/s at 600 rpm: 0.39813° a block of two sequences
    az = np.unwrap(np.radians(np.concatenate([f[0] for f in fields]) / 100))
    step = np.degrees(np.diff(az)) * 100
    assert np.abs(step - 600 / 60 * 36000 * 2 * 55.296e-6).max() <= 1.0


@pytest.mark.parametrize("side", [False, True])
def test_simulated_points_come_back_through_velodyne_decoder(side: bool) -> None:
    xyz, t_ns, line, refl = sim_points(0.35, side=side, seed=int(side))
    port = _free_port()
    rotation = side_mount() if side else None
    client = VelodyneClient(VelodyneEndpoint(LOOP, port), head_rotation=rotation)
    source = chunks(xyz, t_ns, refl)
    with client, EmulatedVelodyne(source, ip=LOOP, dest=(LOOP, port), head_rotation=rotation):
        client.open(2.0)
        sent = t_ns >= round(PACKET_US * 1000)  # packet 0 went out empty, as the probe
        got: PointBatch = collect(client, int(sent.sum()), limit_s=3.0)
        assert client.packets_lost == 0
        assert client.packets_malformed == 0
    assert len(got) == int(sent.sum())
    # every point at its own time (the stamp is whole µs), where the simulator put it,
    # to the packet's 2 mm range steps (±1 mm) and to 0.01° in azimuth: the block's
    # azimuth is rounded to 0.01° (±0.005°), and velodyne-decoder rounds each point's
    # azimuth, interpolated between blocks, to 0.01° again (±0.005°); 1e-6 for float32
    order = np.argsort(got.t_ns, kind="stable")
    dt = got.t_ns[order] - t_ns[sent]
    assert np.abs(dt).max() <= 500
    want = xyz[sent]
    r = np.linalg.norm(want, axis=1)
    err = np.linalg.norm(got.xyz[order] - want, axis=1)
    assert np.all(err <= 1e-3 + r * (math.radians(0.01) + 1e-6))
    np.testing.assert_array_equal(got.line[order], line[sent])
    np.testing.assert_array_equal(got.reflectivity[order], refl[sent])


def test_revolutions_start_every_tenth_of_a_second_at_600_rpm() -> None:
    xyz, t_ns, _, refl = sim_points(0.45)
    port = _free_port()
    client = VelodyneClient(VelodyneEndpoint(LOOP, port))
    cuts: list[int] = []
    with client, EmulatedVelodyne(chunks(xyz, t_ns, refl), ip=LOOP, dest=(LOOP, port)):
        client.open(2.0)
        until = time.monotonic() + 3.0
        while len(cuts) < 5 and time.monotonic() < until:
            cuts += client.read(0.1).cuts
    # device time 0 is azimuth 0.00° (a start), then every 360°
    np.testing.assert_allclose(cuts[:5], [0, 1e8, 2e8, 3e8, 4e8], rtol=0, atol=2_000)


def test_a_host_that_leaves_stops_the_stream_and_the_next_gets_it_from_the_start() -> None:
    xyz, t_ns, _, refl = sim_points(2.0)
    port = _free_port()
    with EmulatedVelodyne(chunks(xyz, t_ns, refl), ip=LOOP, dest=(LOOP, port)) as dev:
        with _listener(port) as rx:
            first = [_fields(rx.recv(2048))[2] for _ in range(20)]
        deadline = time.monotonic() + 1.0
        while not dev.waiting and time.monotonic() < deadline:
            time.sleep(0.01)
        assert dev.hosts_lost == 1
        assert dev.waiting
        with _listener(port) as rx:
            again = [_fields(rx.recv(2048))[2] for _ in range(20)]
        assert dev.hosts == 2
    assert first[0] == 0
    assert again[:3] == [0, 1327, 2654]


def test_after_its_stream_it_is_silent() -> None:
    xyz, t_ns, _, refl = sim_points(0.05)
    port = _free_port()
    with EmulatedVelodyne(chunks(xyz, t_ns, refl), ip=LOOP, dest=(LOOP, port)) as dev:
        with _listener(port) as rx:
            got = [rx.recv(2048), *_until_silent(rx)]
        assert not dev.sampling
        assert not dev.waiting
        assert dev.hosts == 1
    # 50 ms of points end in packet 37 (37 · 1.327 ms ≤ 50 ms < 38 · 1.327 ms)
    assert len(got) == 38
    assert _fields(got[-1])[2] == round(37 * PACKET_US)


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ConfigError, match="300-1200 rpm, not 1500"):
        EmulatedVelodyne([], rpm=1500.0)
    with pytest.raises(ConfigError, match="probe period"):
        EmulatedVelodyne([], probe_s=0.001)
