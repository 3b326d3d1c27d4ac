"""Scenarios: a scene, a target and its trajectory, a sensor on a turret, and the weather.

The target (``[drone]`` and ``[trajectory]``) is the drone the run is scored on;
``[[targets]]`` entries add further drones, each with its own model, path and
start time; ``[[walkers]]`` and ``[[vehicles]]`` people and cars on the ground
(``config/movers.py``).

The turret stands on the ground at the world origin, or, with an ``[observer]``
section, rides on a drone flying its own trajectory (seed 002's relative
tracking); its base is then an offset in the drone's body frame.

A scenario is a validated configuration (TOML at the edge, degrees where humans
type angles); ``build.py`` turns it into a ``SimWorld``.  Named scenarios live in
``scenarios.py``; a TOML file can start from one with ``base = "name"`` and
override any key.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, ClassVar, Literal, Self

import tomli_w
from pydantic import Field, ValidationError, model_validator

from dronetrack.config.movers import VehicleConfig, WalkerConfig
from dronetrack.config.pipeline import PipelineConfig, StrictModel
from dronetrack.config.reach import changes_rig, rig_evaluation
from dronetrack.config.site import SapientConfig, SiteConfig, ZoneConfig
from dronetrack.config.tomlfile import format_validation_error, read_toml
from dronetrack.errors import ScenarioError

__all__ = [
    "ClutterConfig",
    "DroneConfig",
    "FlightSource",
    "ObserverConfig",
    "ScenarioConfig",
    "SceneConfig",
    "SensorConfig",
    "TargetConfig",
    "TrajectoryConfig",
    "TurretConfig",
    "WeatherConfig",
    "absolute_path",
    "apply_overrides",
    "dump_scenario",
    "load_scenario_file",
    "map_paths",
    "with_rig_reach",
]

MAX_DURATION_S = 86_400.0  # one day of simulated time
Vec3 = tuple[float, float, float]
Pair = tuple[float, float]


class ClutterConfig(StrictModel):
    """What else moves or echoes in the scene: swaying tree crowns, random false alarms
    and birds (``sim/clutter.py``).  The sway amplitudes are those of a crown whose
    centre stands 10 m up; other crowns and the hedges scale with their height."""

    # Crowns and hedges sway: a slow gust along the wind plus a faster sway at the
    # trees' natural period, each with a random phase per tree.  0 m turns one off.
    gust_m: float = Field(0.25, ge=0, le=10)  # gust amplitude [m]
    gust_period_s: float = Field(20.0, gt=0, le=3600)
    sway_m: float = Field(0.15, ge=0, le=10)  # natural-sway amplitude [m]
    sway_period_s: float = Field(3.0, gt=0, le=60)  # varies ±25 % from tree to tree
    # Spurious returns per second, besides the sensor's own per-pulse false_alarm_rate.
    false_alarms_per_s: float = Field(0.0, ge=0, le=1e6)
    birds: int = Field(0, ge=0, le=100)
    # Seconds after the target's take-off at which one of the birds crosses the line of
    # sight to the target, halfway along it (at most one crossing per bird).
    bird_crossings_s: tuple[float, ...] = ()
    bird_size_m: Pair = (0.2, 0.5)  # wingspan, drawn uniformly per bird
    bird_speed_m_s: Pair = (5.0, 15.0)
    bird_height_m: Pair = (5.0, 60.0)
    bird_reflectivity: float = Field(0.3, gt=0, le=1)  # diffuse, at 905 nm

    @model_validator(mode="after")
    def _check(self) -> Self:
        for key in ("bird_size_m", "bird_speed_m_s", "bird_height_m"):
            lo, hi = getattr(self, key)
            if not 0 < lo <= hi:
                raise ValueError(f"{key} must be (low, high) with 0 < low ≤ high, got {lo}, {hi}")
        if self.bird_size_m[1] > 5.0 or self.bird_speed_m_s[1] > 50.0:
            raise ValueError("birds are at most 5 m across and fly at most 50 m/s")
        if self.bird_height_m[1] > 1000.0:
            raise ValueError("birds fly at most 1000 m up")
        if any(not 0 <= t <= MAX_DURATION_S for t in self.bird_crossings_s):
            raise ValueError(f"bird_crossings_s must be times from 0 to {MAX_DURATION_S:g} s")
        if len(self.bird_crossings_s) > self.birds:
            raise ValueError(
                f"{len(self.bird_crossings_s)} bird crossings need at least as many birds, "
                f"got birds = {self.birds}"
            )
        return self


class SceneConfig(StrictModel):
    name: str = "outdoor"
    layout_seed: int = Field(0, ge=0)
    clutter: ClutterConfig | None = None  # None: a still scene, as the seeds had


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


class TargetConfig(StrictModel):
    """A further drone (a ``[[targets]]`` entry): its model, its path, and when it enters.

    The path is a named ``flight`` or a CSV ``file`` (columns t,x,y,z), one of them.
    The drone is not in the world before ``start_s``, counted as ``duration_s`` is
    (from the end of the background scan in ``simulate``); it then waits ``hold_s``
    at the path's first point and flies it.  A file's first row is placed there, as
    ``[trajectory] file`` is placed at its ``hold_s``.
    """

    model: str = "phantom4"
    flight: str | None = None
    file: str | None = None
    start_s: float = Field(0.0, ge=0, le=MAX_DURATION_S, allow_inf_nan=False)
    hold_s: float = Field(0.0, ge=0, le=MAX_DURATION_S, allow_inf_nan=False)
    reflectivity_scale: float = Field(1.0, gt=0, allow_inf_nan=False)

    @model_validator(mode="after")
    def _one_path(self) -> Self:
        if (self.flight is None) == (self.file is None):
            raise ValueError("give a target either a flight (a named one) or a file, one of them")
        return self


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
    # Further drones besides the target ([[targets]]); the run is scored on the target.
    targets: tuple[TargetConfig, ...] = ()
    # People and cars on the ground ([[walkers]], [[vehicles]]), labelled in the truth.
    walkers: tuple[WalkerConfig, ...] = ()
    vehicles: tuple[VehicleConfig, ...] = ()
    # Where the turret stands on the Earth, and the zones the site protects
    # (``config/site.py``); without [site], tracks are in the local world frame only.
    site: SiteConfig | None = None
    zones: tuple[ZoneConfig, ...] = ()
    sapient: SapientConfig | None = None  # the node's name and ID for --sapient
    # How the run is processed by ``dronetrack simulate``; the simulator ignores it.
    pipeline: PipelineConfig = PipelineConfig()

    @model_validator(mode="after")
    def _objects_come_in_the_run(self) -> Self:
        if self.zones and self.site is None:
            raise ValueError(
                "[[zones]] need the site's coordinates: add [site] with latitude_deg and "
                "longitude_deg (of the turret base)"
            )
        names = [zone.name for zone in self.zones]
        if len(set(names)) < len(names):
            twice = next(n for n in names if names.count(n) > 1)
            raise ValueError(f"two [[zones]] are named {twice!r}: each zone needs its own name")
        for i, target in enumerate(self.targets):
            if target.start_s >= self.duration_s:
                raise ValueError(
                    f"targets.{i}.start_s = {target.start_s:g} s is not before the run ends "
                    f"(duration_s = {self.duration_s:g} s): the drone would never be seen"
                )
        for i, vehicle in enumerate(self.vehicles):
            if vehicle.arrive_s >= self.duration_s:
                raise ValueError(
                    f"vehicles.{i}.arrive_s = {vehicle.arrive_s:g} s is not before the run "
                    f"ends (duration_s = {self.duration_s:g} s): the vehicle would never park"
                )
        return self


def _merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def with_rig_reach(cfg: ScenarioConfig) -> ScenarioConfig:
    """``cfg`` with the reach of its sensor for its drone in its air
    (``config.reach.rig_evaluation``): a scenario that changes any of the three no
    longer has its base's reach."""
    update = rig_evaluation(cfg.sensor.model, cfg.drone.model, cfg.weather.visibility_m)
    evaluation = cfg.pipeline.evaluation.model_copy(update=update)
    pipeline = cfg.pipeline.model_copy(update={"evaluation": evaluation})
    return cfg.model_copy(update={"pipeline": pipeline})


