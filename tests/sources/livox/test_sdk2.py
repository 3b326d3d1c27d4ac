"""The Livox SDK 2 (Mid-360) client: its decoding and loss count against packets
built by hand from the Mid-360 protocol document (``tests/livox_helpers.py``), a fuzz
of damaged packets, the livox2:// URI, and the client against the emulated device on
loopback: discovery, configuration, keep-alive, every point arriving once with its
time, loss from the udp_cnt sequence, a silent device and a dead keep-alive raising
DeviceError, and a clean close.

Sockets are on 127.0.0.1 with ports the kernel picks; every wait is bounded."""

from __future__ import annotations

import math
import struct
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import ConfigError, DeviceError
from dronetrack.sim.emulate.livox import GridSource, grid_points
from dronetrack.sim.emulate.livox2 import EmulatedLivox2
from dronetrack.sources.livox.sdk2 import Livox2Client, Livox2Endpoint, parse_livox2_uri
from livox_helpers import (
    LOOP,
    T0,
    assert_refused_beside,
    collect,
    damaged_packets,
    loopback_udp,
    port_of,
    read_for,
    sdk2_frame,
    sdk2_packet,
    settled,
)

DT = 5_000  # ns between points at 200,000 points/s
N = 96  # points per packet (protocol document, "Data Types")
P = N * DT  # ns a packet spans
FRAME = 100_000_000  # the emulator's point-cloud frame [ns]


# --- decoding hand-built packets ----------------------------------------------------


def _records(data_type: int, n: int = N) -> tuple[bytes, np.ndarray]:
    """n records of point i at x = 1 + i cm, y = −2 m, z = 0.5 m (spherical: depth
    1 + i cm along +x), reflectivity i, tag 7; and the expected xyz."""
    i = np.arange(n)
    if data_type == 1:  # x, y, z int32 mm, reflectivity, tag
        recs = b"".join(struct.pack("<iiiBB", 1000 + 10 * k, -2000, 500, k, 7) for k in i)
    elif data_type == 2:  # x, y, z int16 in units of 10 mm
        recs = b"".join(struct.pack("<hhhBB", 100 + k, -200, 50, k, 7) for k in i)
    else:  # depth u32 mm, zenith 90° and azimuth 0° in 0.01°: along +x
        recs = b"".join(struct.pack("<IHHBB", 1000 + 10 * k, 9000, 0, k, 7) for k in i)
        return recs, np.stack([1.0 + 0.01 * i, 0 * i, 0 * i], axis=1)
    return recs, np.stack([1.0 + 0.01 * i, np.full(n, -2.0), np.full(n, 0.5)], axis=1)


def _client() -> Livox2Client:
    return Livox2Client(Livox2Endpoint(LOOP))


