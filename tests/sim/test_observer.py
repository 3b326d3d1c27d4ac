"""A moving observer (seed 002): the sensor rides on a drone, the frames carry its poses.

world_T_sensor(t) = world_T_body(t) · body_T_sensor(pan, tilt); the returns, put in
the world with the frames' poses, land on the scene and on the target.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from dronetrack.config.rig import make_turret
from dronetrack.config.run import (
    ObserverConfig,
    SensorConfig,
    dump_scenario,
    load_scenario_file,
)
from dronetrack.config.scenarios import SCENARIOS
from dronetrack.geometry.mount import sensor_poses
from dronetrack.jobs.simulate import run_simulation
from dronetrack.sim.build import build_world, resolve_scenario
from dronetrack.sim.drones import make_drone
from dronetrack.sim.flights import make_flight
from dronetrack.sim.physics import extinction_coefficient
from dronetrack.sim.primitives import Primitives
from dronetrack.sim.scene import Scene, make_scene
from dronetrack.sim.sensors import make_sensor
from dronetrack.sim.shapes import box, cylinder, ground
from dronetrack.sim.trajectories import PiecewiseAcceleration, Trajectory, fly_waypoints
from dronetrack.sim.world import Observer, OdometryDrift, SimWorld
from dronetrack.types import TurretCommand

TURRET = make_turret("widowx")
OUT_OF_RANGE = fly_waypoints((0.0, 0.0, 500.0), [])  # a target no pulse reaches
WALL_X = 19.5  # front face of the wall in ``_scene``
POLES = ((12.0, 2.0), (-6.0, 9.0), (3.0, -11.0))
POLE_RADIUS = 0.1


def _scene() -> Scene:
    """The ground, a wall facing -x at x = 19.5 m, and three thin poles."""
    parts = [ground(0.3), box((WALL_X + 0.5, 0.0, 5.0), (1.0, 40.0, 10.0), 0.3)]
    parts += [cylinder((x, y, 2.0), POLE_RADIUS, 4.0, 0.5) for x, y in POLES]
    return Scene("test", Primitives.concat(parts), (-50.0, -50.0, 50.0, 50.0))


def _constant_velocity(p0: tuple[float, float, float], v: tuple[float, float, float]) -> Trajectory:
    """p(t) = p0 + v t for 0 ≤ t ≤ 60 s."""
    return PiecewiseAcceleration(
        knots=np.array([0.0, 60.0]),
        p=np.array([p0], dtype=np.float64),
        v=np.array([v], dtype=np.float64),
        a=np.zeros((1, 3)),
    )


def _world(
    observer: Observer | None,
    sensor: str = "avia",
    scene: Scene | None = None,
    target: Trajectory | None = None,
    drone: str = "phantom4",
    pan: float = 0.0,
    tilt: float = 0.0,
    odometry_sigma: float = 0.0,
    seed: int = 3,
    noise: bool = False,
) -> SimWorld:
    return SimWorld(
        make_sensor(sensor, noise=noise),
        scene or make_scene("empty"),
        make_drone(drone),
        target or fly_waypoints((40.0, 5.0, 10.0), []),
        TURRET,
        TURRET.mount,
        extinction_coefficient(math.inf),
        np.random.default_rng(seed),
        pan=pan,
        tilt=tilt,
        observer=observer,
        odometry_sigma=odometry_sigma,
    )


def _on_poles(points: np.ndarray) -> np.ndarray:
    """Distance of each point (N, 3) from the nearest pole's axis, horizontally."""
    axes = np.asarray(POLES)
    return np.min(np.linalg.norm(points[:, None, :2] - axes[None], axis=2), axis=1)


# --- a stationary observer is the turret on the ground ------------------------------------