def validate_scenario(data: dict[str, Any], source: str) -> ScenarioConfig:
    """Validate a scenario mapping, raising ScenarioError with a one-line message."""
    try:
        return ScenarioConfig.model_validate(data)
    except ValidationError as err:
        raise ScenarioError(format_validation_error(err, source)) from None


def load_scenario_file(path: Path, named: dict[str, ScenarioConfig]) -> ScenarioConfig:
    """Read a scenario TOML file; ``base = "name"`` starts from a named scenario."""
    data = read_toml(path, "scenario file", ScenarioError)
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
        own = data
        data = _merge(base, {"name": path.stem, **data})
    cfg = validate_scenario(data, str(path))
    if base_name is not None and changes_rig(own):
        cfg = with_rig_reach(cfg)
    # Files named in a scenario file are relative to that file's folder.
    return map_paths(cfg, lambda p: _anchored(p, path.parent))


def _anchored(path: str, folder: Path) -> str:
    """``path`` as given if absolute, else relative to ``folder``."""
    return path if Path(path).expanduser().is_absolute() else str(folder / path)


def absolute_path(path: str) -> str:
    return str(Path(path).expanduser().resolve())


def map_paths(
    cfg: ScenarioConfig, fix: Callable[[str], str], background: bool = True
) -> ScenarioConfig:
    """The scenario with ``fix`` applied to every file it names: the trajectory, target
    and observer CSVs, a ``file:`` scan pattern and (with ``background``) a saved background."""
    traj, sensor, observer = cfg.trajectory, cfg.sensor, cfg.observer
    if traj.file is not None:
        traj = traj.model_copy(update={"file": fix(traj.file)})
    if observer is not None and observer.file is not None:
        observer = observer.model_copy(update={"file": fix(observer.file)})
    if sensor.model.lower().startswith("file:"):
        sensor = sensor.model_copy(update={"model": f"file:{fix(sensor.model[5:])}"})
    targets = tuple(
        t if t.file is None else t.model_copy(update={"file": fix(t.file)}) for t in cfg.targets
    )
    pipeline = cfg.pipeline
    if background and pipeline.background.file is not None:
        stored = pipeline.background.model_copy(update={"file": fix(pipeline.background.file)})
        pipeline = pipeline.model_copy(update={"background": stored})
    return cfg.model_copy(
        update={
            "trajectory": traj,
            "sensor": sensor,
            "pipeline": pipeline,
            "observer": observer,
            "targets": targets,
        }
    )


