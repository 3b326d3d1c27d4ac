"""Trajectories: waypoint flights, random manoeuvres, CSV splines and the seeds' flights."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import TrajectoryError
from dronetrack.sim.flights import FLIGHTS, make_flight
from dronetrack.sim.trajectories import (
    Waypoint,
    fly_waypoints,
    load_csv_trajectory,
    random_manoeuvres,
)

points = st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(0, 30))


@settings(max_examples=30)
@given(st.lists(points, min_size=1, max_size=5), st.floats(0.5, 20), st.floats(0.5, 15))
def test_waypoint_flight_respects_limits_and_visits_waypoints(
    wps: list[tuple[float, float, float]], speed: float, accel: float
) -> None:
    traj = fly_waypoints((0.0, 0.0, 0.0), [Waypoint(p, speed, accel, 0.5) for p in wps])
    t = np.linspace(traj.start - 1, traj.end + 1, 4000)
    v = np.linalg.norm(traj.velocity(t), axis=1)
    a = np.linalg.norm(traj.acceleration(t), axis=1)
    assert v.max() <= speed * (1 + 1e-9)
    assert a.max() <= accel * (1 + 1e-9)
    np.testing.assert_allclose(traj.position(traj.end)[0], wps[-1], atol=1e-9)
    # Velocity is the derivative of position.
    tm = np.linspace(traj.start, traj.end, 500)
    h = 1e-5
    numeric = (traj.position(tm + h) - traj.position(tm - h)) / (2 * h)
    np.testing.assert_allclose(numeric, traj.velocity(tm), atol=1e-3 * max(1.0, speed))


def test_trapezoid_leg_time() -> None:
    # L = 1.2 m at v = a = 0.6: t = L/v + v/a = 3 s, the indoor patterns' leg time.
    traj = fly_waypoints((0, 0, 0), [Waypoint((0.0, 1.2, 0.0), 0.6, 0.6)])
    assert traj.end == pytest.approx(3.0)
    # A short leg is a triangle with peak speed √(L a).
    short = fly_waypoints((0, 0, 0), [Waypoint((0.1, 0.0, 0.0), 5.0, 1.0)])
    assert np.linalg.norm(short.velocity(short.end / 2)) == pytest.approx(np.sqrt(0.1))


def test_hold_before_takeoff() -> None:
    traj = fly_waypoints((1.0, 2.0, 0.0), [Waypoint((1.0, 2.0, 5.0), 1.0, 1.0)], hold=4.0)
    np.testing.assert_allclose(traj.position([0.0, 3.9]), [[1, 2, 0], [1, 2, 0]])
    assert traj.position(4.5)[0, 2] > 0


@settings(max_examples=10)
@given(st.integers(0, 2**32 - 1))
def test_random_manoeuvres_stay_within_limits(seed: int) -> None:
    rng = np.random.default_rng(seed)
    traj = random_manoeuvres(
        rng, 30.0, v_max=8.0, a_max=6.0, center=(15, 0, 6), half_extent=(8, 8, 3)
    )
    t = np.linspace(0, traj.end, 6000)
    assert np.linalg.norm(traj.velocity(t), axis=1).max() <= 8.0 + 1e-9
    assert np.linalg.norm(traj.acceleration(t), axis=1).max() <= 6.0 + 1e-9
    p = traj.position(t)
    # Inside the box, up to the motion of one braking step.
    assert np.all(np.abs(p - [15, 0, 6]) < np.array([8, 8, 3]) * 1.15)


def test_random_manoeuvres_are_seeded() -> None:
    a = random_manoeuvres(np.random.default_rng(3), 10, 8, 6, (0, 0, 5), (5, 5, 2))
    b = random_manoeuvres(np.random.default_rng(3), 10, 8, 6, (0, 0, 5), (5, 5, 2))
    c = random_manoeuvres(np.random.default_rng(4), 10, 8, 6, (0, 0, 5), (5, 5, 2))
    t = np.linspace(0, 10, 50)
    np.testing.assert_array_equal(a.position(t), b.position(t))
    assert not np.allclose(a.position(t), c.position(t))


def test_csv_trajectory_is_smooth_and_exact_at_samples(tmp_path: Path) -> None:
    path = tmp_path / "flight.csv"
    t = np.linspace(0, 10, 21)
    xyz = np.column_stack([5 * t, np.sin(t), 2 + 0.1 * t**2])
    np.savetxt(path, np.column_stack([t + 100, xyz]), delimiter=",", header="t,x,y,z", comments="")
    traj = load_csv_trajectory(path, t0=2.0)
    assert traj.start == 2.0
    np.testing.assert_allclose(traj.position(t + 2.0), xyz, atol=1e-12)
    # The spline recovers the derivative of a smooth path.
    np.testing.assert_allclose(traj.velocity(6.0)[0], [5.0, np.cos(4.0), 0.8], atol=0.02)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("t,x,y\n0,1,2\n1,2,3\n", "missing column"),
        ("t,x,y,z\n0,0,0,0\n0,1,1,1\n", "strictly increase"),
        ("t,x,y,z\n0,0,0,0\n1,nan,1,1\n", "NaN"),
        ("t,x,y,z\n0,0,0,0\n", "at least 2 rows"),
        ("t,x,y,z\n0,0,0,0\n1,a,1,1\n", "not a number"),
        # Positions in millimetres: 5 m/s reads as 5000 m/s.
        ("t,x,y,z\n0,0,0,0\n1,5000,0,0\n2,10000,0,0\n", "line 3\\) exceeds 100 m/s"),
        ("t,x,y,z\n0,0,0,0\n1,1e300,0,0\n", "exceeds 100 m/s"),
    ],
)
def test_malformed_csv_trajectories(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(TrajectoryError, match=message):
        load_csv_trajectory(path)


def test_seed_flights_reach_their_published_extent() -> None:
    rng = np.random.default_rng(0)
    reach = {}
    for name in FLIGHTS:
        traj = make_flight(name, 0.0, 60.0, rng)
        t = np.linspace(traj.start, traj.end, 20_000)
        reach[name] = np.linalg.norm(traj.position(t), axis=1).max()
        speed = np.linalg.norm(traj.velocity(t), axis=1).max()
        assert speed <= 15.0 + 1e-9
    # Seed 000's outdoor flights go beyond the ~140 m where returns stop.
    for name in ("simple-distance", "vertical", "horizontal-slow", "horizontal-fast", "field"):
        assert 140.0 <= reach[name] <= 160.0
    # Indoor patterns stay inside the 7 × 8 m room, about 3 m in front of the sensor.
    for name in ("indoor-horizontal", "indoor-vertical", "indoor-fast", "indoor-lost-and-found"):
        assert 3.0 <= reach[name] <= 4.5


def test_indoor_leg_speeds_match_seed_000() -> None:
    rng = np.random.default_rng(0)
    slow = make_flight("indoor-horizontal", 0.0, 60.0, rng)
    fast = make_flight("indoor-fast", 0.0, 60.0, rng)
    t = np.linspace(0, 60, 30_000)
    assert np.linalg.norm(slow.velocity(t), axis=1).max() == pytest.approx(0.6)
    assert np.linalg.norm(fast.velocity(t), axis=1).max() == pytest.approx(1.2)


def test_unknown_flight() -> None:
    with pytest.raises(TrajectoryError, match="unknown trajectory"):
        make_flight("loop-the-loop", 0.0, 10.0, np.random.default_rng(0))
