"""Scenarios: a scene, a target and its trajectory, a sensor on a turret, and the weather.

The turret stands on the ground at the world origin, or, with an ``[observer]``
section, rides on a drone flying its own trajectory (seed 002's relative
tracking); its base is then an offset in the drone's body frame.

A scenario is a validated configuration (TOML at the edge, degrees where humans
type angles) that builds a ``SimWorld``.  Named scenarios live in
``scenarios.py``; a TOML file can start from one with ``base = "name"`` and
override any key.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar, Literal, Self

import numpy as np
import tomli_w
from pydantic import Field, ValidationError, model_validator

from dronetrack.config import PipelineConfig, StrictModel
from dronetrack.errors import ScenarioError
from dronetrack.kinematics import MountGeometry
from dronetrack.sim.drones import make_drone
from dronetrack.sim.flights import make_flight
from dronetrack.sim.physics import extinction_coefficient
from dronetrack.sim.scene import make_scene
from dronetrack.sim.sensors import SensorModel, make_sensor
from dronetrack.sim.trajectories import Trajectory, load_csv_trajectory
from dronetrack.sim.turret import AxisSpec, TurretSpec, make_turret
from dronetrack.sim.world import Observer, SimWorld

__all__ = [
    "DroneConfig",
    "ObserverConfig",
    "ScenarioConfig",
    "SceneConfig",
    "SensorConfig",
    "TrajectoryConfig",
    "TurretConfig",
    "WeatherConfig",
    "apply_overrides",
    "build_world",
    "dump_scenario",
    "format_validation_error",
    "load_scenario_file",
    "resolve_scenario",
]

MAX_DURATION_S = 86_400.0  # one day of simulated time
Vec3 = tuple[float, float, float]
Pair = tuple[float, float]


class SceneConfig(StrictModel):
    name: str = "outdoor"
    layout_seed: int = Field(0, ge=0)


class DroneConfig(StrictModel):
    model: str = "phantom4"
    reflectivity_scale: float = Field(1.0, gt=0)


DEFAULT_FLIGHT = "horizontal-fast"


class FlightSource(StrictModel):
    """A path: a named flight (the section's default when no file is given either) or a
    CSV with columns t,x,y,z, held ``hold_s`` seconds at its start."""

    _section: ClassVar[str] = "trajectory"
    _default: ClassVar[str] = DEFAULT_FLIGHT

    name: str | None = None  # a named flight; the default one when no file is given either
    file: str | None = None  # CSV with columns t,x,y,z
    hold_s: float = Field(0.0, ge=0)  # at the start (on the ground, or at the first sample)

    @model_validator(mode="after")
    def _one_source(self) -> Self:
        if self.file is not None and self.name is not None:
            section = self._section
            raise ValueError(f"give either {section}.name or {section}.file, not both")
        if self.file is None and self.name is None:
            object.__setattr__(self, "name", self._default)
        return self


class TrajectoryConfig(FlightSource):
    """The target's path."""


DEFAULT_OBSERVER_FLIGHT = "observer-hover"


class ObserverConfig(FlightSource):
    """A moving observer: the turret and sensor ride on a drone flying this trajectory.

    With one, the turret's base (``turret.base_height_m``) is its offset in the
    drone's body frame (x forward, y left, z up; roll and pitch taken as zero).
    The body's yaw follows the velocity heading with a lag (``heading``; held
    while hovering, ``yaw_deg`` before the first move) or stays at ``yaw_deg``
    (``fixed``).  The frames carry the poses the drone's odometry reports:
    the true ones plus a random walk of ``odometry_sigma_m`` m/√s per axis.
    """

    _section: ClassVar[str] = "observer"
    _default: ClassVar[str] = DEFAULT_OBSERVER_FLIGHT

    yaw: Literal["heading", "fixed"] = "heading"
    yaw_deg: float = Field(0.0, allow_inf_nan=False)
    odometry_sigma_m: float = Field(0.0, ge=0, allow_inf_nan=False)  # [m/√s]


class SensorConfig(StrictModel):
    model: str = "avia"  # avia, mid40, mid360, vlp16, vlp16-side or file:PATH
    integration_time_s: float = Field(0.1, ge=1e-3, le=1.0)
    noise: bool = True
    rpm: float | None = None  # vlp16 and vlp16-side spin rate
    rate_hz: float | None = Field(None, gt=0, le=1e7)  # file: patterns
    lines: int | None = Field(None, ge=1, le=255)  # file: patterns
    physics: str | None = None  # whose range physics a file: pattern uses (default avia)
    range_sigma_m: float | None = Field(None, ge=0)
    angular_sigma_deg: float | None = Field(None, ge=0)
    false_alarm_rate: float | None = Field(None, ge=0, le=1)


class TurretConfig(StrictModel):
    model: str = "widowx"
    pan_deg: float = 0.0  # initial angles
    tilt_deg: float = 0.0
    base_height_m: float | None = None
    pan_to_tilt_m: Vec3 | None = None
    tilt_to_sensor_m: Vec3 | None = None
    latency_s: float | None = Field(None, ge=0)
    rate_deg_s: float | None = Field(None, gt=0)
    accel_deg_s2: float | None = Field(None, gt=0)
    resolution_deg: float | None = Field(None, ge=0)
    pan_limits_deg: Pair | None = None
    tilt_limits_deg: Pair | None = None
    profile_time_s: float | None = Field(None, ge=0)


class WeatherConfig(StrictModel):
    # Meteorological visibility [m]; inf is clear air.
    visibility_m: float = Field(math.inf, gt=0, allow_inf_nan=True)

    @model_validator(mode="after")
    def _not_nan(self) -> WeatherConfig:
        if math.isnan(self.visibility_m):
            raise ValueError("visibility_m must be a number or inf")
        return self


class ScenarioConfig(StrictModel):
    name: str = "custom"
    description: str = ""
    duration_s: float = Field(60.0, gt=0, le=MAX_DURATION_S)
    seed: int = Field(0, ge=0)
    scene: SceneConfig = SceneConfig()
    drone: DroneConfig = DroneConfig()
    trajectory: TrajectoryConfig = TrajectoryConfig()
    sensor: SensorConfig = SensorConfig()
    turret: TurretConfig = TurretConfig()
    weather: WeatherConfig = WeatherConfig()
    observer: ObserverConfig | None = None  # None: the turret stands on the ground
    # How the run is processed by ``dronetrack simulate``; the simulator ignores it.
    pipeline: PipelineConfig = PipelineConfig()


def format_validation_error(err: ValidationError, source: str) -> str:
    """One line naming the first bad key and why."""
    first = err.errors()[0]
    key = ".".join(str(p) for p in first["loc"]) or "(top level)"
    if first["type"] == "extra_forbidden":
        msg = f"{source}: unknown key '{key}'"
    else:
        msg = f"{source}: {key}: {first['msg']}"
    more = len(err.errors()) - 1
    return msg + (f" (and {more} more problem{'s' if more > 1 else ''})" if more else "")


def _merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def validate_scenario(data: dict[str, Any], source: str) -> ScenarioConfig:
    """Validate a scenario mapping, raising ScenarioError with a one-line message."""
    try:
        return ScenarioConfig.model_validate(data)
    except ValidationError as err:
        raise ScenarioError(format_validation_error(err, source)) from None


def load_scenario_file(path: Path, named: dict[str, ScenarioConfig]) -> ScenarioConfig:
    """Read a scenario TOML file; ``base = "name"`` starts from a named scenario."""
    try:
        with path.open("rb") as f:
            data = tomllib.load(f)
    except FileNotFoundError:
        raise ScenarioError(f"scenario file not found: {path}") from None
    except tomllib.TOMLDecodeError as err:
        raise ScenarioError(f"{path}: invalid TOML: {err}") from None
    base_name = data.pop("base", None)
    if base_name is not None:
        if not isinstance(base_name, str) or base_name not in named:
            raise ScenarioError(f"{path}: unknown base scenario {base_name!r}")
        base = named[base_name].model_dump()
        if "file" in data.get("trajectory", {}):
            base["trajectory"]["name"] = None  # a file replaces the base's named flight
        observer = data.get("observer")
        if isinstance(observer, dict) and "file" in observer and base.get("observer"):
            base["observer"]["name"] = None
        data = _merge(base, {"name": path.stem, **data})
    # Files named in a scenario file are relative to that file's folder.
    return _map_paths(validate_scenario(data, str(path)), lambda p: _anchored(p, path.parent))


def _anchored(path: str, folder: Path) -> str:
    """``path`` as given if absolute, else relative to ``folder``."""
    return path if Path(path).expanduser().is_absolute() else str(folder / path)


def _absolute(path: str) -> str:
    return str(Path(path).expanduser().resolve())


def _map_paths(
    cfg: ScenarioConfig, fix: Callable[[str], str], background: bool = True
) -> ScenarioConfig:
    """The scenario with ``fix`` applied to every file it names: the trajectory and
    observer CSVs, a ``file:`` scan pattern and (with ``background``) a saved background."""
    traj, sensor, observer = cfg.trajectory, cfg.sensor, cfg.observer
    if traj.file is not None:
        traj = traj.model_copy(update={"file": fix(traj.file)})
    if observer is not None and observer.file is not None:
        observer = observer.model_copy(update={"file": fix(observer.file)})
    if sensor.model.lower().startswith("file:"):
        sensor = sensor.model_copy(update={"model": f"file:{fix(sensor.model[5:])}"})
    pipeline = cfg.pipeline
    if background and pipeline.background.file is not None:
        stored = pipeline.background.model_copy(update={"file": fix(pipeline.background.file)})
        pipeline = pipeline.model_copy(update={"background": stored})
    return cfg.model_copy(
        update={"trajectory": traj, "sensor": sensor, "pipeline": pipeline, "observer": observer}
    )


def apply_overrides(
    cfg: ScenarioConfig,
    *,
    seed: int | None = None,
    duration: float | None = None,
    trajectory: Path | None = None,
    visibility: float | None = None,
    drone: str | None = None,
    sensor: str | None = None,
    noise: bool | None = None,
    tracker: str | None = None,
    particles: int | None = None,
    turret_mode: str | None = None,
) -> ScenarioConfig:
    """The scenario with command-line overrides applied (None leaves a value alone)."""
    data = cfg.model_dump()
    if tracker is not None:
        data["pipeline"]["tracker"]["kind"] = tracker
    if particles is not None:
        data["pipeline"]["tracker"]["particles"] = particles
    if turret_mode is not None:
        data["pipeline"]["controller"]["mode"] = turret_mode
    if seed is not None:
        data["seed"] = seed
    if duration is not None:
        data["duration_s"] = duration
    if trajectory is not None:
        data["trajectory"] = {
            "name": None,
            "file": str(trajectory),
            "hold_s": cfg.trajectory.hold_s,
        }
    if visibility is not None:
        data["weather"]["visibility_m"] = visibility
    if drone is not None:
        data["drone"]["model"] = drone
        data["pipeline"]["tracker"]["s_diag"] = None  # the new drone's diagonal (eq. 11)
        data["pipeline"]["tracker"]["sigma_m"] = None
    if sensor is not None:
        data["sensor"]["model"] = sensor
    if noise is not None:
        data["sensor"]["noise"] = noise
    return validate_scenario(data, "command line")


def dump_scenario(config: ScenarioConfig) -> str:
    """The scenario as TOML (keys left unset are omitted)."""
    return tomli_w.dumps(config.model_dump(exclude_none=True))


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


def _turret(cfg: TurretConfig) -> TurretSpec:
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
    turret = _turret(cfg.turret)
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
    return _map_paths(resolved, _absolute, background=False)


def build_world(cfg: ScenarioConfig, rng: np.random.Generator | None = None) -> SimWorld:
    """The simulator for a scenario; ``rng`` defaults to one seeded with ``cfg.seed``.

    The observer's flight (if any) is built after the target's, so the target flies
    the same path with or without one.
    """
    rng = np.random.default_rng(cfg.seed) if rng is None else rng
    sensor = _sensor(cfg.sensor)
    turret = _turret(cfg.turret)
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