@pytest.mark.parametrize("noise", [False, True])
def test_observer_at_the_origin_gives_the_fixed_turret_frames_bit_for_bit(noise: bool) -> None:
    at_origin = Observer.fixed(fly_waypoints((0.0, 0.0, 0.0), []), 0.0)
    worlds = [
        _world(obs, target=fly_waypoints((20.0, 0.0, 2.0), []), noise=noise)
        for obs in (None, at_origin)
    ]
    for world in worlds:  # slew, so the poses change within every frame
        world.command(TurretCommand(0.0, math.radians(90), math.radians(30), "velocity"))
    for _ in range(4):
        (fa, ta), (fb, tb) = (w.step() for w in worlds)
        np.testing.assert_array_equal(fa.poses, fb.poses)
        np.testing.assert_array_equal(fa.points, fb.points)
        np.testing.assert_array_equal(fa.t, fb.t)
        np.testing.assert_array_equal(ta.hit_target, tb.hit_target)
        # And those poses are the turret's own, T(base) · Rz(pan) · ... on the ground.
        np.testing.assert_array_equal(ta.observer_position, None)
        np.testing.assert_array_equal(tb.observer_position, np.zeros(3))
    assert len(fb) > 1000


def test_observer_file_at_the_origin_reproduces_a_scenario_without_one(tmp_path: Path) -> None:
    np.savetxt(
        tmp_path / "still.csv",
        np.array([[0.0, 0.0, 0.0, 0.0], [100.0, 0.0, 0.0, 0.0]]),
        delimiter=",",
        header="t,x,y,z",
        comments="",
    )
    base = SCENARIOS["mid360-aggressive"]
    path = tmp_path / "still.toml"
    path.write_text('base = "mid360-aggressive"\n[observer]\nfile = "still.csv"\n')
    cfg = load_scenario_file(path, SCENARIOS)
    assert cfg.observer is not None
    assert (cfg.observer.name, Path(cfg.observer.file or "")) == (None, tmp_path / "still.csv")
    assert cfg.observer.yaw == "heading"  # at rest it holds yaw_deg = 0
    a, b = build_world(base), build_world(cfg)
    for _ in range(3):
        (fa, _), (fb, _) = a.step(), b.step()
        np.testing.assert_array_equal(fa.poses, fb.poses)
        np.testing.assert_array_equal(fa.points, fb.points)


def test_named_scenarios_other_than_seed002_have_no_observer() -> None:
    for name, cfg in SCENARIOS.items():
        if name == "seed002-relative":
            assert cfg.observer == ObserverConfig(name="observer-orbit")
        else:
            assert cfg.observer is None
            assert "observer" not in dump_scenario(cfg)


def test_resolved_observer_file_is_absolute_and_round_trips(tmp_path: Path) -> None:
    folder = tmp_path / "site"
    folder.mkdir()
    t = np.linspace(0.0, 10.0, 11)
    rows = np.column_stack([t, -5.0 + 2.0 * t, np.zeros_like(t), np.full_like(t, 10.0)])
    np.savetxt(folder / "obs.csv", rows, delimiter=",", header="t,x,y,z", comments="")
    path = folder / "rel.toml"
    path.write_text(
        'base = "seed002-relative"\n[observer]\nfile = "obs.csv"\nyaw = "fixed"\nyaw_deg = 30\n'
    )
    cfg = load_scenario_file(path, SCENARIOS)
    resolved = resolve_scenario(cfg)
    assert resolved.observer is not None
    assert resolved.observer.file is not None
    assert Path(resolved.observer.file).is_absolute()
    again = tmp_path / "again.toml"
    again.write_text(dump_scenario(resolved))
    assert load_scenario_file(again, SCENARIOS) == resolved
    world = build_world(resolved)
    assert world.observer is not None
    np.testing.assert_allclose(world.observer_position(2.5), [0.0, 0.0, 10.0], atol=1e-9)
    np.testing.assert_allclose(world.observer.yaw_at(5.0), [math.radians(30.0)])


