"""Pipeline steps and tracker steps, timed.

- ``pipeline_step_ms``: one full pipeline step (world transform with per-point
  poses, crop, background lookup of every point, particle-filter predict, update
  and resample) on a 24,000-point Avia frame, at each of ``PF_PARTICLES``.  The
  Avia is tilted 40° down at open ground, so every pulse returns, and the crop box
  keeps the ground, so every point is looked up in the background (the worst
  case); a Phantom 4 hovers 2.5 m ahead and is tracked.  ``worst_case_frames``
  makes the frames.
- ``tracker_step_ms``: ``Tracker.step(t, points, steps=1)`` of one tracker of
  ``TRACKER_NAMES`` (factory defaults: 5,000 particles, pf-systematic 2,000) on a
  synthetic foreground (``tracker_foreground``): 100 points (σ = 0.1 m) around a
  target 20 m ahead moving at a constant 0.5 m/s, one 0.1 s period per step, after
  ``TRACKER_WARMUP`` untimed steps that lock every filter.

The tracker step isolates the filter's cost; the pipeline step adds everything
that runs around it on a real frame.  Both raise RuntimeError if the workload is
not what it claims (the target not tracked), so a fast figure is never the figure
of a filter that gave up.  The replay workload (``replay``) reuses this module's
hovering drone, background scan and pipeline configuration.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from dronetrack.config.pipeline import BackgroundConfig, CropConfig, PipelineConfig, TrackerConfig
from dronetrack.geometry.transforms import FloatArray
from dronetrack.pipeline import Pipeline
from dronetrack.pipeline.factory import build_pipeline
from dronetrack.pipeline.trackers import build_tracker
from dronetrack.types import Frame

if TYPE_CHECKING:
    from dronetrack.sim.trajectories import Trajectory
    from dronetrack.sim.world import SimWorld

__all__ = [
    "HOVER_M",
    "PERIOD_S",
    "PF_PARTICLES",
    "SCAN_S",
    "AviaFrames",
    "ground_facing_avia",
    "pipeline_config",
    "pipeline_step_ms",
    "scanned_pipeline",
    "shifted",
    "tracker_foreground",
    "tracker_step_ms",
    "worst_case_frames",
]

# Seed 000's Table I particle counts, plus 100,000.
PF_PARTICLES: tuple[int, ...] = (1000, 4000, 5000, 10_000, 100_000)
PERIOD_S = 0.1  # every workload runs at 10 Hz
# untimed pipeline steps after the background scan: the frame's ten clusters of unmapped
# ground are classed static (1 s still, 0.5 s held) and the tracker settles on the drone
PIPELINE_WARMUP = 30
TRACKER_WARMUP = 10  # untimed tracker steps: every filter is locked after them
# where the pipeline and replay workloads' drone hovers: 0.9 m up, its bottom 0.75 m
# over the ground (lower, it would stand on the ground to the classes, ``classify``),
# just inside the top of the ground-facing Avia's view
HOVER_M = (2.5, 0.0, 0.9)
SCAN_S = 1.0  # background scan of the pipeline and replay workloads


# --- the pipeline step -----------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class AviaFrames:
    """The pipeline workload: background-scan frames, then the frame that is timed."""

    scan: list[Frame]
    probe: Frame


def ground_facing_avia(trajectory: Trajectory, t0: float = 0.0) -> SimWorld:
    """An Avia on a WidowX tilted 40° down at open ground, so every pulse returns
    (24,000 points a frame), with a Phantom 4 flying ``trajectory``."""
    from dronetrack.config.rig import make_turret
    from dronetrack.sim.drones import make_drone
    from dronetrack.sim.scene import make_scene
    from dronetrack.sim.sensors import make_sensor
    from dronetrack.sim.world import SimWorld

    turret = make_turret("widowx")
    return SimWorld(
        make_sensor("avia"),
        make_scene("empty"),
        make_drone("phantom4"),
        trajectory,
        turret,
        turret.mount,
        0.0,
        np.random.default_rng(0),
        pan=0.0,
        tilt=math.radians(40.0),
        t0=t0,
    )


def _avia_frames(target: tuple[float, float, float], n: int, t0: float = 0.0) -> list[Frame]:
    """Frames of the ground-facing Avia with the drone hovering at ``target``."""
    from dronetrack.sim.trajectories import fly_waypoints

    world = ground_facing_avia(fly_waypoints(target, []), t0)
    return [world.step()[0] for _ in range(n)]


def worst_case_frames() -> AviaFrames:
    """A 1 s background scan with the drone far out of view, then a 24,000-point frame
    with the drone hovering 2.5 m ahead."""
    scan = _avia_frames((-100.0, 0.0, 50.0), round(SCAN_S / PERIOD_S))
    probe = _avia_frames(HOVER_M, 1, t0=SCAN_S)[0]
    return AviaFrames(scan, probe)


def shifted(frame: Frame, dt: float) -> Frame:
    """``frame`` ``dt`` [s] later: its stamp, its returns' times and its poses' times."""
    return replace(frame, stamp=frame.stamp + dt, t=frame.t + dt, pose_t=frame.pose_t + dt)


def pipeline_config(particles: int) -> PipelineConfig:
    """A crop box that keeps the ground, 0.2 m voxels looked up one by one, and a start
    cylinder around the hovering drone."""
    return PipelineConfig(
        crop=CropConfig(min_m=(-200.0, -200.0, -5.0), max_m=(300.0, 200.0, 100.0)),
        background=BackgroundConfig(resolution_m=0.2, lookup_depth=0, scan_s=SCAN_S),
        tracker=TrackerConfig(
            particles=particles,
            cylinder_center_m=(HOVER_M[0], HOVER_M[1], 0.0),
            cylinder_radius_m=2.0,
            cylinder_height_m=2.0,
        ),
    )


def scanned_pipeline(particles: int, frames: AviaFrames) -> Pipeline:
    """The benchmark's pipeline (``pipeline_config``) on the WidowX, after the background
    scan of ``frames``; RuntimeError if the scan did not end."""
    from dronetrack.config.rig import make_turret

    turret = make_turret("widowx")
    pipe = build_pipeline(
        pipeline_config(particles),
        PERIOD_S,
        turret.mount,
        (turret.pan.lower, turret.pan.upper),
        (turret.tilt.lower, turret.tilt.upper),
        np.random.default_rng(1),
    )
    for frame in frames.scan:
        pipe.step(frame)
    if pipe.scanning:
        raise RuntimeError("the pipeline benchmark's background scan did not end")
    return pipe


def pipeline_step_ms(particles: int, repeats: int, frames: AviaFrames | None = None) -> FloatArray:
    """Wall time [ms] of ``repeats`` pipeline steps on 24,000-point frames.

    After the background scan and ``PIPELINE_WARMUP`` untimed steps; each step gets
    the probe frame one filter period after the previous one.  Raises RuntimeError
    if the workload is not what it claims (no foreground, the drone not tracked).
    """
    frames = worst_case_frames() if frames is None else frames
    pipe = scanned_pipeline(particles, frames)
    out = np.empty(repeats)
    for k in range(repeats + PIPELINE_WARMUP):
        frame = shifted(frames.probe, PERIOD_S * k)
        start = time.perf_counter()
        result = pipe.step(frame)
        if k >= PIPELINE_WARMUP:
            out[k - PIPELINE_WARMUP] = 1e3 * (time.perf_counter() - start)
    if result.n_points == 0 or result.estimate is None or not result.estimate.tracked:
        raise RuntimeError(f"the pipeline benchmark lost its target at {particles} particles")
    return out


# --- tracker steps ---------------------------------------------------------------------


def tracker_foreground(steps: int, seed: int = 7) -> list[FloatArray]:
    """``steps`` foregrounds of 100 points (σ = 0.1 m) around a target that starts at
    (20, 0, 5) m and moves at (0.4, 0.3, 0) m/s, one every ``PERIOD_S``."""
    rng = np.random.default_rng(seed)
    cloud = rng.normal(0.0, 0.1, size=(100, 3))
    start, velocity = np.array([20.0, 0.0, 5.0]), np.array([0.4, 0.3, 0.0])
    return [cloud + start + velocity * (PERIOD_S * k) for k in range(steps)]


def tracker_step_ms(kind: str, repeats: int, warmup: int = TRACKER_WARMUP) -> FloatArray:
    """Wall time [ms] of ``repeats`` calls of ``Tracker.step(t, points, steps=1)`` of the
    tracker ``kind`` (factory defaults) on ``tracker_foreground``, after ``warmup``
    untimed ones.  Raises RuntimeError if the filter is not locked on the target."""
    cfg = TrackerConfig.model_validate({"kind": kind})
    tracker = build_tracker(cfg, PERIOD_S, np.random.default_rng(3))
    clouds = tracker_foreground(warmup + repeats)
    out = np.empty(repeats)
    for k, points in enumerate(clouds):
        start = time.perf_counter()
        estimate = tracker.step(PERIOD_S * k, points, 1)
        if k >= warmup:
            out[k - warmup] = 1e3 * (time.perf_counter() - start)
        if k + 1 == warmup and not estimate.tracked:
            raise RuntimeError(f"{kind} is not tracking after {warmup} warm-up steps")
    if not estimate.tracked or np.linalg.norm(estimate.position - clouds[-1].mean(axis=0)) > 1.0:
        raise RuntimeError(f"{kind} lost the benchmark's target")
    return out
