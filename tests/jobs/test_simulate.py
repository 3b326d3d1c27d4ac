"""Seeded closed-loop runs against seed 000's results.

Each threshold is set from the values measured here (seed 0) with margin, and
from the seed's published figures where the simulation can be compared:

- default flight, turret tracking against fixed: measured 73 % / 142 m against
  17 % / 29 m (seed 000 Table II: 71 % / 130 m against 52 % / 103 m);
- field test, sunny against fog (V = 100 m): 153 m against 59 m (seed: 128 m
  against 58 m);
- indoor slow patterns: RMSE 2.9 cm (seed Table IV: 5.4 and 5.7 cm), every
  frame from the first lock within 0.17 m; coverage (within 0.3 m) 96 %, the
  misses being the take-off, while the drone is still inside the ground's
  background cells;
- lost-and-found: recaptured in the frame the drone reappears (seed: "practically
  instantaneous"; the issue asks for 1 s).
"""

from __future__ import annotations

from functools import cache
from typing import Any

import numpy as np
import pytest

from dronetrack.config.run import ScenarioConfig, apply_overrides
from dronetrack.config.scenarios import SCENARIOS
from dronetrack.jobs.run import RunResult
from dronetrack.jobs.simulate import resolve_run, run_simulation
from dronetrack.sim.drones import DRONE_NAMES, make_drone


@cache
def _run(name: str, turret: str | None = None) -> RunResult:
    return run_simulation(apply_overrides(SCENARIOS[name], seed=0, turret_mode=turret))


def _errors(a: dict[str, np.ndarray]) -> np.ndarray:
    """3-D tracking error per frame [m]."""
    return np.sqrt(
        (a["est_x"] - a["gt_x"]) ** 2
        + (a["est_y"] - a["gt_y"]) ** 2
        + (a["est_z"] - a["gt_z"]) ** 2
    )


def _metrics(name: str, turret: str | None = None) -> dict[str, Any]:
    return _run(name, turret).metrics()


@pytest.mark.slow
def test_the_turret_tracks_further_and_longer_than_a_fixed_sensor() -> None:
    moving = _metrics("default")
    fixed = _metrics("default", "fixed")
    assert moving["coverage_pct"] >= 60.0
    # Measured, seeds 0-4: fixed 57.6-60.9 %, moving 88.5-98.5 % (84.8-98.5 % over
    # seeds 0-19: the share of the flight's far end, 132-142 m, where the drone gives
    # 2-5 returns in 7 s, that the turret happens to hold varies from run to run);
    # seed 0: 59.2 against 88.8.
    assert moving["coverage_pct"] >= fixed["coverage_pct"] + 25.0
    # Seeds 0-4, with and without acquisition: the drone is either held to the
    # flight's furthest point (141-142 m, 8 of 10 runs) or lost near 110 m, where it
    # returns about one point a frame (114 m, 2 of 10; seed 0 with acquisition is one).
    assert moving["max_tracking_distance_m"] >= 110.0
    # With acquisition the fixed sensor also finds the drone whenever it crosses the
    # view, out to about 110 m (seed 000's Table II: 103 m fixed), so the furthest
    # correct frame no longer separates the two; the coverage above does.
    assert moving["max_tracking_distance_m"] >= fixed["max_tracking_distance_m"]


@pytest.mark.slow
def test_fog_cuts_the_reach_as_in_the_field_test() -> None:
    sunny = _metrics("field-sunny")["max_tracking_distance_m"]
    foggy = _metrics("field-foggy")["max_tracking_distance_m"]
    assert sunny >= 120.0
    assert 45.0 <= foggy <= 80.0


