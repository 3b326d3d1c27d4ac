"""The rig: presets of the turrets and the targets, and the turret a run's [turret]
section describes.

A rig is what ``simulate``, ``track`` and a live run share: the pan-tilt unit (its
joints' limits and the mount geometry from the turret base to the sensor) and the
expected target (its size sets the particle filter's σ_m, eq. 11).  The simulator
adds the scene, the flight and the weather; the shapes it ray-casts a target with
are its own (``sim/drones.py``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from dronetrack.config.run import TurretConfig
from dronetrack.errors import ConfigError
from dronetrack.geometry.mount import MountGeometry

__all__ = [
    "FIELD_OF_VIEW_DEG",
    "SENSOR_MODELS",
    "TARGETS",
    "TURRET_NAMES",
    "AxisSpec",
    "TargetSpec",
    "TurretSpec",
    "make_turret",
    "narrow_field_of_view",
    "resolve_turret",
    "target_spec",
    "turret_spec",
]

Pair = tuple[float, float]


@dataclass(frozen=True, slots=True)
class AxisSpec:
    """One joint: rate [rad/s] and acceleration [rad/s²] limits, resolution and range [rad],
    and the latency [s] between a command's stamp and the joint acting on it."""

    rate: float
    accel: float
    resolution: float
    lower: float
    upper: float
    latency: float

    def __post_init__(self) -> None:
        if self.rate <= 0 or self.accel <= 0 or self.resolution < 0 or self.latency < 0:
            raise ConfigError(
                "turret rate and acceleration must be positive, resolution and latency ≥ 0"
            )
        if not self.lower < self.upper:
            raise ConfigError(
                f"turret axis limits must satisfy lower < upper, got {self.lower}, {self.upper}"
            )


@dataclass(frozen=True, slots=True)
class TurretSpec:
    """A pan-tilt unit: its two axes and its default mount geometry."""

    name: str
    pan: AxisSpec
    tilt: AxisSpec
    mount: MountGeometry
    profile_time_s: float = 0.0  # > 0: time-based profile, each goal is one move of this duration


def _deg(x: float) -> float:
    return math.radians(x)


def _widowx() -> TurretSpec:
    # Trossen WidowX Dual XM430 (wxxmd): 180°/s (Velocity_Limit 131 × 0.229 rpm),
    # 0.088° (4096 ticks/rev), pan ±180°, tilt ±68°; α_max 360°/s² and L = 20 ms [A].
    # Mount: tilt link → sensor 0.025 m forward, 0.086 m up (LiVOX_MAV_track TF tree);
    # pan → tilt axis 0.05 m up [A].
    pan = AxisSpec(_deg(180.0), _deg(360.0), _deg(0.088), _deg(-180.0), _deg(180.0), 0.020)
    tilt = AxisSpec(_deg(180.0), _deg(360.0), _deg(0.088), _deg(-68.0), _deg(68.0), 0.020)
    mount = MountGeometry(
        base=(0.0, 0.0, 1.0), pan_to_tilt=(0.0, 0.0, 0.05), tilt_to_sensor=(0.025, 0.0, 0.086)
    )
    return TurretSpec("widowx", pan, tilt, mount)


def _ptu_e46() -> TurretSpec:
    # FLIR PTU-E46: "speeds higher than 300°/s" (seed 003), 0.0129° per step
    # (the D46's 0.0514° at a 4× finer step mode; seed 003 quotes "about 0.129°"),
    # pan ±159°, tilt 31° up / 47° down (D46 family); α_max 300°/s² and L = 20 ms [A].
    pan = AxisSpec(_deg(300.0), _deg(300.0), _deg(0.0129), _deg(-159.0), _deg(159.0), 0.020)
    tilt = AxisSpec(_deg(300.0), _deg(300.0), _deg(0.0129), _deg(-31.0), _deg(47.0), 0.020)
    mount = MountGeometry(
        base=(0.0, 0.0, 1.0), pan_to_tilt=(0.0, 0.0, 0.07), tilt_to_sensor=(0.0, 0.0, 0.12)
    )
    return TurretSpec("ptu-e46", pan, tilt, mount)


_BUILDERS = {"widowx": _widowx, "ptu-e46": _ptu_e46}
TURRET_NAMES = tuple(_BUILDERS)


def make_turret(name: str) -> TurretSpec:
    """A turret preset by name: ``widowx`` or ``ptu-e46``."""
    key = name.strip().lower()
    if key not in _BUILDERS:
        raise ConfigError(f"unknown turret {name!r}; choose one of {', '.join(TURRET_NAMES)}")
    return _BUILDERS[key]()


def resolve_turret(cfg: TurretConfig) -> TurretConfig:
    """The [turret] section with its preset's values written out, so a re-run needs nothing
    else."""
    turret = turret_spec(cfg)
    deg = math.degrees
    turret_cfg = cfg.model_copy(
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
    return turret_cfg


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


@dataclass(frozen=True, slots=True)
class TargetSpec:
    """An expected target: its motor-to-motor diagonal [m] and its dynamics envelope."""

    name: str
    s_diag: float  # [m]
    v_max: float  # [m/s]
    a_max: float  # [m/s²]


TARGETS: dict[str, TargetSpec] = {
    # 350 mm diagonal (seed 000 uses 0.4 m for σ_m; the outdoor presets pin it)
    "phantom4": TargetSpec("phantom4", 0.35, v_max=20.0, a_max=15.0),
    # 92 mm motor-to-motor; seed 000's s_diag is 12 cm
    "crazyflie2": TargetSpec("crazyflie2", 0.12, v_max=2.0, a_max=2.0),
    "f550": TargetSpec("f550", 0.55, v_max=15.0, a_max=10.0),  # DJI F550, 550 mm wheelbase
    "spyder-x4": TargetSpec("spyder-x4", 0.85, v_max=20.0, a_max=10.0),  # Sky Hero Spyder X4
    # the 0.6 × 0.45 m board a walker holds up in seed 003's walks
    "sign": TargetSpec("sign", 0.6, v_max=2.0, a_max=2.0),
}


# The sensors the simulator models, by the name a scenario's [sensor] model gives them
# (``sim/sensors.py`` builds each); a model ``file:PATH`` replays a scan-pattern table.
SENSOR_MODELS = ("avia", "mid40", "mid360", "vlp16", "vlp16-side")

# The sensors' fields of view, horizontal × vertical [°], from their datasheets
# (shared/research: sensor_physics.md): the Avia's non-repetitive pattern, the Mid-40's
# circle, the Mid-360's and the VLP-16's rings.
FIELD_OF_VIEW_DEG = {
    "avia": (70.4, 77.2),
    "mid40": (38.4, 38.4),
    "mid360": (360.0, 59.0),
    "vlp16": (360.0, 30.0),
    "vlp16-side": (360.0, 30.0),
}


def narrow_field_of_view(model: str) -> tuple[float, float] | None:
    """A sensor's field of view, horizontal × vertical [rad], where it is narrower than a
    full circle (a turret turns it away from what it saw); None for the rings and for a
    model it does not know (a pattern file)."""
    fov = FIELD_OF_VIEW_DEG.get(model)
    if fov is None or fov[0] >= 360.0:
        return None
    return math.radians(fov[0]), math.radians(fov[1])


def target_spec(name: str) -> TargetSpec:
    """A target preset by name (case and surrounding spaces ignored)."""
    key = name.strip().lower()
    if key not in TARGETS:
        raise ConfigError(f"unknown drone {name!r}; choose one of {', '.join(TARGETS)}")
    return TARGETS[key]
