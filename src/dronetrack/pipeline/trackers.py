"""The trackers' registry: ``TRACKERS`` maps each tracker kind to the builder of its
filter (its keys exactly ``config.pipeline.TrackerKind``), with the defaults the seed
methods take when the configuration leaves a value out (eq. (11)'s σ values, the
particle counts, seed 000's s_diag)."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import replace
from functools import partial
from typing import Any, Literal, get_args

import numpy as np

from dronetrack.config.pipeline import TrackerConfig, TrackerKind
from dronetrack.detect.candidates import SEED002_DETECTOR, SEED003_DETECTOR, CandidateDetector
from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.track.base import Tracker
from dronetrack.track.cluster_kalman import AdaptiveEKF, CentroidEKF, ConstantAccelerationKF
from dronetrack.track.particle import (
    MotionModel,
    NoiseParameters,
    ParticleTracker,
    eq11_parameters,
)
from dronetrack.track.sphere_kalman import CatalanoEKF, DogruEKF

__all__ = [
    "CA_SIGMA_ACC",
    "DEFAULT_PARTICLES",
    "DEFAULT_S_DIAG",
    "SEED002_PF_PARTICLES",
    "TRACKERS",
    "TRACKER_NAMES",
    "TrackerBuilder",
    "build_tracker",
    "check_registry",
    "noise_parameters",
    "particle_count",
    "resolve_tracker",
]


TRACKER_NAMES: tuple[str, ...] = get_args(TrackerKind)
# Seed 002's particle-filter baseline: 2,000 particles, systematic resampling.  The
# paper names no motion model; constant velocity, as a random-walk acceleration
# extrapolates without bound through the long gaps of its flight.
SEED002_PF_PARTICLES = 2000
DEFAULT_PARTICLES = 5000  # mav_track_outside.yaml


# Eq. (11) sets σ_acc = 0, which makes the constant-acceleration model the
# constant-velocity one; pf-ca defaults to the reference's 0.1 m/s² instead
# (mav_track_outside_behind_hedges.yaml, its one constant-acceleration setup).
CA_SIGMA_ACC = 0.1
DEFAULT_S_DIAG = 0.4  # seed 000's Phantom 4 value, when neither the config nor a drone gives one


def noise_parameters(cfg: TrackerConfig, period: float) -> NoiseParameters:
    """The filter's σ values: those given, the rest from eq. (11)."""
    s_diag = DEFAULT_S_DIAG if cfg.s_diag is None else cfg.s_diag
    derived = eq11_parameters(cfg.v_max, cfg.a_max, s_diag, period)
    default_acc = CA_SIGMA_ACC if cfg.kind == "pf-ca" else derived.sigma_acc
    return NoiseParameters(
        sigma_pos=derived.sigma_pos if cfg.sigma_pos is None else cfg.sigma_pos,
        sigma_vel=derived.sigma_vel if cfg.sigma_vel is None else cfg.sigma_vel,
        sigma_acc=default_acc if cfg.sigma_acc is None else cfg.sigma_acc,
        sigma_m=derived.sigma_m if cfg.sigma_m is None else cfg.sigma_m,
        period=period,
    )


def particle_count(cfg: TrackerConfig) -> int:
    """The configured particle count, or the method's default."""
    if cfg.particles is not None:
        return cfg.particles
    return SEED002_PF_PARTICLES if cfg.kind == "pf-systematic" else DEFAULT_PARTICLES


def resolve_tracker(
    cfg: TrackerConfig, period: float, s_diag: float | None = None
) -> TrackerConfig:
    """The tracker section with the particle count, resampling, s_diag (default
    ``s_diag``, the drone's) and the σ values of eq. (11) written out."""
    if cfg.s_diag is None:
        cfg = cfg.model_copy(update={"s_diag": DEFAULT_S_DIAG if s_diag is None else s_diag})
    n = noise_parameters(cfg, period)
    return cfg.model_copy(
        update={
            "particles": particle_count(cfg),
            "resampling": "systematic" if cfg.kind == "pf-systematic" else cfg.resampling,
            "sigma_pos": n.sigma_pos,
            "sigma_vel": n.sigma_vel,
            "sigma_acc": n.sigma_acc,
            "sigma_m": n.sigma_m,
        }
    )


def _kwargs(**values: Any) -> dict[str, Any]:
    """The keyword arguments that were given (None: the tracker's own default)."""
    return {k: v for k, v in values.items() if v is not None}


def _detector(cfg: TrackerConfig, base: CandidateDetector, home: FloatArray) -> CandidateDetector:
    d = cfg.detector
    z = d.roi_z_m
    return replace(
        base,
        **_kwargs(
            voxel_size=d.voxel_m,
            eps=d.eps_m,
            min_points=d.min_points,
            max_extent=d.max_extent_m,
            roi_radius=d.roi_radius_m,
            roi_center_xy=(float(home[0]), float(home[1])) if d.roi_radius_m else None,
            z_min=z[0] if z else None,
            z_max=z[1] if z else None,
        ),
    )