@pytest.mark.parametrize("data_type", [1, 2, 3])
def test_decode_gives_every_point_with_its_time_and_line(data_type: int) -> None:
    recs, xyz = _records(data_type)
    # time_interval 4750 × 0.1 µs over the 95 gaps of 96 points: 5000 ns apart
    packet = sdk2_packet(data_type, recs, N, interval=4750)
    batch = _client().decode([packet])
    np.testing.assert_array_equal(batch.t_ns, T0 + DT * np.arange(N))
    np.testing.assert_allclose(batch.xyz, xyz, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(batch.reflectivity, np.arange(N))
    # line: the point's index in its packet mod 4 (livox_ros_driver2 pub_handler.cpp)
    np.testing.assert_array_equal(batch.line, np.arange(N) % 4)


def test_decode_drops_no_return_points_skips_imu_and_sorts_by_time() -> None:
    first = struct.pack("<iiiBB", 5000, 0, 0, 9, 0)
    later = sdk2_packet(1, first + bytes(14 * 95), N, interval=4750, stamp=T0 + P)
    earlier = sdk2_packet(2, struct.pack("<hhhBB", 1, 2, 3, 4, 0) * 3, 3, interval=20)
    imu = sdk2_packet(0, struct.pack("<6f", 0, 0, 0, 0, 0, 1), 1, interval=0)
    client = _client()
    batch = client.decode([later, imu, earlier])
    # 3 points 1 µs apart (time_interval 20 over 2 gaps), then the one return of `later`
    np.testing.assert_array_equal(batch.t_ns, [T0, T0 + 1000, T0 + 2000, T0 + P])
    np.testing.assert_allclose(batch.xyz[-1], [5.0, 0, 0])
    np.testing.assert_allclose(batch.xyz[0], [0.01, 0.02, 0.03])
    np.testing.assert_array_equal(batch.line, [0, 1, 2, 0])
    assert client.packets_malformed == 0


def test_decode_gives_the_packets_firings_with_or_without_a_return() -> None:
    """Two packets of 96 points 5 µs apart, returns only in the first ten of the first:
    the batch holds those ten points, and its firings span both packets, from point 0
    of the first to point 95 of the second, so time is known to have passed where the
    sky sent nothing back."""
    hits = b"".join(struct.pack("<iiiBB", 1000 + k, 0, 0, 9, 0) for k in range(10))
    first = sdk2_packet(1, hits + bytes(14 * 86), N, interval=4750)
    second = sdk2_packet(1, bytes(14 * N), N, interval=4750, stamp=T0 + P, udp_cnt=4)
    imu = sdk2_packet(0, struct.pack("<6f", 0, 0, 0, 0, 0, 1), 1, interval=0, stamp=T0 + 9 * P)
    client = _client()
    batch = client.decode([first, second, imu])
    np.testing.assert_array_equal(batch.t_ns, T0 + DT * np.arange(10))
    assert batch.firings == (T0, T0 + P + 95 * DT)
    sky = client.decode([second])
    assert len(sky) == 0
    assert sky.firings == (T0 + P, T0 + P + 95 * DT)
    assert client.decode([imu]).firings is None
    assert client.decode([]).firings is None
    assert client.decode([b"junk"]).firings is None


def test_decode_skips_and_counts_malformed_packets() -> None:
    recs, _ = _records(1)
    good = sdk2_packet(1, recs, N, interval=4750)
    client = _client()
    batch = client.decode([good, b"junk", good[:-1], b"\x01" + good[1:]])
    assert client.packets_malformed == 3
    assert len(batch) == N
    assert len(client.decode([])) == 0


GOOD = [sdk2_packet(t, _records(t)[0], N, interval=4750) for t in (1, 2, 3)]


@given(st.lists(damaged_packets(GOOD, header_bytes=36), max_size=5))
@settings(max_examples=150, deadline=None)
def test_damaged_packets_are_counted_never_raised(bufs: list[bytes]) -> None:
    client = _client()
    batch = client.decode([GOOD[0], *bufs])
    assert 0 <= client.packets_malformed <= len(bufs)
    assert len(batch) >= N  # the good packet's points always come through
    assert np.all(np.diff(batch.t_ns) >= 0)
    for buf in bufs:
        client._count_loss(buf)  # never raises either


# --- loss from udp_cnt -------------------------------------------------------------


def _counted(sequence: list[tuple[int, int]], data_type: int = 1) -> int:
    """packets_lost after packets with these (frame_cnt, udp_cnt)."""
    client = _client()
    for frame_cnt, udp_cnt in sequence:
        client._count_loss(sdk2_packet(data_type, bytes(14), 1, 0, 0, udp_cnt, frame_cnt))
    return client.packets_lost


@pytest.mark.parametrize(
    ("sequence", "lost"),
    [
        ([(0, 0), (0, 1), (0, 2)], 0),
        ([(0, 0), (0, 3)], 2),  # udp_cnt 1 and 2 missing
        ([(0, 5), (1, 0), (1, 1)], 0),  # a new frame starts at 0
        ([(0, 5), (1, 2)], 2),  # the new frame's first two missing
        ([(0, 5), (0, 0), (0, 1)], 0),  # cleared at a frame start frame_cnt does not show
        ([(0, 65534), (0, 65535), (0, 0), (0, 2)], 1),  # wraps at 16 bits
        ([(0, 0), (0, 1), (0, 1)], 0),  # a repeated packet is not a loss
    ],
)
def test_loss_follows_the_udp_cnt_sequence(sequence: list[tuple[int, int]], lost: int) -> None:
    assert _counted(sequence) == lost


def test_imu_packets_do_not_count_in_the_point_loss() -> None:
    client = _client()
    for udp_cnt in (0, 5, 9):
        client._count_loss(sdk2_packet(0, bytes(24), 1, 0, 0, udp_cnt, 0))
    assert client.packets_lost == 0


# --- livox2:// URIs ----------------------------------------------------------------


def test_a_uri_with_only_the_ip_takes_the_sdk_defaults() -> None:
    # host ports 56101 and 56301, detection port 56000, device command port 56100
    # (Livox-SDK2 comm/define.h)
    assert parse_livox2_uri("livox2://192.168.1.12") == Livox2Endpoint(
        "192.168.1.12", None, 56101, 56301, 56000, 56100, 56000, True, None
    )


def test_a_uri_sets_every_key() -> None:
    uri = (
        "livox2://10.0.0.2?host=10.0.0.9&cmd_port=0&point_port=7000&discovery_port=0"
        "&device_port=1&device_discovery_port=2&broadcast=0&data_type=3"
    )
    assert parse_livox2_uri(uri) == Livox2Endpoint(
        "10.0.0.2", "10.0.0.9", 0, 7000, 0, 1, 2, False, 3
    )


@pytest.mark.parametrize(
    ("uri", "problem"),
    [
        ("livox://192.168.1.12", "livox2://IP"),
        ("livox2://", "no device IP"),
        ("livox2://192.168.1.12:56100", "device_port"),
        ("livox2://192.168.1.12?data_type=0", "data_type='0' is not one of 1, 2, 3"),
        ("livox2://192.168.1.12?broadcast=yes", "broadcast='yes' is not one of 0, 1"),
        ("livox2://192.168.1.12?device_discovery_port=0", "is not a port in 1..65535"),
        ("livox2://192.168.1.12?data_port=1", "unknown query key 'data_port'"),
    ],
)
def test_bad_uris_name_the_problem(uri: str, problem: str) -> None:
    with pytest.raises(ConfigError, match=problem.replace(".", r"\.").replace("?", r"\?")):
        parse_livox2_uri(uri)


# --- against the emulated Mid-360 ----------------------------------------------------


@contextmanager
def linked(
    source: GridSource, discover: bool = True, data_type: int | None = None, **client_kw: object
) -> Iterator[tuple[Livox2Client, EmulatedLivox2]]:
    """A running emulated Mid-360 and a client that finds it by discovery (its
    configured command port, 1, is wrong: only discovery gives the right one), or
    that is given its command port; both closed after."""
    dev = EmulatedLivox2(source, discovery_port=0, cmd_port=0, push_port=0, point_port=0)
    device_port = 1 if discover else dev.address[1]
    ep = Livox2Endpoint(
        LOOP, None, 0, 0, 0, device_port, dev.discovery_address[1], False, data_type
    )
    kw: dict[str, object] = {"heartbeat_period_s": 0.2, "discover_s": 1.0} | client_kw
    client = Livox2Client(ep, **kw)  # type: ignore[arg-type]
    try:
        dev.start()
        yield client, dev
    finally:
        client.close()
        dev.close()


def test_discovery_configuration_and_keep_alive() -> None:
    with linked(GridSource(DT, 3.0)) as (client, dev):
        client.open(timeout_s=2.0)
        assert (client.dev_type, client.serial) == (9, "0EMULATEDMID360")
        assert client.name == "Livox Mid-360 at 127.0.0.1"
        assert dev.discoveries_answered >= 1
        # status pushes to the command port; points and IMU data to the point port
        hosts = {k: (h.host_ip, h.host_port) for k, h in dev.hosts.items()}
        cmd, point = (LOOP, client.cmd_port), (LOOP, client.point_port)
        assert hosts == {0x0005: cmd, 0x0006: point, 0x0007: point}
        assert dev.sampling
        read_for(client, 0.9)
        # a work-state query every 0.2 s for 0.9 s: 4 or 5 sent, all answered
        assert client.heartbeats_sent >= 4
        assert client.heartbeats_missed == 0
        assert dev.queries_answered >= client.heartbeats_sent - 1
        assert client.work_state == 0x01  # SAMPLING
        assert client.pushes_received >= 1  # the emulator pushes once a second


# the grid's whole-mm points are exact in data type 1; type 2 rounds to 10 mm (half a
# unit per axis); type 3 rounds depth to 1 mm and both angles to 0.01°: half a mm plus
# half a quantum of arc on each angle at the grid's farthest 11.2 m
SPHERICAL_TOL_M = 0.0005 + 11.2 * math.radians(0.005) * math.sqrt(2)


@pytest.mark.parametrize(
    ("data_type", "tol_m"), [(None, 1e-9), (2, 0.005 + 1e-9), (3, SPHERICAL_TOL_M)]
)
@pytest.mark.slow
def test_every_point_arrives_once_with_its_time(data_type: int | None, tol_m: float) -> None:
    source = GridSource(DT, 1.0, stride=3)
    k = source.firing_indices()
    with linked(source, data_type=data_type) as (client, dev):
        client.open(timeout_s=2.0)
        batch = collect(client, len(k))
        assert dev.data_type == (data_type or 1)
        np.testing.assert_array_equal(batch.t_ns, k * DT)
        np.testing.assert_allclose(batch.xyz, grid_points(k), rtol=0, atol=tol_m)
        np.testing.assert_array_equal(batch.reflectivity, k % 251)
        np.testing.assert_array_equal(batch.line, k % N % 4)
        assert client.packets_lost == client.packets_malformed == client.queue_dropped == 0
        assert (
            client.packets_received
            == settled(lambda: dev.packets_sent, client.packets_received)
            == -(-int(k[-1] + 1) // N)
        )


def test_without_discovery_the_client_configures_the_given_port() -> None:
    source = GridSource(DT, 0.3, stride=5)
    k = source.firing_indices()
    with linked(source, discover=False, discover_s=0.0) as (client, dev):
        client.open(timeout_s=2.0)
        assert client.dev_type is None
        assert dev.discoveries_answered == 0
        np.testing.assert_array_equal(collect(client, len(k)).t_ns, k * DT)


def test_lost_packets_are_counted_from_udp_cnt() -> None:
    source = GridSource(DT, 0.5)
    k = source.firing_indices()
    n_packets = -(-len(k) // N)
    # every 209th packet: 208, the last of frame 0 (frames hold 208⅓ packets), 417, the
    # first of frame 2, then two inside frames 3 and 4
    every = 209
    assert n_packets % every != 0  # the last packet arrives
    p = np.arange(n_packets)
    dropped = p[(p + 1) % every == 0]
    # a packet lost at the end of its frame leaves no gap in udp_cnt (the next packet
    # starts a frame at 0): the client sees the other losses
    frame = p * P // FRAME
    visible = int(np.sum(frame[dropped] == frame[dropped + 1]))
    assert (len(dropped), visible) == (4, 3)
    with linked(source) as (client, dev):
        dev.drop_every = every
        client.open(timeout_s=2.0)
        kept = k[(k // N + 1) % every != 0]
        batch = collect(client, len(kept))
        assert dev.packets_dropped == len(dropped)
        assert client.packets_lost == visible
        np.testing.assert_array_equal(batch.t_ns, kept * DT)


@pytest.mark.slow
def test_a_device_that_stops_sending_raises_device_error_within_1_5_s() -> None:
    with linked(GridSource(DT, 5.0)) as (client, dev):
        client.open(timeout_s=2.0)
        assert len(client.read(0.5)) > 0
        dev.paused = True
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match=r"Livox Mid-360 at 127\.0\.0\.1: no point packet"):
            read_for(client, 3.0)
        # stall_s = 1 s after the last packet, seen within one 50 ms wait
        assert 0.9 < time.monotonic() - t0 < 1.5


@pytest.mark.slow
def test_a_dead_keep_alive_raises_device_error() -> None:
    with linked(GridSource(DT, 5.0), heartbeat_period_s=0.1, heartbeat_timeout_s=0.5) as (
        client,
        dev,
    ):
        client.open(timeout_s=2.0)
        dev.answer_commands = False
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match=r"127\.0\.0\.1: no work-state ACK for 0\.5 s"):
            read_for(client, 3.0)
        assert time.monotonic() - t0 < 1.0
        assert client.heartbeats_missed >= 3  # 0.5 s of queries every 0.1 s, none answered


@pytest.mark.slow
def test_close_stops_sampling_and_is_idempotent() -> None:
    with linked(GridSource(DT, 5.0)) as (client, dev):
        with client:
            client.open(timeout_s=2.0)
            assert len(client.read(0.3)) > 0
        t0 = time.monotonic()
        client.close()
        assert time.monotonic() - t0 < 0.1
        assert not dev.sampling  # work mode IDLE sent at close
        assert not any(t.is_alive() for t in client._threads)
        with pytest.raises(DeviceError, match="not sampling"):
            client.read(0.1)


@pytest.mark.parametrize(
    ("taken", "what"), [("cmd_port", "commands"), ("point_port", "point data")]
)
@pytest.mark.slow
def test_a_second_client_on_a_taken_port_is_refused_and_the_first_runs_on(
    taken: str, what: str
) -> None:
    # with SO_REUSEADDR the second would bind too and, bound last, take the first's
    # ACKs or points, and configure the device to send to its own ports
    with linked(GridSource(DT, 5.0)) as (first, dev):
        first.open(timeout_s=2.0)
        ports = {"cmd_port": first.cmd_port, "point_port": first.point_port}
        hosts = dict(dev.hosts)
        ep = replace(first.endpoint, device_port=dev.address[1], **{taken: ports[taken]})
        second = Livox2Client(ep, discover_s=0.0)
        assert_refused_beside(first, second, 2, ports[taken], what, taken)
        assert dev.hosts == hosts  # the second configured nothing


@pytest.mark.slow
def test_a_device_that_does_not_answer_fails_open_within_its_timeout() -> None:
    silent = EmulatedLivox2(
        GridSource(DT, 1.0), discovery_port=0, cmd_port=0, push_port=0, point_port=0
    )
    try:  # bound, never started
        ep = Livox2Endpoint(
            LOOP, None, 0, 0, 0, silent.address[1], silent.discovery_address[1], False
        )
        client = Livox2Client(ep, discover_s=0.1)
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match=r"127\.0\.0\.1: no host configuration ACK"):
            client.open(timeout_s=0.6)
        assert time.monotonic() - t0 < 1.0
        assert not any(t.is_alive() for t in client._threads)
    finally:
        silent.close()


# --- the device information against a device answering hand-built frames ------------

INFO_KEYS = [0x8000, 0x8001, 0x8002, 0x8003, 0x8004, 0x8005, 0x8006]


def _kv(key: int, value: bytes) -> bytes:
    return struct.pack("<HH", key, len(value)) + value


@contextmanager
def hand_built_device(inquiry: bytes | None) -> Iterator[int]:
    """A device on 127.0.0.1 (its command port yielded) that answers, with frames built
    by hand: 0x0100 with ret_code 0, a work-state query (the keep-alive) with IDLE, and
    any other 0x0101 with the ACK data ``inquiry`` (None: no answer)."""
    sock = loopback_udp()
    sock.settimeout(0.05)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                buf, peer = sock.recvfrom(2048)
            except TimeoutError:
                continue
            (seq, cmd_id), data = struct.unpack_from("<IH", buf, 4), buf[24:]
            if cmd_id == 0x0100:
                reply = struct.pack("<BH", 0, 0)
            elif data == struct.pack("<HHH", 1, 0, 0x8006):
                reply = struct.pack("<BH", 0, 1) + _kv(0x8006, b"\x02")
            elif inquiry is not None:
                reply = inquiry
            else:
                continue
            sock.sendto(sdk2_frame(cmd_id, 1, seq, reply, sender=1), peer)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield port_of(sock)
    finally:
        stop.set()
        thread.join(1.0)
        sock.close()


def _connected(device_port: int) -> Livox2Client:
    ep = Livox2Endpoint(LOOP, None, 0, 0, 0, device_port, 1, False)
    client = Livox2Client(ep, discover_s=0.0)
    client.connect(timeout_s=2.0)
    return client


def test_query_info_reads_what_the_device_reports() -> None:
    items = [
        _kv(0x8000, b"47MDL9W0020022\0\0"),
        _kv(0x8001, b"Mid-360 2021/12/01".ljust(64, b"\0")),
        _kv(0x8002, bytes([10, 11, 6, 35])),
        _kv(0x8006, b"\x02"),
    ]  # loader, hardware and MAC left out
    inquiry = struct.pack("<BH", 0, len(items)) + b"".join(items)
    with hand_built_device(inquiry) as port:
        client = _connected(port)
        try:
            info = client.query_info(timeout_s=1.0)
        finally:
            client.close()
    assert info is not None
    assert (info.serial, info.product, info.firmware) == (
        "47MDL9W0020022",
        "Mid-360 2021/12/01",
        "10.11.6.35",
    )
    assert (info.loader, info.hardware, info.mac, info.work_state) == (None, None, None, 2)


def test_query_info_asks_for_the_documented_keys_and_names_a_refusal() -> None:
    asked: list[bytes] = []
    refusal = struct.pack("<BH", 0x01, 0)  # ret_code 0x01 failure, no keys
    with hand_built_device(refusal) as port:
        client = _connected(port)
        original = client._send

        def spy(cmd_id: int, payload: bytes, cmd_type: int | None = None) -> int:
            if cmd_id == 0x0101:
                asked.append(payload)
            return original(cmd_id, payload, cmd_type)

        client._send = spy  # type: ignore[method-assign]
        try:
            with pytest.raises(DeviceError, match="parameter inquiry refused, ret_code 0x01"):
                client.query_info(timeout_s=1.0)
        finally:
            client.close()
    assert struct.pack("<HH7H", 7, 0, *INFO_KEYS) in asked


@pytest.mark.slow
def test_query_info_without_an_answer_is_none_and_the_link_stays_alive() -> None:
    with hand_built_device(None) as port:
        client = _connected(port)
        try:
            t0 = time.monotonic()
            assert client.query_info(timeout_s=0.3) is None
            assert 0.3 <= time.monotonic() - t0 < 1.0
            assert client._dead is None
        finally:
            client.close()
    with pytest.raises(DeviceError, match="not connected"):
        Livox2Client(Livox2Endpoint(LOOP)).query_info()


def test_query_info_of_the_emulated_mid360() -> None:
    with linked(GridSource(DT, 1.0)) as (client, dev):
        client.connect(timeout_s=2.0)
        info = client.query_info()
        assert info is not None
        assert (info.serial, info.firmware, info.work_state) == ("0EMULATEDMID360", "0.1.0.0", 2)
        assert info.product == "Mid-360 emulated"
        assert dev.queries_answered >= 1
