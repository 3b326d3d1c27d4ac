"""Building the simulator from a scenario: sensor, turret, paths, observer, world.

``resolve_scenario`` writes every preset value out so a re-run needs nothing
else; ``build_world`` turns a scenario into a ``SimWorld``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.config.movers import VehicleConfig, WalkerConfig
from dronetrack.config.rig import resolve_turret, turret_spec
from dronetrack.config.run import (
    FlightSource,
    ObserverConfig,
    ScenarioConfig,
    SensorConfig,
    TargetConfig,
    absolute_path,
    map_paths,
)
from dronetrack.config.tomlfile import tidy_model
from dronetrack.errors import ConfigError, ScenarioError
from dronetrack.sim.clutter import ClutterSpec
from dronetrack.sim.drones import make_drone
from dronetrack.sim.flights import make_flight
from dronetrack.sim.movers import Mover, Movers, vehicle, walker
from dronetrack.sim.physics import extinction_coefficient
from dronetrack.sim.scene import make_scene
from dronetrack.sim.sensors import SensorModel, make_sensor
from dronetrack.sim.targets import SimTarget
from dronetrack.sim.trajectories import Trajectory, load_csv_trajectory
from dronetrack.sim.world import Observer, SimWorld

__all__ = ["build_world", "resolve_scenario"]

Pair = tuple[float, float]


def _sensor(cfg: SensorConfig) -> SensorModel:
    overrides: dict[str, Any] = {}
    if cfg.range_sigma_m is not None:
        overrides["range_sigma_m"] = cfg.range_sigma_m
    if cfg.angular_sigma_deg is not None:
        overrides["angular_sigma"] = math.radians(cfg.angular_sigma_deg)
    if cfg.false_alarm_rate is not None:
        overrides["false_alarm_rate"] = cfg.false_alarm_rate
    return make_sensor(
        cfg.model,
        noise=cfg.noise,
        rpm=cfg.rpm,
        rate_hz=cfg.rate_hz,
        lines=cfg.lines,
        physics=cfg.physics,
        **overrides,
    )


def _flight(source: FlightSource, duration: float, rng: np.random.Generator) -> Trajectory:
    """The path a trajectory or observer section names: its CSV file or a named flight."""
    if source.file is not None:
        return load_csv_trajectory(Path(source.file).expanduser(), t0=source.hold_s)
    assert source.name is not None
    return make_flight(source.name, source.hold_s, duration, rng)


def _target(i: int, cfg: TargetConfig, duration: float, rng: np.random.Generator) -> SimTarget:
    """Target entry ``i``: in the world from ``start_s``, flying its path from
    ``start_s + hold_s`` (a file's first row there); a bad entry is a ScenarioError
    naming it."""
    take_off = cfg.start_s + cfg.hold_s
    try:
        drone = make_drone(cfg.model, cfg.reflectivity_scale)
        path: Trajectory
        if cfg.file is not None:
            path = load_csv_trajectory(Path(cfg.file).expanduser(), t0=take_off)
        else:
            assert cfg.flight is not None
            path = make_flight(cfg.flight, take_off, duration, rng)
    except ConfigError as err:
        raise ScenarioError(f"targets.{i}: {err}") from None
    return SimTarget(drone, path, cfg.start_s)


def _movers(
    walkers: tuple[WalkerConfig, ...],
    vehicles: tuple[VehicleConfig, ...],
    rng: np.random.Generator,
) -> Movers:
    """The walkers (each walking on a stream of its own, spawned from ``rng``), then the
    vehicles, in the order given."""
    out: list[Mover] = []
    for group in walkers:
        out += [
            walker(group.area_m, group.speed_m_s, group.pause_s, stream)
            for stream in rng.spawn(group.count)
        ]
    out += [vehicle(v.path_m, v.speed_m_s, v.arrive_s, v.size_m, v.reflectivity) for v in vehicles]
    return Movers(out)


def _observer(cfg: ObserverConfig, duration: float, rng: np.random.Generator) -> Observer:
    trajectory = _flight(cfg, duration, rng)
    yaw = math.radians(cfg.yaw_deg)
    if cfg.yaw == "fixed":
        return Observer.fixed(trajectory, yaw)
    return Observer.heading(trajectory, yaw)


def resolve_scenario(cfg: ScenarioConfig) -> ScenarioConfig:
    """The scenario with every preset value written out, so a re-run needs nothing else."""
    sensor = _sensor(cfg.sensor)
    deg = math.degrees
    sensor_cfg = cfg.sensor.model_copy(
        update={
            "range_sigma_m": sensor.range_sigma_m,
            "angular_sigma_deg": deg(sensor.angular_sigma),
            "false_alarm_rate": sensor.false_alarm_rate,
        }
    )
    if not cfg.sensor.noise:
        sensor_cfg = sensor_cfg.model_copy(
            update={"range_sigma_m": None, "angular_sigma_deg": None, "false_alarm_rate": None}
        )
    turret_cfg = resolve_turret(cfg.turret)
    # Input files as absolute paths (the background's is written by the pipeline's
    # resolution, with the map's own settings).
    resolved = cfg.model_copy(update={"sensor": sensor_cfg, "turret": turret_cfg})
    return tidy_model(map_paths(resolved, absolute_path, background=False))


def build_world(cfg: ScenarioConfig, rng: np.random.Generator | None = None) -> SimWorld:
    """The simulator for a scenario; ``rng`` defaults to one seeded with ``cfg.seed``.

    The observer's flight (if any) is built after the target's, so the target flies
    the same path with or without one.  The birds' crossing times count from the
    target's take-off, ``trajectory.hold_s``.  The ``[[targets]]`` drones' flights and
    detections draw from a stream of their own, spawned after the world's, so the
    target, the observer and the clutter are the same with or without them; their
    ``start_s`` is a time on the world's clock here (``jobs.simulate.flight_config``
    moves it past the background scan).  The walkers and vehicles draw from a stream
    spawned after that, so with them the drones fly as without; a vehicle's
    ``arrive_s`` is a time on the world's clock too.
    """
    rng = np.random.default_rng(cfg.seed) if rng is None else rng
    sensor = _sensor(cfg.sensor)
    turret = turret_spec(cfg.turret)
    scene = make_scene(cfg.scene.name, cfg.scene.layout_seed)
    drone = make_drone(cfg.drone.model, cfg.drone.reflectivity_scale)
    trajectory = _flight(cfg.trajectory, cfg.duration_s, rng)
    observer = None if cfg.observer is None else _observer(cfg.observer, cfg.duration_s, rng)
    world = SimWorld(
        sensor=sensor,
        scene=scene,
        drone=drone,
        trajectory=trajectory,
        turret=turret,
        mount=turret.mount,
        extinction=extinction_coefficient(cfg.weather.visibility_m),
        rng=rng,
        integration_time=cfg.sensor.integration_time_s,
        pan=math.radians(cfg.turret.pan_deg),
        tilt=math.radians(cfg.turret.tilt_deg),
        observer=observer,
        odometry_sigma=0.0 if cfg.observer is None else cfg.observer.odometry_sigma_m,
        clutter=None
        if cfg.scene.clutter is None
        else ClutterSpec.from_config(cfg.scene.clutter, cfg.trajectory.hold_s),
    )
    if cfg.targets:
        stream = rng.spawn(1)[0]  # after the world's own (odometry drift, clutter)
        others = [_target(i, t, cfg.duration_s, stream) for i, t in enumerate(cfg.targets)]
        world.add_targets(others, stream)
    if cfg.walkers or cfg.vehicles:
        stream = rng.spawn(1)[0]
        world.add_movers(_movers(cfg.walkers, cfg.vehicles, stream), stream)
    return world
