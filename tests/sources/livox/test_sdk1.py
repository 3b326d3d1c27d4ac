"""The Livox SDK 1 client against the emulated device on loopback: discovery,
handshake, heartbeat, sampling; every point of a known source arriving once with its
time; loss inferred from the timestamp gaps; a silent device and a dead heartbeat
raising DeviceError; a clean close; and the livox:// URI.

Sockets are on 127.0.0.1 with ports the kernel picks; every wait is bounded."""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.errors import ConfigError, DeviceError
from dronetrack.formats.livox import sdk1 as s1
from dronetrack.sim.emulate.livox import EmulatedLivox, GridSource, grid_points
from dronetrack.sources.assembly import PointBatch
from dronetrack.sources.livox.sdk1 import LivoxClient, LivoxEndpoint, parse_livox_uri
from livox_helpers import LOOP, assert_refused_beside, collect, read_for, settled

DT = {7: 4_167, 1: 10_000}  # ns between firings (livox_ros_driver lds.h)
N = {7: 96, 1: 100}  # firings per packet of data types 2 and 0


@contextmanager
def linked(
    source: GridSource,
    dev_type: int = 7,
    broadcast: bool = True,
    host: str | None = None,
    **client_kw: object,
) -> Iterator[tuple[LivoxClient, EmulatedLivox]]:
    """An emulated device and a bound client that knows its port (and announces
    ``host``, if given, as its address), both closed after."""
    dev = EmulatedLivox(source, dev_type=dev_type, device_port=0, broadcast_period_s=0.05)
    ep = LivoxEndpoint(LOOP, host, 0, 0, 0, dev.address[1])
    kw: dict[str, object] = {"heartbeat_period_s": 0.2, "discover_s": 1.0} | client_kw
    client = LivoxClient(ep, **kw)  # type: ignore[arg-type]
    try:
        client.bind()
        if broadcast:
            dev.broadcast_to = (LOOP, client.broadcast_port)
        dev.start()
        yield client, dev
    finally:
        client.close()
        dev.close()


