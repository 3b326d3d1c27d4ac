"""Detection physics: the range equation, its datasheet calibration, fog, and the reach."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import brentq

from dronetrack.config.rig import make_turret
from dronetrack.control.aiming import aim_angles
from dronetrack.errors import ConfigError
from dronetrack.sim.drones import make_drone
from dronetrack.sim.lidar import LidarSimulator
from dronetrack.sim.patterns import TablePattern
from dronetrack.sim.physics import detection_probability, extinction_coefficient, signal_ratio
from dronetrack.sim.raycast import Primitives
from dronetrack.sim.scene import Scene, make_scene
from dronetrack.sim.sensors import make_sensor
from dronetrack.sim.shapes import box
from dronetrack.sim.trajectories import fly_waypoints
from dronetrack.sim.world import SimWorld

AVIA = make_sensor("avia", noise=False)


def test_signal_is_one_at_the_rated_range() -> None:
    s = signal_ratio(
        AVIA.rated_reflectivity,
        AVIA.rated_range_m,
        AVIA.rated_range_m,
        AVIA.rated_reflectivity,
        AVIA.gamma,
        0.0,
    )
    assert s == pytest.approx(1.0)
    assert detection_probability(s, 1.0) == pytest.approx(0.5)


@given(st.floats(0.05, 1.0))
def test_rated_range_scales_as_reflectivity_to_the_gamma(rho: float) -> None:
    # s(R) = 1 for an extended target at R_max = R_ref (ρ/ρ_ref)^γ.
    r_max = AVIA.rated_range_m * (rho / AVIA.rated_reflectivity) ** AVIA.gamma
    s = signal_ratio(rho, r_max, AVIA.rated_range_m, AVIA.rated_reflectivity, AVIA.gamma, 0.0)
    assert s == pytest.approx(1.0)


def test_avia_rated_ranges_at_20_and_80_percent() -> None:
    # Datasheet (100 klx): 190 m @ 10 %, 230 m @ 20 %, 320 m @ 80 %.
    for rho, rated in ((0.2, 230.0), (0.8, 320.0)):
        r = AVIA.rated_range_m * (rho / AVIA.rated_reflectivity) ** AVIA.gamma
        assert r == pytest.approx(rated, rel=0.06)


def test_koschmieder_extinction() -> None:
    assert extinction_coefficient(1000.0) == pytest.approx(3.912e-3, rel=1e-3)
    assert extinction_coefficient(float("inf")) == 0.0
    with pytest.raises(ConfigError, match="visibility"):
        extinction_coefficient(0.0)


@given(st.floats(1e-3, 1e3), st.floats(1e-3, 1e3))
def test_detection_probability_is_monotonic(a: float, b: float) -> None:
    lo, hi = sorted((a, b))
    assert detection_probability(lo, 1.0) <= detection_probability(hi, 1.0)
    assert 0.0 <= detection_probability(lo, 1.0) <= 1.0


def _staring(target: Primitives, rng_seed: int = 0) -> LidarSimulator:
    """An Avia whose every pulse points straight along +x, noise off."""
    sensor = make_sensor("avia", noise=False)
    stare = TablePattern(np.zeros(1), np.zeros(1), rate_hz=24_000.0)
    from dataclasses import replace

    sensor = replace(sensor, pattern=stare)
    drone = make_drone("phantom4")
    drone = replace(drone, body=target)
    return LidarSimulator(
        sensor,
        Scene("sky", Primitives.empty(), (0, 0, 1, 1)),
        drone,
        fly_waypoints((0.0, 0.0, 0.0), []),
        0.0,
    )


def _return_fraction(sim: LidarSimulator, range_m: float) -> float:
    # Move the sensor so the target (at the origin) is `range_m` ahead.
    pose = np.eye(4)
    pose[0, 3] = -range_m
    scan = sim.scan(0.0, 0.1, np.array([0.0]), pose[None], np.random.default_rng(1))
    return float(np.mean(scan.hit_target)) * len(scan.t) / scan.n_pulses


def test_a_wall_fades_at_its_rated_range() -> None:
    wall = box((0.0, 0.0, 0.0), (0.2, 50.0, 50.0), 0.3)
    sim = _staring(wall)
    r_max = AVIA.rated_range_m * (0.3 / AVIA.rated_reflectivity) ** AVIA.gamma
    assert _return_fraction(sim, 0.9 * r_max) > 0.7
    assert _return_fraction(sim, 1.1 * r_max) < 0.3


def test_a_small_target_fades_faster_than_a_wall() -> None:
    # A 0.35 m wide, 0.1 m tall plate: the 0.28° beam over-fills it vertically
    # beyond 20 m, so its echo falls as R^-(1 + 1/γ) instead of R^-(1/γ).
    rho, h = 0.3, 0.1
    plate = box((0.0, 0.0, 0.0), (0.05, 0.35, h), rho)
    sim = _staring(plate)

    def fill(r: float) -> float:
        # Share of the elliptical top-hat footprint inside the band |v| < h/2:
        # (2/π)(a√(1 − a²) + asin a) with a = h / (θ_v R).
        a = min(1.0, h / (AVIA.divergence_v * r))
        return float(2 / np.pi * (a * np.sqrt(1 - a * a) + np.arcsin(a)))

    def log_s(r: float) -> float:
        return float(
            np.log(
                signal_ratio(
                    rho * fill(r), r, AVIA.rated_range_m, AVIA.rated_reflectivity, AVIA.gamma, 0.0
                )
            )
        )

    r_half = brentq(log_s, 20.0, 500.0)
    r_wall = AVIA.rated_range_m * (rho / AVIA.rated_reflectivity) ** AVIA.gamma
    assert r_half < 0.7 * r_wall
    assert _return_fraction(sim, 0.88 * r_half) > 0.6
    assert _return_fraction(sim, 1.12 * r_half) < 0.4


def _target_frames(range_m: float, visibility: float, n_frames: int = 30) -> np.ndarray:
    turret = make_turret("widowx")
    target = (range_m, 0.0, 20.0)
    pan, tilt = aim_angles(target, turret.mount)
    world = SimWorld(
        make_sensor("avia"),
        make_scene("sky"),
        make_drone("phantom4"),
        fly_waypoints(target, []),
        turret,
        turret.mount,
        extinction_coefficient(visibility),
        np.random.default_rng(7),
        pan=pan,
        tilt=tilt,
    )
    return np.array([world.step()[1].n_target_points for _ in range(n_frames)])


def test_detection_falls_with_range() -> None:
    means = [_target_frames(r, float("inf")).mean() for r in (40.0, 80.0, 120.0, 160.0)]
    assert np.all(np.diff(means) < 0)


def test_detection_falls_with_lower_visibility() -> None:
    means = [_target_frames(50.0, v).mean() for v in (float("inf"), 300.0, 100.0, 60.0)]
    assert np.all(np.diff(means) < 0)


@pytest.mark.parametrize(
    ("visibility", "near", "far"),
    [
        # Seed 000, sunny: tracked to ~130 m, last returns at 135-147 m.
        # Measured here: a return in 82 % of frames at 130 m, in 5 % at 170 m.
        (float("inf"), 130.0, 170.0),
        # Seed 000, fog: tracked to 58 m.  Measured here at V = 100 m: a return in
        # every frame at 45 m, in 3 % of frames at 60 m and none at 65 m.
        (100.0, 45.0, 65.0),
    ],
)
def test_reach_of_a_phantom_4_seen_by_an_avia(visibility: float, near: float, far: float) -> None:
    assert np.mean(_target_frames(near, visibility) > 0) > 0.6
    assert np.mean(_target_frames(far, visibility) > 0) < 0.2