@pytest.mark.parametrize("name", ["indoor-horizontal", "indoor-vertical"])
@pytest.mark.slow
def test_indoor_slow_patterns_reach_centimetre_accuracy(name: str) -> None:
    m = _metrics(name)
    assert m["rmse_m"] < 0.06
    assert m["rmse_ci95_m"][0] < m["rmse_m"] < m["rmse_ci95_m"][1]
    assert m["correct_radius_m"] == 0.3
    assert m["coverage_pct"] >= 93.0
    a = _run(name).log.arrays()
    err = _errors(a)
    locked = int(np.argmax(a["tracked"]))
    assert a["t"][locked] - a["t"][0] <= 2.0  # the take-off
    assert err[locked:].max() < 0.25


@pytest.mark.slow
def test_lost_and_found_recaptures_within_a_second() -> None:
    a = _run("indoor-lost-and-found").log.arrays()
    visible = a["n_target_points"] > 0
    err = _errors(a)
    recaptured = a["tracked"] & (err < 0.3)
    delays = []
    hidden_for = 0
    for i in range(1, len(a["t"])):
        hidden_for = hidden_for + 1 if not visible[i - 1] else 0
        if visible[i] and hidden_for >= 10:  # back after at least 1 s out of sight
            later = np.flatnonzero(recaptured[i:])
            assert len(later), f"never recaptured after t = {a['t'][i]:.1f} s"
            delays.append(a["t"][i + later[0]] - a["t"][i])
    assert len(delays) >= 6  # the pattern hides the drone on every pass
    assert max(delays) <= 1.0
    # Once the drone has been hidden for half a second the filter knows it has lost
    # it (measured: none of 277 such frames counted as tracked).
    hidden_long = np.zeros(len(visible), dtype=bool)
    run = 0
    for i, seen in enumerate(visible):
        run = 0 if seen else run + 1
        hidden_long[i] = run > 5
    assert hidden_long.sum() >= 100
    assert not a["tracked"][hidden_long].any()


@pytest.mark.parametrize("drone", DRONE_NAMES)
def test_the_drone_sets_the_measurement_noise(drone: str) -> None:
    """σ_m = s_diag / 2 of the flown drone (eq. 11), also when the preset named another."""
    cfg = resolve_run(apply_overrides(SCENARIOS["default"], drone=drone))
    assert cfg.pipeline.tracker.s_diag == make_drone(drone).s_diag
    assert cfg.pipeline.tracker.sigma_m == pytest.approx(make_drone(drone).s_diag / 2)
    # An explicit value in the configuration wins over the drone.
    data = SCENARIOS["default"].model_dump()
    data["drone"]["model"] = drone
    data["pipeline"]["tracker"]["sigma_m"] = 0.33
    assert resolve_run(ScenarioConfig.model_validate(data)).pipeline.tracker.sigma_m == 0.33


@pytest.mark.slow
def test_a_filter_coasting_past_the_last_return_does_not_extend_the_reach() -> None:
    """seed 003's EKF predicts on for up to 2 s after its last centroid and stays
    within 4 m of the drone for a while; those frames used no measurement and do not
    count.  Measured (seed 0): 36.8 m counting them, 35.2 m without, which is the
    range of the last return."""
    run = _run("seed003-field")
    m = run.metrics()
    assert m["max_tracking_distance_m"] <= m["max_return_distance_m"]
    a = run.log.arrays()
    # A Kalman filter's measurement error is known exactly on the frames it updated.
    assert np.array_equal(np.isfinite(a["meas_error_m"]), a["measured"])


def test_a_particle_filter_measures_by_its_nearest_point() -> None:
    """A particle filter weighs every foreground point; its measurement error is the
    distance of the nearest one to the truth, known exactly on frames with points."""
    a = _run("indoor-horizontal").log.arrays()
    updated = (a["n_points"] > 0) & ~np.isin(a["flags"], ["repeated", "out_of_order"])
    assert np.array_equal(np.isfinite(a["meas_error_m"]), updated)
    # Once it has climbed out of the ground's background cells, every frame with
    # returns from the drone has a point within the drone's size of the truth.
    flying = (a["n_target_points"] > 0) & (a["gt_z"] > 0.5)
    assert flying.sum() > 100
    assert np.all(a["meas_error_m"][flying] <= make_drone("crazyflie2").s_diag)
