"""Build the pipeline's components from a validated configuration.

The algorithms take plain SI/radian keyword arguments; this is the one place
that maps configuration sections (degrees, optional values) onto them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dronetrack.config import ControllerConfig, PipelineConfig, TrackerConfig
from dronetrack.control.controller import TurretController
from dronetrack.io.background import load_background
from dronetrack.kinematics import MountGeometry
from dronetrack.pipeline import OutlierSettings, Pipeline
from dronetrack.preprocess.background import VoxelBackground
from dronetrack.track.particle import MotionModel, NoiseParameters, eq11_parameters
from dronetrack.track.tracker import ParticleTracker

__all__ = ["build_pipeline", "noise_parameters", "resolve_tracker", "scan_duration"]

_MODELS: dict[str, MotionModel] = {"pf-delta": "delta", "pf-cv": "cv", "pf-ca": "ca"}


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


def resolve_tracker(
    cfg: TrackerConfig, period: float, s_diag: float | None = None
) -> TrackerConfig:
    """The tracker section with s_diag (default ``s_diag``, the drone's) and the σ values
    of eq. (11) written out."""
    if cfg.s_diag is None:
        cfg = cfg.model_copy(update={"s_diag": DEFAULT_S_DIAG if s_diag is None else s_diag})
    n = noise_parameters(cfg, period)
    return cfg.model_copy(
        update={
            "sigma_pos": n.sigma_pos,
            "sigma_vel": n.sigma_vel,
            "sigma_acc": n.sigma_acc,
            "sigma_m": n.sigma_m,
        }
    )


def _controller(
    cfg: ControllerConfig,
    scan: PipelineConfig,
    mount: MountGeometry,
    pan_limits: tuple[float, float],
    tilt_limits: tuple[float, float],
) -> TurretController:
    bg = scan.background
    return TurretController(
        mount=mount,
        pan_limits=pan_limits,
        tilt_limits=tilt_limits,
        mode=cfg.mode,
        home=np.asarray(cfg.home_m),
        lead_s=cfg.lead_s,
        search_hold_s=cfg.search_hold_s,
        search_pan=math.radians(cfg.search_pan_deg),
        search_tilt=math.radians(cfg.search_tilt_deg),
        search_period_s=cfg.search_period_s,
        scan_pan=(math.radians(bg.scan_pan_deg[0]), math.radians(bg.scan_pan_deg[1])),
        scan_tilt=(math.radians(bg.scan_tilt_deg[0]), math.radians(bg.scan_tilt_deg[1])),
        scan_period_s=bg.scan_period_s,
    )


def build_pipeline(
    cfg: PipelineConfig,
    period: float,
    mount: MountGeometry,
    pan_limits: tuple[float, float],
    tilt_limits: tuple[float, float],
    rng: np.random.Generator,
    start: float = 0.0,
) -> Pipeline:
    """The pipeline for frames of ``period`` seconds from a turret with this mount and limits.

    The background is loaded from ``background.file`` if given, else scanned for
    ``background.scan_s`` seconds after ``start``; with the background disabled
    tracking starts at once.
    """
    tc = cfg.tracker
    tracker = ParticleTracker(
        n=tc.particles,
        model=_MODELS[tc.kind],
        noise=noise_parameters(tc, period),
        rng=rng,
        cylinder_center=np.asarray(tc.cylinder_center_m),
        cylinder_radius=tc.cylinder_radius_m,
        cylinder_height=tc.cylinder_height_m,
        resampling=tc.resampling,
        weight_floor=tc.weight_floor,
    )
    bg_cfg = cfg.background
    background: VoxelBackground | None = None
    if bg_cfg.enabled:
        if bg_cfg.file is not None:
            background = load_background(Path(bg_cfg.file).expanduser())
        elif bg_cfg.scan_s > 0:
            background = VoxelBackground(
                bg_cfg.resolution_m, bg_cfg.inflate_voxels, bg_cfg.lookup_depth, bg_cfg.min_hits
            )
    o = cfg.outliers
    outliers = OutlierSettings(
        radius=o.radius_m if o.radius_enabled else None,
        min_neighbors=o.min_neighbors,
        mean_k=o.mean_k if o.statistical_enabled else None,
        std_mul=o.std_mul,
    )
    return Pipeline(
        tracker=tracker,
        controller=_controller(cfg.controller, cfg, mount, pan_limits, tilt_limits),
        crop_min=np.asarray(cfg.crop.min_m),
        crop_max=np.asarray(cfg.crop.max_m),
        background=background,
        scan_until=start + bg_cfg.scan_s,
        outliers=outliers,
        latency_s=cfg.latency.sensor_s + cfg.latency.processing_s,
    )


def scan_duration(cfg: PipelineConfig) -> float:
    """Seconds spent scanning the background before tracking starts."""
    bg = cfg.background
    return bg.scan_s if bg.enabled and bg.file is None else 0.0