def apply_overrides(
    cfg: ScenarioConfig,
    *,
    seed: int | None = None,
    duration: float | None = None,
    trajectory: Path | Sequence[Path] | None = None,
    visibility: float | None = None,
    drone: str | None = None,
    sensor: str | None = None,
    noise: bool | None = None,
    tracker: str | None = None,
    particles: int | None = None,
    turret_mode: str | None = None,
    source: str = "command line",
) -> ScenarioConfig:
    """The scenario with command-line overrides applied (None leaves a value alone); a
    bad value is a ScenarioError naming ``source`` (where the values came from).

    ``trajectory`` may name several CSV files: the first replaces the target's path,
    each further one adds a drone of the scenario's model (after ``drone``) on it,
    entering at the start, after any ``[[targets]]`` the scenario has.  A ``duration``
    that ends the run before a ``[[vehicles]]`` entry parks leaves that vehicle out."""
    paths = [trajectory] if isinstance(trajectory, Path) else list(trajectory or ())
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
        # a run cut short leaves out the vehicles that would only park after its end
        data["vehicles"] = [v for v in data.get("vehicles", []) if v["arrive_s"] < duration]
    if paths:
        data["trajectory"] = {
            "name": None,
            "file": str(paths[0]),
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
    model = data["drone"]["model"]
    data["targets"] = [*data["targets"], *({"model": model, "file": str(p)} for p in paths[1:])]
    cfg = validate_scenario(data, source)
    if drone is not None or sensor is not None or visibility is not None:
        cfg = with_rig_reach(cfg)  # the reach belongs to the sensor, the drone and the air
    return cfg


def dump_scenario(config: ScenarioConfig) -> str:
    """The scenario as TOML (keys left unset are omitted, and so are ``targets``,
    ``walkers``, ``vehicles`` and ``zones`` when there are none); further drones are
    ``[[targets]]`` tables, people and cars ``[[walkers]]`` and ``[[vehicles]]``."""
    data = config.model_dump(exclude_none=True)
    for key in ("targets", "walkers", "vehicles", "zones"):
        if not data[key]:
            del data[key]
    return tomli_w.dumps(data)