# (cfg, period T [s], random generator, home: the turret base (3,) world [m])
TrackerBuilder = Callable[[TrackerConfig, float, np.random.Generator, FloatArray], Tracker]


def _particle_filter(
    model: MotionModel,
    resampling: Literal["multinomial", "systematic"] | None,
    cfg: TrackerConfig,
    period: float,
    rng: np.random.Generator,
    home: FloatArray,
) -> Tracker:
    """Seed 000's particle filter with ``model``; ``resampling`` None: the config's."""
    return ParticleTracker(
        n=particle_count(cfg),
        model=model,
        noise=noise_parameters(cfg, period),
        rng=rng,
        cylinder_center=np.asarray(cfg.cylinder_center_m),
        cylinder_radius=cfg.cylinder_radius_m,
        cylinder_height=cfg.cylinder_height_m,
        resampling=cfg.resampling if resampling is None else resampling,
        weight_floor=cfg.weight_floor,
        birth_share=cfg.birth_share,
    )


def _dogru(
    cfg: TrackerConfig, period: float, rng: np.random.Generator, home: FloatArray
) -> Tracker:
    k = cfg.kalman
    return DogruEKF(
        period=period,
        home=home,
        **_kwargs(
            sigma_acc=k.sigma_acc,
            sigma_lidar=k.sigma_lidar,
            min_search_radius=k.search_radius_m,
            tracked_threshold=k.tracked_variance_m2,
        ),
    )


def _catalano(
    radius: float, cfg: TrackerConfig, period: float, rng: np.random.Generator, home: FloatArray
) -> Tracker:
    """Catalano et al.'s EKF with the fixed search ``radius`` [m] unless the config gives one."""
    k = cfg.kalman
    return CatalanoEKF(
        period=period,
        home=home,
        **_kwargs(
            search_radius=k.search_radius_m or radius,
            sigma_acc=k.sigma_acc,
            sigma_lidar=k.sigma_lidar,
            tracked_threshold=k.tracked_variance_m2,
        ),
    )


def _centroid_ekf(
    cfg: TrackerConfig, period: float, rng: np.random.Generator, home: FloatArray
) -> Tracker:
    return CentroidEKF(
        period=period,
        home=home,
        detector=_detector(cfg, SEED003_DETECTOR, home),
        **_kwargs(lost_after_s=cfg.kalman.lost_after_s),
    )


def _ca_kalman(
    adaptive: bool, cfg: TrackerConfig, period: float, rng: np.random.Generator, home: FloatArray
) -> Tracker:
    """Seed 002's constant-acceleration filter: adaptive (AEKF) or with fixed Q and R."""
    k = cfg.kalman
    cls = AdaptiveEKF if adaptive else ConstantAccelerationKF
    extra = _kwargs(alpha=k.alpha, beta=k.beta) if adaptive else {}
    return cls(
        period=period,
        home=home,
        detector=_detector(cfg, SEED002_DETECTOR, home),
        **_kwargs(
            sigma_acc=k.sigma_acc, sigma_lidar=k.sigma_lidar, gate=k.gate, t_occ=k.lost_after_s
        ),
        **extra,
    )


TRACKERS: dict[TrackerKind, TrackerBuilder] = {
    "pf-delta": partial(_particle_filter, "delta", None),
    "pf-cv": partial(_particle_filter, "cv", None),
    "pf-ca": partial(_particle_filter, "ca", None),
    # Seed 002's baseline: constant velocity (see SEED002_PF_PARTICLES), systematic resampling.
    "pf-systematic": partial(_particle_filter, "cv", "systematic"),
    "ekf-dogru": _dogru,
    # Seed 000's fixed search radii for Catalano et al.'s EKF: theirs, and 1.5 m ("mod.").
    "ekf-catalano": partial(_catalano, 0.2),
    "ekf-catalano-mod": partial(_catalano, 1.5),
    "ekf-cv": _centroid_ekf,
    "kf-ca": partial(_ca_kalman, False),
    "aekf-ca": partial(_ca_kalman, True),
}


def check_registry(what: str, registry: Iterable[str], names: tuple[str, ...]) -> None:
    """A registry's keys are exactly the names of its ``Literal``, in the same order."""
    if tuple(registry) != names:
        raise ConfigError(
            f"the {what} registry lists {', '.join(registry)}; the names are {', '.join(names)}"
        )


check_registry("tracker", TRACKERS, TRACKER_NAMES)


def build_tracker(
    cfg: TrackerConfig,
    period: float,
    rng: np.random.Generator,
    home: FloatArray | None = None,
) -> Tracker:
    """The tracker ``cfg.kind`` names; ``home`` (the turret base) is where a Kalman
    filter reports itself before its first fix, and the centre of a detector's ROI."""
    base = np.zeros(3) if home is None else np.asarray(home, dtype=np.float64)
    return TRACKERS[cfg.kind](cfg, period, rng, base)
