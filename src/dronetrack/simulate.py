"""The main job: a closed-loop run of seed 000's system on the simulator.

    simulator ──frame──▶ pipeline.step ──command──▶ simulated turret

The run starts as on a real site: the turret scans the background while the
target waits on the ground, then the target flies and the pipeline tracks it.
Frames of the tracking phase are logged with their ground truth.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.eval.log import TrackLog
from dronetrack.factory import build_pipeline, noise_parameters, resolve_tracker, scan_duration
from dronetrack.io.background import read_background_settings
from dronetrack.pipeline import Pipeline, StepResult
from dronetrack.sim.drones import make_drone
from dronetrack.sim.scenario import ScenarioConfig, build_world, dump_scenario, resolve_scenario
from dronetrack.sim.world import FrameTruth, SimWorld
from dronetrack.types import Frame

__all__ = ["SimulationRun", "resolve_run", "run_simulation", "write_run"]

Progress = Callable[[int, int], None]


def resolve_run(cfg: ScenarioConfig) -> ScenarioConfig:
    """The configuration with every derived value written out: sensor, turret, the
    drone's diagonal and the σ values of eq. (11), and a background file's own settings
    and absolute path."""
    cfg = resolve_scenario(cfg)
    pipeline = cfg.pipeline
    drone = make_drone(cfg.drone.model)
    tracker = resolve_tracker(pipeline.tracker, cfg.sensor.integration_time_s, drone.s_diag)
    background = pipeline.background
    if background.file is not None:
        path = Path(background.file).expanduser().resolve()
        stored = read_background_settings(path)
        background = background.model_copy(
            update={
                "file": str(path),
                "resolution_m": stored.resolution,
                "inflate_voxels": stored.inflate,
                "lookup_depth": stored.lookup_depth,
                "min_hits": stored.min_hits,
            }
        )
    pipeline = pipeline.model_copy(update={"tracker": tracker, "background": background})
    return cfg.model_copy(update={"pipeline": pipeline})


@dataclass(frozen=True, slots=True)
class SimulationRun:
    """A finished closed-loop run."""

    config: ScenarioConfig  # resolved
    log: TrackLog
    pipeline: Pipeline
    wall_s: float
    simulated_s: float

    @property
    def realtime_factor(self) -> float:
        return self.simulated_s / self.wall_s if self.wall_s > 0 else math.inf

    def metrics(self) -> dict[str, Any]:
        out = self.log.summary(self.config.pipeline.evaluation.correct_radius_m)
        out["realtime_factor"] = self.realtime_factor
        out["wall_s"] = self.wall_s
        return out


def run_simulation(cfg: ScenarioConfig, progress: Progress | None = None) -> SimulationRun:
    """Run the scenario closed-loop; ``cfg`` is resolved first (see ``resolve_run``)."""
    cfg = resolve_run(cfg)
    scan_s = scan_duration(cfg.pipeline)
    # The flight starts after the background scan: the target waits on the ground.
    flight = cfg.model_copy(
        update={
            "trajectory": cfg.trajectory.model_copy(
                update={"hold_s": cfg.trajectory.hold_s + scan_s}
            )
        }
    )
    sim_seed, filter_seed = np.random.SeedSequence(cfg.seed).spawn(2)
    world = build_world(flight, np.random.default_rng(sim_seed))
    turret = world.plant.spec
    period = cfg.sensor.integration_time_s
    pipeline = build_pipeline(
        cfg.pipeline,
        period,
        world.mount,
        (turret.pan.lower, turret.pan.upper),
        (turret.tilt.lower, turret.tilt.upper),
        np.random.default_rng(filter_seed),
    )
    start_cmd = pipeline.controller.scanning(0.0) if pipeline.scanning else None
    if start_cmd is not None:
        world.place_turret(start_cmd.pan, start_cmd.tilt)
    elif cfg.pipeline.controller.mode == "fixed":
        world.place_turret(*pipeline.controller.home)
    n_frames = max(1, math.ceil((scan_s + cfg.duration_s) / period - 1e-9))
    log = TrackLog()
    begin = time.perf_counter()
    for i in range(n_frames):
        frame, truth = world.step()
        result = pipeline.step(frame)
        if result.command is not None:
            world.command(result.command)
        if result.phase == "track":
            _record(log, world, frame, truth, result)
        if progress is not None:
            progress(i + 1, n_frames)
    wall = time.perf_counter() - begin
    return SimulationRun(cfg, log, pipeline, wall, n_frames * period)


def _record(
    log: TrackLog, world: SimWorld, frame: Frame, truth: FrameTruth, result: StepResult
) -> None:
    est = result.estimate
    assert est is not None
    sensor = frame.poses[-1, :3, 3]
    log.append(
        t=frame.end,
        gt=truth.target_position,
        est=est.position,
        tracked=est.tracked,
        sigma=est.spread,
        n_points=result.n_points,
        n_target_points=truth.n_target_points,
        range_m=float(np.linalg.norm(truth.target_position - sensor)),
        pan=truth.turret.pan,
        tilt=truth.turret.tilt,
        step_ms=result.step_ms,
        flags=result.flags,
    )


def write_run(run: SimulationRun, out_dir: Path) -> dict[str, Any]:
    """Write config.toml, frames.csv, metrics.json, the plots and the scanned background
    (``background.npz``, to load with ``[pipeline.background] file``); return the metrics."""
    from dronetrack.io.background import save_background
    from dronetrack.io.runs import write_frames_csv, write_metrics, write_plots

    out_dir.mkdir(parents=True, exist_ok=True)
    background = run.pipeline.background
    if background is not None and background.ready and run.config.pipeline.background.file is None:
        save_background(background, out_dir / "background.npz")
    (out_dir / "config.toml").write_text(dump_scenario(run.config))
    write_frames_csv(run.log, out_dir / "frames.csv")
    metrics = run.metrics()
    write_metrics(metrics, out_dir / "metrics.json")
    noise = noise_parameters(run.config.pipeline.tracker, run.config.sensor.integration_time_s)
    threshold = noise.threshold
    radius = run.config.pipeline.evaluation.correct_radius_m
    write_plots(run.log, out_dir, threshold, run.config.name, radius)
    return metrics
