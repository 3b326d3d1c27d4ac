"""Scan patterns: Risley field-of-view edges, VLP-16 angles and timing, density, files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.errors import SensorError
from dronetrack.geometry.transforms import azimuth_elevation, unit
from dronetrack.sim.patterns import (
    VLP16_ELEVATION_DEG,
    avia_pattern,
    load_pattern_table,
    mid40_pattern,
    refract,
    vlp16_pattern,
)
from dronetrack.sim.sensors import make_sensor


def _off_axis_deg(d: np.ndarray) -> np.ndarray:
    return np.degrees(np.arccos(np.clip(d[:, 0], -1.0, 1.0)))


@given(
    st.floats(0.0, 1.4),
    st.floats(0.0, 2 * np.pi),
    st.floats(1.0, 2.0),
)
def test_refraction_obeys_snell(theta: float, phi: float, n_glass: float) -> None:
    normal = np.array([0.0, 0.0, -1.0])  # against a beam travelling up +z
    d = np.array([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])
    out, ok = refract(d, normal, 1.0, n_glass)
    assert ok
    assert np.isclose(np.linalg.norm(out), 1.0)
    # n_a sin θ_i = n_b sin θ_r, and the refracted ray stays in the plane of incidence.
    sin_r = np.linalg.norm(np.cross(out, -normal))
    assert np.isclose(np.sin(theta), n_glass * sin_r, atol=1e-12)
    assert abs(np.dot(np.cross(d, normal), out)) < 1e-12


def test_total_internal_reflection_is_reported() -> None:
    d = unit(np.array([0.8, 0.0, 0.6]))
    _, ok = refract(d, np.array([0.0, 0.0, -1.0]), 1.5, 1.0)
    assert not ok


def test_mid40_field_of_view_is_a_38_4_degree_circle() -> None:
    p = mid40_pattern().pulses(0.0, 2.0)
    assert len(p) == 200_000
    off = _off_axis_deg(p.dirs)
    # Datasheet: 38.4° circular.  The prism model reaches 38.32°.
    assert 2 * off.max() == pytest.approx(38.4, abs=0.15)
    az, el = azimuth_elevation(p.dirs)
    assert np.degrees(np.ptp(az)) == pytest.approx(38.4, abs=0.15)
    assert np.degrees(np.ptp(el)) == pytest.approx(38.4, abs=0.15)


def test_avia_field_of_view_is_70_4_by_77_2_degrees() -> None:
    p = avia_pattern().pulses(0.0, 2.0)
    assert len(p) == 480_000
    az, el = azimuth_elevation(p.dirs)
    assert np.degrees(np.ptp(az)) == pytest.approx(70.4, abs=0.3)
    assert np.degrees(np.ptp(el)) == pytest.approx(77.2, abs=0.3)
    # Six interleaved lines, 240,000 points/s.
    np.testing.assert_array_equal(p.line[:12], np.tile(np.arange(6), 2))
    np.testing.assert_allclose(np.diff(p.t[:10]), 1 / 240_000)


def test_avia_centre_stays_dense_over_minutes() -> None:
    pattern = avia_pattern()

    def near_axis(t0: float) -> int:
        return int(np.sum(_off_axis_deg(pattern.pulses(t0, t0 + 0.5).dirs) < 1.0))

    counts = [near_axis(t0) for t0 in (0.0, 30.0, 60.0, 120.0, 600.0)]
    assert min(counts) > 0.9 * max(counts)


def test_pattern_continues_across_frames() -> None:
    pattern = avia_pattern()
    whole = pattern.pulses(0.0, 0.3)
    parts = [pattern.pulses(0.1 * k, 0.1 * (k + 1)) for k in range(3)]
    assert [len(q) for q in parts] == [24_000] * 3
    np.testing.assert_allclose(np.concatenate([q.dirs for q in parts]), whole.dirs, atol=1e-10)


def _ring_density(dirs: np.ndarray, edges_deg: np.ndarray) -> np.ndarray:
    off = _off_axis_deg(dirs)
    counts, _ = np.histogram(off, bins=edges_deg)
    solid = 2 * np.pi * (np.cos(np.radians(edges_deg[:-1])) - np.cos(np.radians(edges_deg[1:])))
    return counts / solid


def test_avia_density_is_highest_at_the_centre() -> None:
    d = avia_pattern().pulses(0.0, 1.0).dirs
    density = _ring_density(d, np.arange(0.0, 36.0, 5.0))
    # Rings 0-5° against 25-30°: the centre is many times denser (research: ≈8×).
    assert density[0] / density[5] > 3.0
    assert np.all(np.diff(density[:4]) < 0)


def _coverage(dirs: np.ndarray, cell_deg: float, half_fov_deg: float) -> float:
    az, el = np.degrees(azimuth_elevation(dirs))
    inside = np.hypot(az, el) < half_fov_deg
    n = int(2 * half_fov_deg / cell_deg)
    grid = np.zeros((n, n), bool)
    i = ((az[inside] + half_fov_deg) / cell_deg).astype(int).clip(0, n - 1)
    j = ((el[inside] + half_fov_deg) / cell_deg).astype(int).clip(0, n - 1)
    grid[i, j] = True
    centres = (np.arange(n) + 0.5) * cell_deg - half_fov_deg
    in_circle = np.hypot(*np.meshgrid(centres, centres)) < half_fov_deg
    return float(grid[in_circle].mean())


def test_coverage_grows_with_integration_time() -> None:
    pattern = mid40_pattern()
    cov = [_coverage(pattern.pulses(0.0, t).dirs, 0.2, 19.0) for t in (0.05, 0.1, 0.2, 0.5, 1.0)]
    assert np.all(np.diff(cov) > 0)
    # Research notes (Mid-40, 0.2° cells): 14 % at 0.1 s, 76 % at 1 s.
    assert cov[1] == pytest.approx(0.144, abs=0.04)
    assert cov[4] == pytest.approx(0.76, abs=0.06)


def test_vlp16_angles_and_timing() -> None:
    p = vlp16_pattern(600.0).pulses(0.0, 0.1)
    # One revolution at 600 rpm: 0.1 s / 55.296 µs = 1808.45 firing cycles of 16.
    assert len(p) == 1809 * 16 - sum(1 for c in range(16) if 1808 * 55.296e-6 + c * 2.304e-6 >= 0.1)
    np.testing.assert_allclose(np.diff(p.t[:16]), 2.304e-6)
    np.testing.assert_allclose(p.t[16] - p.t[0], 55.296e-6)
    np.testing.assert_array_equal(p.line[:16], np.arange(16))
    _, el = azimuth_elevation(p.dirs)
    np.testing.assert_allclose(np.degrees(el[:16]), VLP16_ELEVATION_DEG, atol=1e-9)
    az, _ = azimuth_elevation(p.dirs)
    # Clockwise seen from above: 360° · 600/60 · 55.296 µs = 0.199° per firing cycle.
    step = np.degrees(az[0] - az[16])
    assert step == pytest.approx(0.19907, abs=1e-4)
    # Beam origins carry the per-laser vertical offsets (11.2 mm for laser 0).
    assert p.origins[0, 2] == pytest.approx(0.0112)


@pytest.mark.parametrize("frame", [0.1, 0.05, 0.0333])
def test_vlp16_frames_neither_lose_nor_repeat_pulses(frame: float) -> None:
    pattern = vlp16_pattern(600.0)
    whole = pattern.pulses(0.0, 20 * frame)
    parts = [pattern.pulses(k * frame, (k + 1) * frame) for k in range(20)]
    np.testing.assert_array_equal(np.concatenate([q.t for q in parts]), whole.t)
    np.testing.assert_array_equal(np.concatenate([q.line for q in parts]), whole.line)


def test_vlp16_spin_rate_is_limited() -> None:
    with pytest.raises(SensorError, match="300-1200 rpm"):
        vlp16_pattern(1500.0)


def test_mid360_covers_its_field_of_view() -> None:
    p = make_sensor("mid360").pattern.pulses(0.0, 1.0)
    assert len(p) == 200_000
    assert set(np.unique(p.line)) == {0, 1, 2, 3}
    az, el = np.degrees(azimuth_elevation(p.dirs))
    assert el.min() == pytest.approx(-7.0, abs=0.1)
    assert el.max() == pytest.approx(52.0, abs=0.1)
    counts, _ = np.histogram(az, bins=36, range=(-180, 180))
    assert counts.min() > 0.5 * counts.mean()


def test_pattern_file_csv_and_npy(tmp_path: Path) -> None:
    csv = tmp_path / "scan.csv"
    csv.write_text("Time/s,Azimuth/deg,Zenith/deg\n1,0,90\n2,10,80\n3,-20,100\n")
    az, el = load_pattern_table(csv)
    np.testing.assert_allclose(np.degrees(az), [0, 10, -20])
    np.testing.assert_allclose(np.degrees(el), [0, 10, -10])
    npy = tmp_path / "scan.npy"
    np.save(npy, np.column_stack([az, el]))
    sensor = make_sensor(f"file:{npy}", rate_hz=30.0, lines=2)
    p = sensor.pattern.pulses(0.0, 0.2)
    # 30 points/s over 0.2 s: rows 0..5, wrapping around the 3-row table.
    assert len(p) == 6
    np.testing.assert_allclose(p.dirs[3], p.dirs[0])
    np.testing.assert_array_equal(p.line, [0, 1, 0, 1, 0, 1])


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("a,b,c\n1,2,3\n", "missing column"),
        ("Time/s,Azimuth/deg,Zenith/deg\n", "no rows"),
        ("Time/s,Azimuth/deg,Zenith/deg\n1,x,3\n", "not a number"),
        ("Time/s,Azimuth/deg,Zenith/deg\n1,nan,3\n", "NaN"),
        ("Time/s,Azimuth/deg,Zenith/deg\n1,0,200\n", "elevations"),
    ],
)
def test_bad_pattern_files(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(SensorError, match=message):
        load_pattern_table(path)


def test_csv_with_a_byte_order_mark(tmp_path: Path) -> None:
    path = tmp_path / "excel.csv"
    path.write_bytes("Time/s,Azimuth/deg,Zenith/deg\n1,0,90\n".encode("utf-8-sig"))
    az, el = load_pattern_table(path)
    np.testing.assert_allclose([az[0], el[0]], [0.0, 0.0])


def test_options_that_do_not_apply_are_refused() -> None:
    with pytest.raises(SensorError, match="vlp16 only"):
        make_sensor("avia", rpm=600)
    with pytest.raises(SensorError, match="file: patterns"):
        make_sensor("vlp16", rate_hz=1000.0)


def test_missing_and_malformed_npy(tmp_path: Path) -> None:
    with pytest.raises(SensorError, match="not found"):
        load_pattern_table(tmp_path / "none.npy")
    bad = tmp_path / "bad.npy"
    np.save(bad, np.zeros((4, 3)))
    with pytest.raises(SensorError, match=r"\(N, 2\)"):
        load_pattern_table(bad)
    words = tmp_path / "words.npy"
    np.save(words, np.array([["a", "b"], ["c", "d"]]))
    with pytest.raises(SensorError, match="numbers"):
        load_pattern_table(words)
