"""The VLP-16 packet codec against packets built by hand from the VLP-16 User Manual."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.config.spinning import head_rotation
from dronetrack.errors import InputError
from dronetrack.formats import velodyne as fv
from dronetrack.sim.mounted import side_mount
from dronetrack.sim.spinning import VLP16_ELEVATION_DEG, VLP16_VERTICAL_OFFSET_MM, vlp16_pattern
from velodyne_helpers import (
    FIRING_SEQUENCE_US,
    FIRING_US,
    MANUAL_CORRECTION_MM,
    MANUAL_ELEVATION_DEG,
    point_time_us,
    vlp16_packet,
)


def test_the_tables_and_timing_are_the_manuals_and_the_simulators() -> None:
    assert list(fv.ELEVATION_DEG) == MANUAL_ELEVATION_DEG == list(VLP16_ELEVATION_DEG)
    assert list(fv.VERTICAL_CORRECTION_MM) == MANUAL_CORRECTION_MM
    assert list(VLP16_VERTICAL_OFFSET_MM) == MANUAL_CORRECTION_MM
    pattern = vlp16_pattern()
    assert pytest.approx(pattern.cycle_s, abs=1e-15) == fv.FIRING_CYCLE_NS * 1e-9
    assert pytest.approx(pattern.firing_interval_s, abs=1e-15) == fv.FIRING_INTERVAL_NS * 1e-9
    assert round(FIRING_SEQUENCE_US * 1000) == fv.FIRING_CYCLE_NS
    # 24 sequences a packet: 1327.104 µs, 753.5 packets/s (manual §8.2.1: ~754)
    assert fv.packet_span_ns() == 1_327_104
    assert 1e9 / fv.packet_span_ns() == pytest.approx(753.5, abs=0.1)
    # rings by elevation, lowest first: laser IDs 0, 2, …, 14, 1, 3, …, 15
    assert list(fv.LASER_OF_RING) == [*range(0, 16, 2), *range(1, 16, 2)]


def test_the_side_mount_is_the_simulators() -> None:
    R = head_rotation("vlp16-side")
    assert R is not None
    np.testing.assert_allclose(R, side_mount(), atol=1e-15)
    assert head_rotation("vlp16") is None


def test_a_hand_built_packet_decodes_to_its_fields() -> None:
    az = [100 * b + 7 for b in range(12)]
    pts = {(0, 0): (5000, 12), (3, 17): (12345, 200), (11, 31): (65535, 255)}
    packet = vlp16_packet(az, pts, stamp_us=3_599_999_999, return_mode=0x38, product=0x22)
    got, ok = fv.decode_packets([packet])
    assert ok.tolist() == [True]
    assert got.azimuth[0].tolist() == az
    assert got.stamp_us.tolist() == [3_599_999_999]
    assert got.return_mode.tolist() == [0x38]
    assert got.product.tolist() == [0x22]
    for (b, k), (d, r) in pts.items():
        assert got.distance[0, b, k] == d
        assert got.reflectivity[0, b, k] == r
    assert int(got.distance.astype(bool).sum()) == 3


@pytest.mark.parametrize(
    "packet",
    [
        vlp16_packet([0] * 12)[:-1],  # 1205 bytes
        vlp16_packet([0] * 12) + b"\x00",  # 1207 bytes
        vlp16_packet([0] * 12, flag=b"\xff\xdd"),  # a VLS-128's upper block flag
        vlp16_packet([36000] + [0] * 11),  # an azimuth past 359.99°
        vlp16_packet([0] * 12, return_mode=0x00),  # no factory bytes
        b"",
    ],
)
def test_malformed_packets_are_flagged(packet: bytes) -> None:
    good = vlp16_packet([5] * 12, {(0, 0): (10, 1)})
    got, ok = fv.decode_packets([good, packet, good])
    assert ok.tolist() == [True, False, True]
    assert len(got) == 2


def test_the_firing_offsets_are_the_manuals() -> None:
    single = fv.firing_offsets_ns(fv.STRONGEST)
    for b in range(12):
        for k in range(32):
            want = point_time_us(0.0, b, k)
            assert single[b, k] == pytest.approx(want * 1000, abs=1e-6)
    assert single[11, 31] == 1_306_368  # 23 · 55.296 + 15 · 2.304 µs
    dual = fv.firing_offsets_ns(fv.DUAL)
    # dual return: blocks 2i and 2i + 1 hold the same two sequences (§9.4's table)
    np.testing.assert_array_equal(dual[0::2], dual[1::2])
    assert dual[3, 16] == round((2 * FIRING_SEQUENCE_US + FIRING_SEQUENCE_US) * 1000)
    assert dual[11, 15] == round((10 * FIRING_SEQUENCE_US + 15 * FIRING_US) * 1000)
    assert fv.packet_span_ns(fv.DUAL) == 12 * 55_296
    with pytest.raises(InputError, match="unknown Velodyne return mode 0x00"):
        fv.firing_offsets_ns(0)


def test_the_encoder_writes_the_manuals_bytes() -> None:
    distance = np.zeros((1, 12, 32))
    refl = np.zeros((1, 12, 32), np.uint8)
    distance[0, 0, 0], refl[0, 0, 0] = 10.0, 12  # 5000 × 2 mm
    distance[0, 3, 17], refl[0, 3, 17] = 24.69, 200  # 12345 × 2 mm
    distance[0, 5, 5] = 0.0005  # under one step: no return
    distance[0, 6, 6] = 140.0  # beyond the field's 131.07 m: no return
    distance[0, 7, 7] = np.nan
    azimuth = np.array([[b + 0.07 + (359.0 if b == 11 else 0.0) for b in range(12)]])
    got = fv.encode_packets(distance, refl, azimuth, np.array([3_600_000_123]))
    az = [100 * b + 7 for b in range(11)] + [(1100 + 7 + 35900) % 36000]
    want = vlp16_packet(az, {(0, 0): (5000, 12), (3, 17): (12345, 200)}, stamp_us=123)
    assert got == [want]


def test_the_encoder_refuses_mismatched_shapes() -> None:
    half = np.zeros((1, 12, 16))
    with pytest.raises(InputError, match=r"need distances and reflectivities \(n, 12, 32\)"):
        fv.encode_packets(half, half.astype(np.uint8), np.zeros((1, 12)), np.zeros(1, np.int64))


def test_beam_range_inverts_the_manuals_coordinates() -> None:
    # A return at R along laser c lies at R d + (0, 0, δ_c): its beam range is R.
    rng = np.random.default_rng(3)
    laser = rng.integers(0, 16, 200)
    R = rng.uniform(0.5, 120.0, 200)
    alpha = rng.uniform(0.0, 2 * np.pi, 200)
    w = np.radians(np.asarray(MANUAL_ELEVATION_DEG, float)[laser])
    xyz = np.stack(
        [
            R * np.cos(w) * np.cos(alpha),
            -R * np.cos(w) * np.sin(alpha),
            R * np.sin(w) + np.asarray(MANUAL_CORRECTION_MM)[laser] * 1e-3,
        ],
        axis=1,
    )
    np.testing.assert_allclose(fv.beam_range(xyz, laser), R, rtol=0, atol=1e-9)


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.integers(0, 0xFFFF), min_size=12 * 32, max_size=12 * 32),
    st.lists(st.integers(0, 35999), min_size=12, max_size=12),
    st.integers(0, fv.HOUR_US - 1),
    st.sampled_from([fv.STRONGEST, fv.LAST, fv.DUAL]),
)
def test_encode_then_decode_gives_back_the_fields(
    units: list[int], az: list[int], stamp: int, mode: int
) -> None:
    d = np.asarray(units, float).reshape(1, 12, 32) * 0.002
    refl = (np.arange(12 * 32) % 256).astype(np.uint8).reshape(1, 12, 32)
    packets = fv.encode_packets(
        d, refl, np.asarray(az, float).reshape(1, 12) / 100, np.array([stamp]), return_mode=mode
    )
    got, ok = fv.decode_packets(packets)
    assert ok.all()
    assert got.distance.ravel().tolist() == units
    assert got.azimuth.ravel().tolist() == az
    assert got.stamp_us.tolist() == [stamp]
    assert got.return_mode.tolist() == [mode]
    np.testing.assert_array_equal(got.reflectivity, refl)