@pytest.mark.parametrize(
    ("observer", "message"),
    [
        ({"name": "observer-orbit", "file": "x.csv"}, "not both"),
        ({"yaw": "sideways"}, "yaw"),
        ({"odometry_sigma_m": -0.1}, "odometry_sigma_m"),
        ({"yaw_deg": math.nan}, "yaw_deg"),
        ({"hold_s": -1.0}, "hold_s"),
    ],
)
def test_bad_observer_sections(observer: dict[str, object], message: str) -> None:
    from dronetrack.config.run import validate_scenario
    from dronetrack.errors import ScenarioError

    with pytest.raises(ScenarioError, match=message):
        validate_scenario({"observer": observer}, "test")
    assert ObserverConfig().name == "observer-hover"


# --- a moving observer: the returns land where they belong --------------------------------


def test_constant_velocity_observer_puts_the_scene_where_it_is() -> None:
    # 3 m/s along +y at 3 m, body turned 30° left; the turret pans back to look along +x.
    yaw = math.radians(30.0)
    observer = Observer.fixed(_constant_velocity((0.0, -6.0, 3.0), (0.0, 3.0, 0.0)), yaw)
    world = _world(observer, scene=_scene(), target=OUT_OF_RANGE, pan=-yaw, tilt=math.radians(8.0))
    wall_centres, pole_centres, naive_offsets = [], [], []
    for k in range(25):
        frame, truth = world.step()
        assert not truth.hit_target.any()
        np.testing.assert_allclose(
            truth.observer_position, [0.0, -6.0 + 3.0 * frame.end, 3.0], atol=1e-12
        )
        pts = frame.world_points()
        on_ground = np.abs(pts[:, 2]) < 1e-6
        on_wall = np.abs(pts[:, 0] - WALL_X) < 1e-6
        on_pole = np.abs(_on_poles(pts) - POLE_RADIUS) < 1e-6
        assert np.all(on_ground | on_wall | on_pole)
        on_pole &= np.linalg.norm(pts[:, :2] - POLES[0], axis=1) < 1.0  # the one in view
        if k in (5, 20):  # 1.5 s and 4.5 m apart
            assert on_wall.sum() > 1000
            assert on_pole.sum() > 20
            wall_centres.append(pts[on_wall].mean(axis=0))
            pole_centres.append(pts[on_pole, :2].mean(axis=0))
            # The turret's poses alone (as if the observer stood still) put them metres away.
            turret_only = sensor_poses(
                np.full(len(frame.pose_t), -yaw), math.radians(8.0), TURRET.mount
            )
            naive = frame.points[on_pole] @ turret_only[-1, :3, :3].T + turret_only[-1, :3, 3]
            naive_offsets.append(np.linalg.norm(naive[:, :2].mean(axis=0) - POLES[0]))
    # The same pole, seen from 4.5 m further along, is in the same place (its near side).
    for centre in pole_centres:
        assert np.linalg.norm(centre - POLES[0]) < 1.5 * POLE_RADIUS
    assert min(naive_offsets) > 2.0
    # The wall's returns follow the sensor's footprint along it: 4.5 m further in y.
    assert wall_centres[1][1] - wall_centres[0][1] == pytest.approx(4.5, abs=0.5)


def test_orbiting_yawing_observer_puts_the_scene_where_it_is() -> None:
    # The Mid-360 (360°) on a drone circling at 2.5 m/s, its body turning with its heading.
    flight = make_flight("observer-orbit", 0.0, 30.0, np.random.default_rng(0))
    lowered = PiecewiseAcceleration(
        knots=flight.knots, p=flight.p - [0.0, 0.0, 8.0], v=flight.v, a=flight.a
    )
    observer = Observer.heading(lowered)
    world = _world(observer, sensor="mid360", scene=_scene(), target=OUT_OF_RANGE)
    turned = 0
    for _ in range(80):
        frame, _truth = world.step()
        pts = frame.world_points()
        on_ground = np.abs(pts[:, 2]) < 1e-6
        on_pole = np.abs(_on_poles(pts) - POLE_RADIUS) < 1e-6
        on_wall = np.abs(pts[:, 0] - WALL_X) < 1e-6
        assert np.all(on_ground | on_pole | on_wall)
        turned += int(on_pole.sum())
    assert turned > 200
    yaw = float(observer.yaw_at(frame.end)[0])
    assert yaw > math.radians(120)  # it turned with the orbit


