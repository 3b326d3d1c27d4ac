"""The VLP-16 link (``velodyne://``): packets built by hand from the VLP-16 User Manual,
decoded by velodyne-decoder through the client, and the client on loopback."""

from __future__ import annotations

import math
import socket
import time
from threading import Thread

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dronetrack.errors import ConfigError, DeviceError
from dronetrack.geometry.transforms import rot_x
from dronetrack.sources.velodyne.client import VelodyneClient, VelodyneEndpoint, parse_velodyne_uri
from livox_helpers import LOOP, collect, damaged_packets, read_for
from velodyne_helpers import (
    FIRING_SEQUENCE_US,
    manual_xyz,
    point_time_us,
    spin_step_cdeg,
    steady_azimuths,
    vlp16_packet,
)

HOUR_US = 3_600_000_000


def _client(**kw: object) -> VelodyneClient:
    return VelodyneClient(VelodyneEndpoint(LOOP, 0), **kw)  # type: ignore[arg-type]


# A packet spinning 0.2° a block from 90°: points of lasers 0, 1, 15 and 14 at known
# ranges (distance in 2 mm units, reflectivity), in both sequences of their blocks.
POINTS = {(0, 0): (5000, 10), (3, 17): (10000, 20), (11, 31): (30000, 30), (6, 14): (2500, 40)}
STAMP_US = 1_000_000


def _expected(stamp_us: int, first_cdeg: int, step_cdeg: float) -> dict[int, tuple]:  # type: ignore[type-arg]
    """time [ns] → (xyz, laser, reflectivity): the manual's X, Y, Z at the precise azimuth
    of §9.5, the block's azimuth plus the turn since the block's first firing."""
    out = {}
    for (b, k), (units, refl) in POINTS.items():
        t_us = point_time_us(stamp_us, b, k)
        since_block = t_us - point_time_us(stamp_us, b, 0)
        alpha = (
            first_cdeg + b * step_cdeg + step_cdeg * since_block / (2 * FIRING_SEQUENCE_US)
        ) / 100
        out[round(t_us * 1000)] = (manual_xyz(units * 0.002, alpha, k % 16), k % 16, refl)
    return out


def _check_points(batch, expected, rotation=None) -> None:  # type: ignore[no-untyped-def]
    assert len(batch) == len(expected)
    for i, t in enumerate(batch.t_ns.tolist()):
        want_t = min(expected, key=lambda w: abs(w - t))
        assert abs(want_t - t) <= 10  # ns: velodyne-decoder's float32 times
        xyz, laser, refl = expected[want_t]
        if rotation is not None:
            xyz = rotation @ np.asarray(xyz)
        r = float(np.linalg.norm(xyz))
        # velodyne-decoder rounds each point's azimuth, interpolated between blocks, to
        # 0.01° (±0.005°); 0.1 mm and 1e-6 for its float32 coordinates
        atol = r * (math.radians(0.005) + 1e-6) + 1e-4
        np.testing.assert_allclose(batch.xyz[i], xyz, rtol=0, atol=atol)
        assert batch.line[i] == laser
        assert batch.reflectivity[i] == refl


def test_hand_built_points_decode_to_the_manuals_coordinates_and_times() -> None:
    az = steady_azimuths(9000, 20)
    with _client() as c:
        batch = c.decode([vlp16_packet(az, POINTS, stamp_us=STAMP_US)])
        _check_points(batch, _expected(STAMP_US, 9000, 20))
        assert c.product == 0x22
        assert c.return_mode == 0x37
        assert c.packets_malformed == 0
    # the batch's firings: the packet's first and last (block 11, data point 31)
    assert batch.firings == (STAMP_US * 1000, round(point_time_us(STAMP_US, 11, 31) * 1000))


def test_a_head_on_its_side_turns_the_points_into_the_pipelines_frame() -> None:
    R = rot_x(0.5 * math.pi)
    az = steady_azimuths(31000, 20)
    with _client(head_rotation=R) as c:
        batch = c.decode([vlp16_packet(az, POINTS, stamp_us=STAMP_US)])
    _check_points(batch, _expected(STAMP_US, 31000, 20), rotation=R)


def test_points_of_several_packets_keep_their_own_times() -> None:
    step = spin_step_cdeg(600.0)
    stamps = [STAMP_US + round(i * 24 * FIRING_SEQUENCE_US) for i in range(3)]
    packets = [
        vlp16_packet(
            [round(a) % 36000 for a in 12000 + step * (12 * i + np.arange(12))],
            {(i, 2 * i): (4000 + i, 7)},
            stamp_us=stamps[i],
        )
        for i in range(3)
    ]
    with _client() as c:
        batch = c.decode(packets)
        assert c.rpm == pytest.approx(600.0, rel=2e-3)
        assert c.packets_lost == 0
    want = [round(point_time_us(stamps[i], i, 2 * i) * 1000) for i in range(3)]
    assert np.abs(batch.t_ns - np.array(want)).max() <= 10
    assert batch.line.tolist() == [0, 2, 4]


