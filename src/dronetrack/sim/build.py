"""Building the simulator from a scenario: sensor, turret, paths, observer, world.

``resolve_scenario`` writes every preset value out so a re-run needs nothing
else; ``build_world`` turns a scenario into a ``SimWorld``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.config.run import (
    FlightSource,
    ObserverConfig,
    ScenarioConfig,
    SensorConfig,
    TurretConfig,
    absolute_path,
    map_paths,
)
from dronetrack.geometry.mount import MountGeometry
from dronetrack.sim.drones import make_drone
from dronetrack.sim.flights import make_flight
from dronetrack.sim.physics import extinction_coefficient
from dronetrack.sim.scene import make_scene
from dronetrack.sim.sensors import SensorModel, make_sensor
from dronetrack.sim.trajectories import Trajectory, load_csv_trajectory
from dronetrack.sim.turret import AxisSpec, TurretSpec, make_turret
from dronetrack.sim.world import Observer, SimWorld

__all__ = ["build_world", "resolve_scenario", "turret_spec"]

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


def _axis(preset: AxisSpec, cfg: TurretConfig, limits: Pair | None) -> AxisSpec:
    lo, hi = (
        (math.radians(limits[0]), math.radians(limits[1]))
        if limits
        else (preset.lower, preset.upper)
    )
    return AxisSpec(
        rate=math.radians(cfg.rate_deg_s) if cfg.rate_deg_s is not None else preset.rate,
        accel=math.radians(cfg.accel_deg_s2) if cfg.accel_deg_s2 is not None else preset.accel,
        resolution=(
            math.radians(cfg.resolution_deg)
            if cfg.resolution_deg is not None
            else preset.resolution
        ),
        lower=lo,
        upper=hi,
        latency=preset.latency if cfg.latency_s is None else cfg.latency_s,
    )


def turret_spec(cfg: TurretConfig) -> TurretSpec:
    """The turret a scenario's [turret] section describes: its preset with the section's values."""
    preset = make_turret(cfg.model)
    m = preset.mount
    base = m.base if cfg.base_height_m is None else (m.base[0], m.base[1], cfg.base_height_m)
    mount = MountGeometry(
        base=base,
        pan_to_tilt=cfg.pan_to_tilt_m or m.pan_to_tilt,
        tilt_to_sensor=cfg.tilt_to_sensor_m or m.tilt_to_sensor,
    )
    return TurretSpec(
        name=preset.name,
        pan=_axis(preset.pan, cfg, cfg.pan_limits_deg),
        tilt=_axis(preset.tilt, cfg, cfg.tilt_limits_deg),
        mount=mount,
        profile_time_s=preset.profile_time_s if cfg.profile_time_s is None else cfg.profile_time_s,
    )


def _flight(source: FlightSource, duration: float, rng: np.random.Generator) -> Trajectory:
    """The path a trajectory or observer section names: its CSV file or a named flight."""
    if source.file is not None:
        return load_csv_trajectory(Path(source.file).expanduser(), t0=source.hold_s)
    assert source.name is not None
    return make_flight(source.name, source.hold_s, duration, rng)


def _observer(cfg: ObserverConfig, duration: float, rng: np.random.Generator) -> Observer:
    trajectory = _flight(cfg, duration, rng)
    yaw = math.radians(cfg.yaw_deg)
    if cfg.yaw == "fixed":
        return Observer.fixed(trajectory, yaw)
    return Observer.heading(trajectory, yaw)


def resolve_scenario(cfg: ScenarioConfig) -> ScenarioConfig:
    """The scenario with every preset value written out, so a re-run needs nothing else."""
    sensor = _sensor(cfg.sensor)
    turret = turret_spec(cfg.turret)
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
    turret_cfg = cfg.turret.model_copy(
        update={
            "base_height_m": turret.mount.base[2],
            "pan_to_tilt_m": turret.mount.pan_to_tilt,
            "tilt_to_sensor_m": turret.mount.tilt_to_sensor,
            "pan_limits_deg": (deg(turret.pan.lower), deg(turret.pan.upper)),
            "tilt_limits_deg": (deg(turret.tilt.lower), deg(turret.tilt.upper)),
            "profile_time_s": turret.profile_time_s,
        }
    )
    # The per-axis settings are written out when both axes share them (as in the
    # presets); the config sets both axes at once.
    p, t = turret.pan, turret.tilt
    if (p.rate, p.accel, p.resolution, p.latency) == (t.rate, t.accel, t.resolution, t.latency):
        turret_cfg = turret_cfg.model_copy(
            update={
                "rate_deg_s": deg(turret.pan.rate),
                "accel_deg_s2": deg(turret.pan.accel),
                "resolution_deg": deg(turret.pan.resolution),
                "latency_s": turret.pan.latency,
            }
        )
    # Input files as absolute paths (the background's is written by the pipeline's
    # resolution, with the map's own settings).
    resolved = cfg.model_copy(update={"sensor": sensor_cfg, "turret": turret_cfg})
    return map_paths(resolved, absolute_path, background=False)


def build_world(cfg: ScenarioConfig, rng: np.random.Generator | None = None) -> SimWorld:
    """The simulator for a scenario; ``rng`` defaults to one seeded with ``cfg.seed``.

    The observer's flight (if any) is built after the target's, so the target flies
    the same path with or without one.
    """
    rng = np.random.default_rng(cfg.seed) if rng is None else rng
    sensor = _sensor(cfg.sensor)
    turret = turret_spec(cfg.turret)
    scene = make_scene(cfg.scene.name, cfg.scene.layout_seed)
    drone = make_drone(cfg.drone.model, cfg.drone.reflectivity_scale)
    trajectory = _flight(cfg.trajectory, cfg.duration_s, rng)
    observer = None if cfg.observer is None else _observer(cfg.observer, cfg.duration_s, rng)
    return SimWorld(
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
    )