def test_heading_yaw_lags_the_velocity_heading_by_rate_times_tau() -> None:
    flight = make_flight("observer-orbit", 0.0, 60.0, np.random.default_rng(0))
    observer = Observer.heading(flight, yaw0=0.0, tau=1.0)
    t = np.linspace(20.0, 40.0, 50)
    v = flight.velocity(t)
    heading = np.unwrap(np.arctan2(v[:, 1], v[:, 0]))
    lag = heading - observer.yaw_at(t)
    lag = (lag + np.pi) % (2 * np.pi) - np.pi
    omega = 2.5 / 8.0  # orbit speed / radius [rad/s]
    # A first-order lag follows a ramp of rate ω a constant ω τ behind (discretely,
    # ω dt / α − ω dt ≈ ω τ (1 − dt / 2τ)).
    np.testing.assert_allclose(lag, omega * 1.0, rtol=0.02)
    # At rest it holds: yaw0 before the first move.
    hover = Observer.heading(fly_waypoints((1.0, 2.0, 3.0), []), yaw0=0.7)
    np.testing.assert_allclose(hover.yaw_at([0.0, 5.0, 100.0]), 0.7)


def test_target_returns_land_on_the_target_seen_from_the_moving_observer() -> None:
    cfg = SCENARIOS["seed002-relative"]
    cfg = cfg.model_copy(
        update={"sensor": SensorConfig(model="mid360", noise=False), "duration_s": 10.0}
    )
    world = build_world(cfg)
    drone = make_drone("f550")
    half_beam = 0.5 * make_sensor("mid360").divergence_v
    trajectory = world.trajectory
    hits = 0
    for _ in range(60):
        frame, truth = world.step()
        if truth.hit_target.any():
            pts = frame.world_points()[truth.hit_target]
            at = trajectory.position(frame.t[truth.hit_target])
            ranges = np.linalg.norm(frame.points[truth.hit_target], axis=1)
            miss = np.linalg.norm(pts - at, axis=1)
            assert np.all(miss <= drone.radius + half_beam * ranges + 1e-6)
            hits += len(pts)
    assert hits >= 20


# --- odometry ------------------------------------------------------------------------------


def test_no_drift_without_sigma_and_drift_only_in_the_reported_poses() -> None:
    flight = _constant_velocity((0.0, -6.0, 3.0), (0.0, 3.0, 0.0))
    kwargs = {"scene": _scene(), "target": OUT_OF_RANGE, "tilt": 0.1, "seed": 4}
    clean = _world(Observer.fixed(flight), **kwargs)
    drifting = _world(Observer.fixed(flight), odometry_sigma=0.5, **kwargs)
    assert clean.odometry is None
    for _ in range(10):
        (fa, ta), (fb, tb) = clean.step(), drifting.step()
        # Sigma 0: the reported poses are the true ones.
        assert ta.observer_position is not None
        assert ta.observer_reported is not None
        np.testing.assert_array_equal(ta.observer_reported, ta.observer_position)
        # The sensor fires from the true pose either way: the same returns.
        np.testing.assert_array_equal(fa.points, fb.points)
        np.testing.assert_array_equal(tb.observer_position, ta.observer_position)
        # Only the reported translation drifts, by the truth's reported − true at the end.
        np.testing.assert_array_equal(fb.poses[:, :3, :3], fa.poses[:, :3, :3])
        drift = fb.poses[:, :3, 3] - fa.poses[:, :3, 3]
        assert tb.observer_reported is not None
        assert tb.observer_position is not None
        np.testing.assert_allclose(
            drift[-1], tb.observer_reported - tb.observer_position, atol=1e-12
        )
    assert np.linalg.norm(drift[-1]) > 0.0
    # A 1 s walk at 0.5 m/√s: a few decimetres, not metres.
    assert np.linalg.norm(drift[-1]) < 5 * 0.5 * math.sqrt(3.0)