def test_malformed_packets_are_counted_and_skipped() -> None:
    good = vlp16_packet(steady_azimuths(0, 20), POINTS, stamp_us=STAMP_US)
    bad = [good[:-6], good + b"\x00", b"\xff\xdd" + good[2:], b"", bytes(512)]
    with _client() as c:
        batch = c.decode([bad[0], good, *bad[1:]])
        assert c.packets_malformed == len(bad)
        assert len(batch) == len(POINTS)
        empty = c.decode(bad)
        assert len(empty) == 0
        assert empty.firings is None
        assert c.packets_malformed == 2 * len(bad)


def _stamps(indices: list[int], start_us: int = STAMP_US) -> list[int]:
    """Stamps [µs past the hour] of the packets ``indices`` of a steady stream."""
    return [round(start_us + i * 24 * FIRING_SEQUENCE_US) % HOUR_US for i in indices]


def test_lost_packets_are_counted_from_the_gaps_in_their_stamps() -> None:
    with _client() as c:
        c.decode([vlp16_packet([0] * 12, stamp_us=s) for s in _stamps([0, 1, 4, 5])])
        assert c.packets_lost == 2
        c.decode([vlp16_packet([0] * 12, stamp_us=s) for s in _stamps([9])])  # across reads
        assert c.packets_lost == 5
        c.decode([vlp16_packet([0] * 12, stamp_us=s) for s in _stamps([3])])  # time went back
        assert c.packets_lost == 5


def test_the_hour_rolls_over_without_a_jump_or_a_loss() -> None:
    start = HOUR_US - 3000  # 3 ms before the top of the hour
    stamps = _stamps(list(range(6)), start)
    assert stamps[3] < stamps[2]  # the stamps wrap, inside the first read
    packets = [vlp16_packet([0] * 12, {(0, 0): (5000, 1)}, stamp_us=s) for s in stamps]
    with _client() as c:
        first = c.decode(packets[:4])
        second = c.decode(packets[4:])
        assert c.packets_lost == 0
    t = np.r_[first.t_ns, second.t_ns]
    want = [round(start + i * 24 * FIRING_SEQUENCE_US) * 1000 for i in range(6)]
    assert np.abs(t - np.array(want)).max() <= 10


