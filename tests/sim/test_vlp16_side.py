"""The VLP-16 on its side (seed 003): spin sweeps elevation, the beams fan out in azimuth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dronetrack.errors import SensorError
from dronetrack.geometry.mount import MountGeometry, sensor_poses
from dronetrack.geometry.transforms import rot_x, rot_z, wrap_angle
from dronetrack.sim.drones import make_drone
from dronetrack.sim.lidar import LidarSimulator
from dronetrack.sim.mounted import RotatedPattern, side_mount
from dronetrack.sim.patterns import VLP16_ELEVATION_DEG, vlp16_pattern
from dronetrack.sim.scene import make_scene
from dronetrack.sim.sensors import SENSOR_NAMES, make_sensor
from dronetrack.sim.trajectories import fly_waypoints

SIDE = make_sensor("vlp16-side", noise=False)
UPRIGHT = make_sensor("vlp16", noise=False)


def test_directions_are_unit_vectors_and_frames_keep_the_vlp16_pulses() -> None:
    side = SIDE.pattern.pulses(0.0, 0.1)
    upright = UPRIGHT.pattern.pulses(0.0, 0.1)
    np.testing.assert_allclose(np.linalg.norm(side.dirs, axis=1), 1.0, atol=1e-12)
    # 600 rpm, 0.1 s: the VLP-16's 55.296 µs firing cycles of 16 lasers, all kept.
    assert len(side) == len(upright) == 28_939
    np.testing.assert_array_equal(side.t, upright.t)
    np.testing.assert_array_equal(side.line, upright.line)
    assert SIDE.pattern.n_lines == 16


def test_the_beams_fan_out_fifteen_degrees_each_way_in_azimuth() -> None:
    p = SIDE.pattern.pulses(0.0, 0.1)
    # The angle out of the spin (x-z) plane is the laser's elevation, negated.
    offset = np.degrees(np.arcsin(p.dirs[:, 1]))
    assert offset.min() == pytest.approx(-15.0, abs=1e-9)
    assert offset.max() == pytest.approx(15.0, abs=1e-9)
    expected = -np.asarray(VLP16_ELEVATION_DEG)[p.line]
    np.testing.assert_allclose(offset, expected, atol=1e-9)
    assert np.unique(np.round(offset, 6)).tolist() == list(range(-15, 16, 2))
    # Looking forward, that offset is the pulse's azimuth: a ±15° fan, 2° between beams.
    ahead = np.abs(np.arctan2(p.dirs[:, 2], p.dirs[:, 0])) < math.radians(1.0)
    azimuth = np.degrees(np.arctan2(p.dirs[ahead, 1], p.dirs[ahead, 0]))
    assert azimuth.min() == pytest.approx(-15.0, abs=0.01)
    assert azimuth.max() == pytest.approx(15.0, abs=0.01)


def test_the_spin_sweeps_the_full_circle_of_elevation() -> None:
    p = SIDE.pattern.pulses(0.0, 0.1)  # one revolution at 600 rpm
    pitch = np.arctan2(p.dirs[:, 2], p.dirs[:, 0])
    counts, _ = np.histogram(np.degrees(pitch), bins=72, range=(-180.0, 180.0))
    assert counts.min() > 0.9 * counts.mean()
    # The in-plane angle is the head's spin angle az(t) = az0 − ω t (seed 003's "internal
    # spin angle", matched against the drone's pitch).
    spin = -2.0 * math.pi * 600.0 / 60.0 * p.t
    np.testing.assert_allclose(wrap_angle(pitch - spin), 0.0, atol=1e-9)


def test_beam_origins_and_footprint_turn_with_the_head() -> None:
    p = SIDE.pattern.pulses(0.0, 0.01)
    # The VLP-16's laser heights above its centre now lie along −y.
    assert np.abs(p.origins[:, [0, 2]]).max() < 1e-12
    np.testing.assert_allclose(p.origins[:, 1], -UPRIGHT.pattern.pulses(0.0, 0.01).origins[:, 2])
    assert p.max_origin_offset == pytest.approx(np.abs(p.origins).max())
    assert (SIDE.divergence_h, SIDE.divergence_v) == (UPRIGHT.divergence_v, UPRIGHT.divergence_h)


def test_rpm_applies_to_the_side_mounted_head() -> None:
    slow = make_sensor("vlp16-side", rpm=300.0)
    assert isinstance(slow.pattern, RotatedPattern)
    assert slow.pattern.base.rpm == 300.0  # type: ignore[attr-defined]
    assert slow.name == "vlp16-side"
    # Half the spin rate: half the turn in the same time, same pulse count.
    p = slow.pattern.pulses(0.0, 0.1)
    assert len(p) == 28_939
    pitch = np.degrees(np.arctan2(p.dirs[:, 2], p.dirs[:, 0]))
    assert np.ptp(pitch[np.abs(pitch) < 179.0]) < 181.0
    with pytest.raises(SensorError, match="300-1200 rpm"):
        make_sensor("vlp16-side", rpm=2000.0)


def test_names_and_errors_list_the_side_mounted_head() -> None:
    assert "vlp16-side" in SENSOR_NAMES
    assert make_sensor(" VLP16-Side ").name == "vlp16-side"
    with pytest.raises(SensorError, match="vlp16, vlp16-side, file:PATH"):
        make_sensor("vlp17")
    with pytest.raises(SensorError, match=r"vlp16 only \(vlp16, vlp16-side\)"):
        make_sensor("mid40", rpm=600.0)


def test_a_rotated_pattern_is_the_base_pattern_turned() -> None:
    R = rot_z(0.3) @ rot_x(-0.7)
    base = vlp16_pattern()
    a, b = RotatedPattern(base, R).pulses(0.01, 0.02), base.pulses(0.01, 0.02)
    np.testing.assert_allclose(a.dirs, b.dirs @ R.T, atol=1e-12)
    np.testing.assert_allclose(a.origins, b.origins @ R.T, atol=1e-12)
    np.testing.assert_allclose(side_mount() @ [0.0, 0.0, 1.0], [0.0, -1.0, 0.0], atol=1e-12)


@pytest.mark.parametrize(
    "matrix", [np.eye(2), np.diag([1.0, 1.0, -1.0]), 2.0 * np.eye(3), np.full((3, 3), np.nan)]
)
def test_a_mounting_must_be_a_rotation(matrix: np.ndarray) -> None:
    with pytest.raises(SensorError, match="mounting rotation"):
        RotatedPattern(vlp16_pattern(), matrix)


def _target_returns(sensor_name: str, target: tuple[float, float, float], pan: float) -> int:
    """Target returns in one 0.1 s revolution with the sensor panned to ``pan``, level."""
    mount = MountGeometry((0.0, 0.0, 1.0), (0.0, 0.0, 0.07), (0.0, 0.0, 0.12))  # ptu-e46
    sim = LidarSimulator(
        make_sensor(sensor_name, noise=False),
        make_scene("sky"),
        make_drone("phantom4"),
        fly_waypoints(target, []),
        0.0,
    )
    pose_t = np.array([0.0, 0.1])
    poses = sensor_poses(np.full(2, pan), np.zeros(2), mount)
    scan = sim.scan(0.0, 0.1, pose_t, poses, np.random.default_rng(0))
    return int(scan.hit_target.sum())


def _at(range_m: float, azimuth_deg: float, elevation_deg: float) -> tuple[float, float, float]:
    """A point at a range, azimuth and elevation from the ptu-e46's sensor origin (level)."""
    az, el = math.radians(azimuth_deg), math.radians(elevation_deg)
    c = range_m * math.cos(el)
    return (c * math.cos(az), c * math.sin(az), 1.19 + range_m * math.sin(el))


def test_a_panned_side_head_sees_a_target_in_its_fan_at_any_elevation() -> None:
    # On the beam 1° to the left: seen level and 40° up, out of the upright VLP-16's ±15°.
    assert _target_returns("vlp16-side", _at(12.0, 1.0, 0.0), 0.0) > 0
    assert _target_returns("vlp16-side", _at(12.0, 1.0, 40.0), 0.0) > 0
    assert _target_returns("vlp16", _at(12.0, 1.0, 40.0), 0.0) == 0
    # 30° off to the side: outside the ±15° fan until the turret pans to it.
    assert _target_returns("vlp16-side", _at(12.0, 1.0, 0.0), math.radians(30.0)) == 0


def test_a_small_target_hides_in_the_gap_between_beams() -> None:
    # Seed 003 §3.3: the beams at ±1° pass 0.21 m either side of a target dead ahead at
    # 12 m, and the Phantom 4 fits between them.  At 5 m they cross it.
    assert _target_returns("vlp16-side", _at(12.0, 0.0, 0.0), 0.0) == 0
    assert _target_returns("vlp16-side", _at(5.0, 0.0, 0.0), 0.0) > 0