def assert_points_are(batch: PointBatch, k: np.ndarray, dev_type: int) -> None:
    """``batch`` holds exactly the grid points of firings ``k``, each at k·Δt."""
    np.testing.assert_array_equal(batch.t_ns, k * DT[dev_type])
    np.testing.assert_allclose(batch.xyz, grid_points(k), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(batch.reflectivity, k % 251)
    # line: the firing's index in its packet modulo 6 for the Avia (lds.cpp), 0 for a Mid-40
    lines = 6 if dev_type == 7 else 1
    np.testing.assert_array_equal(batch.line, k % N[dev_type] % lines)


@pytest.mark.parametrize("dev_type", [7, 1])
def test_discovery_handshake_and_heartbeat(dev_type: int) -> None:
    with linked(GridSource(DT[dev_type], 3.0), dev_type) as (client, dev):
        client.open(timeout_s=2.0)
        assert client.dev_type == dev_type
        assert client.broadcast_code == "0EMULATEDLIVOX1"
        assert dev.host is not None
        assert (dev.host.ip, dev.host.cmd_port, dev.host.data_port) == (
            LOOP,
            client.cmd_port,
            client.data_port,
        )
        assert dev.sampling
        read_for(client, 0.9)
        # a heartbeat every 0.2 s for 0.9 s: 4 or 5 sent, each answered
        assert client.heartbeats_sent >= 4
        assert client.heartbeats_missed == 0
        assert dev.heartbeats_answered >= client.heartbeats_sent - 1


@pytest.mark.parametrize("dev_type", [7, 1])
@pytest.mark.slow
def test_every_point_arrives_once_with_its_time(dev_type: int) -> None:
    source = GridSource(DT[dev_type], 1.0, stride=3)
    k = source.firing_indices()
    with linked(source, dev_type) as (client, dev):
        client.open(timeout_s=2.0)
        batch = collect(client, len(k))
        assert_points_are(batch, k, dev_type)
        assert client.packets_lost == 0
        assert client.packets_malformed == 0
        assert client.queue_dropped == 0
        assert dev.points_dropped == 0
        assert (
            client.packets_received
            == settled(lambda: dev.packets_sent, client.packets_received)
            == -(-int(k[-1] + 1) // N[dev_type])
        )


def test_without_a_broadcast_the_handshake_goes_straight_to_the_device() -> None:
    """No discovery: the Mid-40's 10 µs firing interval comes from its data type 0."""
    source = GridSource(DT[1], 0.5, stride=2)
    k = source.firing_indices()
    with linked(source, 1, broadcast=False, discover_s=0.2) as (client, dev):
        client.open(timeout_s=2.0)
        assert client.dev_type is None
        assert dev.broadcasts_sent == 0
        assert_points_are(collect(client, len(k)), k, 1)
        assert client.packets_lost == 0


def test_lost_packets_are_counted_from_the_timestamp_gaps() -> None:
    source = GridSource(DT[7], 0.5)
    k = source.firing_indices()
    n_packets = -(-len(k) // N[7])
    every = 7
    assert n_packets % every != 0  # the last packet arrives, so every gap shows
    with linked(source) as (client, dev):
        dev.drop_every = every
        client.open(timeout_s=2.0)
        kept = k[(k // N[7] + 1) % every != 0]  # packet p = ⌊k/n⌋ is dropped if (p+1) mod 7 = 0
        batch = collect(client, len(kept))
        assert dev.packets_dropped == n_packets // every
        assert client.packets_lost == dev.packets_dropped
        assert_points_are(batch, kept, 7)


@pytest.mark.slow
def test_a_device_that_stops_sending_raises_device_error_within_1_5_s() -> None:
    with linked(GridSource(DT[7], 5.0)) as (client, dev):
        client.open(timeout_s=2.0)
        assert len(client.read(0.5)) > 0
        dev.paused = True
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match=r"Livox Avia at 127\.0\.0\.1: no point packet"):
            read_for(client, 3.0)
        # stall_s = 1 s after the last packet, seen within one 50 ms wait
        assert 0.9 < time.monotonic() - t0 < 1.5


@pytest.mark.parametrize(
    ("host", "why"),
    [
        (None, None),
        ("192.0.2.1", ", not an address of this host"),  # TEST-NET-1: on no interface
        ("127.0.0.9", r" \(this host reaches 127\.0\.0\.1 from 127\.0\.0\.1\)"),
    ],
)
@pytest.mark.slow
def test_no_point_packet_at_all_names_a_given_host_address(
    host: str | None, why: str | None
) -> None:
    with linked(GridSource(DT[7], 5.0), host=host) as (client, dev):
        dev.paused = True  # nothing arrives, as from a device told a wrong address
        client.open(timeout_s=2.0)
        with pytest.raises(DeviceError, match="no point packet for 1") as failed:
            read_for(client, 3.0)
        assert dev.host is not None
        assert dev.host.ip == (host or LOOP)
        sent = re.escape(f"; it was told to send to {host}:{client.data_port}")
    message = str(failed.value)
    if why is None:  # the routed address: the device reaches it
        assert "--host-ip" not in message
    else:
        assert re.search(rf"{sent}{why}: check --host-ip \(the URI's host=\)$", message)


@pytest.mark.slow
def test_a_dead_heartbeat_raises_device_error() -> None:
    with linked(GridSource(DT[7], 5.0), heartbeat_period_s=0.1, heartbeat_timeout_s=0.5) as (
        client,
        dev,
    ):
        client.open(timeout_s=2.0)
        dev.answer_heartbeats = False
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match=r"127\.0\.0\.1: no heartbeat ACK for 0\.5 s"):
            read_for(client, 3.0)
        assert time.monotonic() - t0 < 1.0
        assert client.heartbeats_missed >= 3  # 0.5 s of beats every 0.1 s, none answered


@pytest.mark.slow
def test_close_is_clean_and_idempotent() -> None:
    with linked(GridSource(DT[7], 5.0)) as (client, dev):
        with client:
            client.open(timeout_s=2.0)
            assert len(client.read(0.3)) > 0
        t0 = time.monotonic()
        client.close()  # again: nothing to do
        assert time.monotonic() - t0 < 0.1
        assert dev.host is None
        assert not dev.sampling
        assert not any(t.is_alive() for t in client._threads)
        with pytest.raises(DeviceError, match="not sampling"):
            client.read(0.1)
        with pytest.raises(DeviceError, match="not bound"):
            _ = client.data_port


@pytest.mark.slow
def test_a_device_that_does_not_answer_fails_open_within_its_timeout() -> None:
    silent = EmulatedLivox(GridSource(DT[7], 1.0), device_port=0)  # bound, never started
    try:
        ep = LivoxEndpoint(LOOP, None, 0, 0, 0, silent.address[1])
        client = LivoxClient(ep, discover_s=0.1)
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match=r"127\.0\.0\.1: no handshake ACK"):
            client.open(timeout_s=0.6)
        assert time.monotonic() - t0 < 1.0
        assert not any(t.is_alive() for t in client._threads)
    finally:
        silent.close()


@pytest.mark.parametrize(("taken", "what"), [("cmd_port", "commands"), ("data_port", "point data")])
@pytest.mark.slow
def test_a_second_client_on_a_taken_port_is_refused_and_the_first_runs_on(
    taken: str, what: str
) -> None:
    # with SO_REUSEADDR the second would bind too and, bound last, take the first's
    # ACKs or points: the first then stops with "no point packet"
    with linked(GridSource(DT[7], 5.0)) as (first, dev):
        first.open(timeout_s=2.0)
        ports = {"cmd_port": first.cmd_port, "data_port": first.data_port}
        ep = LivoxEndpoint(LOOP, None, 0, 0, 0, dev.address[1])
        second = LivoxClient(replace(ep, **{taken: ports[taken]}), discover_s=0.1)
        assert_refused_beside(first, second, 1, ports[taken], what, taken)
        assert dev.host is not None  # still the first's: the second sent no handshake
        assert (dev.host.cmd_port, dev.host.data_port) == (first.cmd_port, first.data_port)


def test_a_second_client_shares_the_discovery_port() -> None:
    # the device's broadcast reaches every host socket on the port (livox_net)
    with linked(GridSource(DT[7], 1.0)) as (first, _):
        second = LivoxClient(LivoxEndpoint(LOOP, None, 0, 0, first.broadcast_port))
        try:
            second.bind()
            assert second.broadcast_port == first.broadcast_port
        finally:
            second.close()


def test_the_queue_keeps_the_newest_packets_and_counts_the_dropped() -> None:
    with linked(GridSource(DT[7], 5.0), max_packets=10) as (client, dev):
        client.open(timeout_s=2.0)
        time.sleep(0.2)  # 0.2 s of an Avia: about 500 packets
        dev.paused = True
        time.sleep(0.1)  # the packets on their way arrive; then nothing more comes
        packets = client.packets(0.1)
        assert len(packets) == 10
        assert client.queue_dropped == client.packets_received - 10 > 0
        stamps = [int.from_bytes(p[10:18], "little") for p in packets]
        newest = (client.packets_received - 1) * N[7] * DT[7]
        assert stamps == [newest - (9 - i) * N[7] * DT[7] for i in range(10)]


def test_decode_skips_and_counts_malformed_packets() -> None:
    client = LivoxClient(LivoxEndpoint(LOOP))
    client.dev_type = 7
    good = s1.encode_point_packets(
        grid_points(np.arange(96)),
        np.zeros(96, np.uint8),
        data_type=2,
        t0_ns=0,
        point_interval_ns=DT[7],
    )[0]
    batch = client.decode([good, b"junk", good[:-1]])
    assert client.packets_malformed == 2
    np.testing.assert_array_equal(batch.t_ns, np.arange(96) * DT[7])
    assert len(client.decode([])) == 0


def test_decode_gives_the_packets_firings_with_or_without_a_return() -> None:
    """Two Avia packets of 96 firings, returns only in the first ten of the first:
    the batch holds those ten points, and its firings span both packets, from firing
    0 to firing 191 (4.167 µs apart), so time is known to have passed where the sky
    sent nothing back."""
    client = LivoxClient(LivoxEndpoint(LOOP))
    client.dev_type = 7
    xyz = grid_points(np.arange(192))
    xyz[10:] = 0.0  # no return
    packets = s1.encode_point_packets(
        xyz, np.zeros(192, np.uint8), data_type=2, t0_ns=5_000, point_interval_ns=DT[7]
    )
    batch = client.decode(packets)
    np.testing.assert_array_equal(batch.t_ns, 5_000 + np.arange(10) * DT[7])
    assert batch.firings == (5_000, 5_000 + 191 * DT[7])
    sky = client.decode(packets[1:])
    assert len(sky) == 0
    assert sky.firings == (5_000 + 96 * DT[7], 5_000 + 191 * DT[7])
    assert client.decode([]).firings is None
    assert client.decode([b"junk"]).firings is None


# --- livox:// URIs ---------------------------------------------------------------


def test_a_uri_with_only_the_ip_takes_the_sdk_defaults() -> None:
    assert parse_livox_uri("livox://192.168.1.3") == LivoxEndpoint(
        "192.168.1.3", None, 55501, 56001, 55000, 65000
    )


def test_a_uri_sets_every_port_and_the_host() -> None:
    uri = "livox://10.0.0.2?host=10.0.0.9&cmd_port=0&data_port=7000&broadcast_port=0&device_port=1"
    assert parse_livox_uri(uri) == LivoxEndpoint("10.0.0.2", "10.0.0.9", 0, 7000, 0, 1)


@given(
    ports=st.fixed_dictionaries(
        {}, optional={k: st.integers(0, 65535) for k in ("cmd_port", "data_port", "broadcast_port")}
    ),
    device=st.integers(1, 65535),
    ip=st.ip_addresses(v=4).map(str),
)
def test_any_valid_ports_round_trip(ports: dict[str, int], device: int, ip: str) -> None:
    query = "&".join([f"{k}={v}" for k, v in ports.items()] + [f"device_port={device}"])
    ep = parse_livox_uri(f"livox://{ip}?{query}")
    assert ep.device_ip == ip
    assert ep.device_port == device
    for key, value in ports.items():
        assert getattr(ep, key) == value


@pytest.mark.parametrize(
    ("uri", "problem"),
    [
        ("udp://192.168.1.3", "livox://IP"),
        ("livox://", "no device IP"),
        ("livox://lidar.local", "not an IPv4 address"),
        ("livox://192.168.1.300", "not an IPv4 address"),
        ("livox://192.168.1.3:65000", "device_port"),
        ("livox://192.168.1.3/points", "no path"),
        ("livox://192.168.1.3?port=1", "unknown query key 'port'"),
        ("livox://192.168.1.3?cmd_port=abc", "cmd_port='abc' is not a port"),
        ("livox://192.168.1.3?data_port=70000", "is not a port in 0..65535"),
        ("livox://192.168.1.3?device_port=0", "is not a port in 1..65535"),
        ("livox://192.168.1.3?data_port=1&data_port=2", "given twice"),
        ("livox://192.168.1.3?host=me", "host 'me' is not an IPv4"),
        ("livox://192.168.1.3?host", "not key=value"),
    ],
)
def test_bad_uris_name_the_problem(uri: str, problem: str) -> None:
    with pytest.raises(ConfigError, match=problem.replace(".", r"\.").replace("?", r"\?")) as info:
        parse_livox_uri(uri)
    assert "\n" not in str(info.value)