def test_a_revolution_starts_where_the_azimuth_passes_zero() -> None:
    block_ns = round(2 * FIRING_SEQUENCE_US * 1000)
    with _client() as c:
        # 359.90° + 0.2° a block: 0° is passed half-way from block 0 to block 1
        batch = c.decode([vlp16_packet(steady_azimuths(35990, 20), stamp_us=STAMP_US)])
        assert batch.cuts == (STAMP_US * 1000 + block_ns // 2,)
        # the next packet goes on from 2.30° and holds no start
        nxt = c.decode([vlp16_packet(steady_azimuths(230, 20), stamp_us=STAMP_US + 1327)])
        assert nxt.cuts == ()
    with _client() as c:
        # a first block right on 0.00° starts a revolution; one at 0.01° does not
        assert c.decode([vlp16_packet(steady_azimuths(0, 20))]).cuts == (0,)
    with _client() as c:
        assert c.decode([vlp16_packet(steady_azimuths(1, 20))]).cuts == ()


def test_another_product_is_a_device_error() -> None:
    with _client() as c, pytest.raises(DeviceError, match=r"Puck Hi-Res \(product ID 0x24\)"):
        c.decode([vlp16_packet([0] * 12, product=0x24)])


def _sender() -> socket.socket:
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind((LOOP, 0))
    return s


def _send_later(tx: socket.socket, packet: bytes, to: tuple[str, int], times: int) -> Thread:
    def send() -> None:
        time.sleep(0.1)
        for _ in range(times):
            tx.sendto(packet, to)

    thread = Thread(target=send)
    thread.start()
    return thread


@pytest.mark.slow
def test_a_silent_port_fails_open_within_its_timeout() -> None:
    with _client() as c:
        started = time.monotonic()
        with pytest.raises(
            DeviceError, match=r"VLP-16 on UDP 127\.0\.0\.1:0: no packet within 0\.3 s"
        ):
            c.open(0.3)
        assert 0.25 < time.monotonic() - started < 2.0


@pytest.mark.slow
def test_on_loopback_the_client_reads_what_the_sensor_sends_until_it_falls_silent() -> None:
    packet = vlp16_packet(steady_azimuths(9000, 20), POINTS, stamp_us=STAMP_US)
    with _client(stall_s=0.3) as c, _sender() as tx:
        c.bind()
        sender = _send_later(tx, packet, c.address, 3)
        c.open(2.0)
        sender.join()
        assert len(collect(c, 3 * len(POINTS), 2.0)) == 3 * len(POINTS)
        assert c.source_ip == LOOP
        assert c.packets_received == 3
        started = time.monotonic()
        with pytest.raises(DeviceError, match=r"VLP-16 on UDP 127\.0\.0\.1:\d+: no data packet"):
            read_for(c, 3.0)
        assert time.monotonic() - started < 1.0


def test_a_second_listener_on_the_port_is_refused_and_the_first_gets_every_packet() -> None:
    # with SO_REUSEADDR the second would bind too and, bound last, take every packet
    # sent to this address
    packet = vlp16_packet(steady_azimuths(9000, 20), POINTS, stamp_us=STAMP_US)
    with _client() as first, _sender() as tx:
        first.bind()
        port = first.address[1]
        second = VelodyneClient(VelodyneEndpoint("0.0.0.0", port))
        in_use = (
            rf"VLP-16 on UDP 0\.0\.0\.0:{port}: UDP port {port} is in use on this host, most "
            r"likely by another dronetrack live or info on this LiDAR$"
        )
        with pytest.raises(DeviceError, match=in_use):
            second.open(1.0)
        sender = _send_later(tx, packet, first.address, 3)
        first.open(2.0)
        sender.join()
        assert len(collect(first, 3 * len(POINTS), 2.0)) == 3 * len(POINTS)


def test_packets_from_another_address_are_ignored_with_device() -> None:
    packet = vlp16_packet([0] * 12, {(0, 0): (5000, 1)})
    with VelodyneClient(VelodyneEndpoint(LOOP, 0, device_ip="127.0.0.2")) as c, _sender() as tx:
        c.bind()
        sender = _send_later(tx, packet, c.address, 1)
        with pytest.raises(DeviceError, match="no packet within"):
            c.open(0.5)
        sender.join()
        assert c.packets_ignored == 1


@pytest.mark.parametrize(
    ("uri", "want"),
    [
        ("velodyne://", VelodyneEndpoint("0.0.0.0", 2368)),
        ("velodyne://2368", VelodyneEndpoint("0.0.0.0", 2368)),
        ("velodyne://2369", VelodyneEndpoint("0.0.0.0", 2369)),
        ("velodyne://192.168.1.100:2368", VelodyneEndpoint("192.168.1.100", 2368)),
        ("velodyne://2368?host=127.0.0.5", VelodyneEndpoint("127.0.0.5", 2368)),
        ("velodyne://127.0.0.5:2368?host=127.0.0.5", VelodyneEndpoint("127.0.0.5", 2368)),
        (
            "velodyne://2368?device=192.168.1.201",
            VelodyneEndpoint("0.0.0.0", 2368, "192.168.1.201"),
        ),
    ],
)
def test_uris(uri: str, want: VelodyneEndpoint) -> None:
    assert parse_velodyne_uri(uri) == want


@pytest.mark.parametrize(
    ("uri", "problem"),
    [
        ("livox://2368", "a VLP-16 is given as velodyne://PORT"),
        ("velodyne://192.168.1.201", "give the UDP port the sensor sends to"),
        ("velodyne://0", "'0' is not a UDP port"),
        ("velodyne://70000", "'70000' is not a UDP port"),
        ("velodyne://1.2.3:2368", "local address '1.2.3' is not an IPv4 address"),
        ("velodyne://2368/x", "takes no path"),
        ("velodyne://127.0.0.1:2368?host=127.0.0.2", "host=127.0.0.2 and the address"),
        ("velodyne://2368?port=1", "unknown query key 'port'"),
        ("velodyne://2368?device=1.2.3.4&device=1.2.3.4", "'device' is given twice"),
        ("velodyne://2368?x", "not key=value pairs"),
    ],
)
def test_bad_uris_name_the_problem(uri: str, problem: str) -> None:
    with pytest.raises(ConfigError, match=problem.replace("(", r"\(").replace(".", r"\.")):
        parse_velodyne_uri(uri)


GOOD = [
    vlp16_packet(steady_azimuths(a, 20), POINTS, stamp_us=STAMP_US + 1327 * i)
    for i, a in enumerate((0, 240, 480))
]


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(st.lists(st.one_of(damaged_packets(GOOD, 1206), st.sampled_from(GOOD)), max_size=8))
def test_damaged_packets_never_break_the_decoder(packets: list[bytes]) -> None:
    well_formed = [
        p
        for p in packets
        if len(p) == 1206
        and all(p[100 * b : 100 * b + 2] == b"\xff\xee" for b in range(12))
        and all(int.from_bytes(p[100 * b + 2 : 100 * b + 4], "little") < 36000 for b in range(12))
        and p[1204] in (0x37, 0x38, 0x39)
    ]
    with _client() as c:
        if any(p[1205] != 0x22 for p in well_formed):  # a damaged product byte
            with pytest.raises(DeviceError, match="product ID"):
                c.decode(packets)
            return
        batch = c.decode(packets)
    assert c.packets_malformed == len(packets) - len(well_formed)
    n = len(batch)
    assert batch.xyz.shape == (n, 3)
    assert np.all(np.isfinite(batch.xyz))
    assert np.all(np.diff(batch.t_ns) >= 0)
    assert np.all(batch.line < 16)
    assert (batch.firings is None) == (not well_formed)