def test_odometry_drift_grows_as_sigma_root_t() -> None:
    sigma, walkers = 0.2, 400
    period = 0.5  # [s] frames of the walk (any length will do)
    checkpoints: dict[int, list[np.ndarray]] = {2: [], 8: [], 18: []}  # frame → drift at its end
    continuous = True
    for seed in range(walkers):
        drift = OdometryDrift(sigma, np.random.default_rng(seed))
        previous = drift.current
        for k in range(1, 19):
            # Frames whose pose samples share their ends, as the world's do.
            d = drift.sample(np.linspace(period * (k - 1), period * k, 11))
            continuous &= bool(np.array_equal(d[0], previous))
            previous = d[-1]
            if k in checkpoints:
                checkpoints[k].append(d[-1])
    assert continuous
    for k, ends in checkpoints.items():
        ends_a = np.asarray(ends)  # (walkers, 3)
        t = period * k
        # Per axis the drift is N(0, σ² t): 1200 samples, so the std is within a few %.
        assert np.std(ends_a) == pytest.approx(sigma * math.sqrt(t), rel=0.08)
        assert abs(np.mean(ends_a)) < 4 * sigma * math.sqrt(t / ends_a.size)
    # Seeded: the same generator gives the same walk; σ = 0 never draws.
    times = np.linspace(0.0, 0.1, 101)
    a = OdometryDrift(sigma, np.random.default_rng(7)).sample(times)
    b = OdometryDrift(sigma, np.random.default_rng(7)).sample(times)
    np.testing.assert_array_equal(a, b)
    rng = np.random.default_rng(7)
    state = rng.bit_generator.state
    np.testing.assert_array_equal(OdometryDrift(0.0, rng).sample(times), np.zeros((101, 3)))
    assert rng.bit_generator.state == state


# --- the seed 002 preset -------------------------------------------------------------------


def test_seed002_relative_runs_closed_loop_and_sees_the_target() -> None:
    cfg = SCENARIOS["seed002-relative"].model_copy(update={"duration_s": 3.0})
    run = run_simulation(cfg)
    log = run.log
    assert len(log.t) == 30  # no background scan: tracking from the first frame
    assert max(log.n_target_points) > 0
    # range_m is the observer-target distance (to the sensor, 0.24 m above the body).
    orbit = make_flight("observer-orbit", 0.0, 3.0, np.random.default_rng(0))
    observer = orbit.position(np.asarray(log.t))
    truth = np.linalg.norm(np.asarray(log.gt) - observer, axis=1)
    np.testing.assert_allclose(log.range_m, truth, atol=0.3)
    # The mount holds still ("fixed" mode, level): the sensor looks along the body's x.
    assert np.allclose(log.pan, 0.0, atol=1e-3)
    assert np.allclose(log.tilt, 0.0, atol=2e-3)


def test_seed002_relative_keeps_the_observer_clear_of_the_target() -> None:
    world = build_world(SCENARIOS["seed002-relative"])
    assert world.observer is not None
    t = np.linspace(0.0, 60.0, 6001)
    gap = np.linalg.norm(
        world.trajectory.position(t) - world.observer.trajectory.position(t), axis=1
    )
    assert gap.min() > 4.0
    assert 60.0 < gap.max() < 75.0  # out beyond seed 002's 50 m
    speed = np.linalg.norm(world.observer.trajectory.velocity(t), axis=1)
    assert speed.max() == pytest.approx(2.5, abs=0.01)
    z = world.observer.trajectory.position(t)[:, 2]
    np.testing.assert_allclose(z, 10.0)
    target_speed = np.linalg.norm(world.trajectory.velocity(t), axis=1)
    assert target_speed.max() <= 9.0 + 1e-9
