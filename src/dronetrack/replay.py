"""Replay a recording through the pipeline (``dronetrack track``).

    recording ──frame──▶ pipeline.step ──command──▶ commands.csv (not executed)

The pipeline is the one ``simulate`` runs, built from the same configuration:
the scenario a simulated recording carries, ``--config``, or the defaults.  The
background is scanned from the first ``background.scan_s`` seconds (or
``--background-from S``) or loaded from a file.  With ground truth, each frame
is logged with it and the returns near it are counted as the target's.
"""

from __future__ import annotations

import math
import time
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.errors import ConfigError, RecordingError
from dronetrack.eval.log import TrackLog
from dronetrack.factory import build_pipeline
from dronetrack.geometry import FloatArray
from dronetrack.io.source import GroundTruth, Recording
from dronetrack.io.view import NamedTransform, ViewerSink, view_frame
from dronetrack.kinematics import pointing_angles
from dronetrack.pipeline import StepResult
from dronetrack.sim.build import turret_spec
from dronetrack.sim.drones import make_drone
from dronetrack.sim.scenario import ScenarioConfig, validate_scenario
from dronetrack.simulate import Progress, SimulationRun, log_result, resolve_run
from dronetrack.types import Frame, TurretCommand

__all__ = [
    "ReplayRun",
    "recording_config",
    "run_replay",
    "target_point_count",
    "write_commands_csv",
]

# A return within the drone's half-diagonal plus this margin of the true position
# counts as the target's (the sensor's range noise and the truth's own error).
TARGET_MARGIN_M = 0.15
# cos α is lowered by this in the cone preselection, for the sensor's rotation within
# a frame (0.05 allows 18° at the cone's edge for a distant target).
CONE_MARGIN = 0.05


@dataclass(frozen=True, slots=True)
class ReplayRun:
    """A finished replay: the run (as ``simulate`` gives it) and what was skipped."""

    run: SimulationRun
    commands: list[TurretCommand]
    skipped: dict[str, int]
    has_truth: bool

    def metrics(self) -> dict[str, Any]:
        out = self.run.metrics()
        out["skipped_messages"] = dict(self.skipped)
        out["turret_commands"] = len(self.commands)
        return out


def recording_config(
    recording: Recording,
    base: ScenarioConfig | None,
    *,
    tracker: str | None = None,
    background_file: Path | None = None,
    background_from: float | None = None,
) -> ScenarioConfig:
    """The configuration to replay with: ``base`` (``--config``), else the scenario the
    recording carries, else the defaults; then the command line's choices."""
    if base is None and recording.config_text is not None:
        try:
            data = tomllib.loads(recording.config_text)
        except tomllib.TOMLDecodeError as err:
            raise RecordingError(f"{recording.path}: the carried configuration: {err}") from None
        base = validate_scenario(data, f"{recording.path} (carried configuration)")
    cfg = base if base is not None else ScenarioConfig(name="replay")
    if background_file is not None and background_from is not None:
        raise ConfigError("give --background or --background-from, not both")
    pipeline = cfg.pipeline
    if tracker is not None:
        pipeline = pipeline.model_copy(
            update={"tracker": pipeline.tracker.model_copy(update={"kind": tracker})}
        )
    bg = pipeline.background
    if background_file is not None:
        bg = bg.model_copy(update={"enabled": True, "file": str(background_file)})
    elif background_from is not None:
        if not background_from >= 0:
            raise ConfigError(f"--background-from must be >= 0 s, got {background_from}")
        bg = bg.model_copy(
            update={"enabled": background_from > 0, "file": None, "scan_s": background_from}
        )
    pipeline = pipeline.model_copy(update={"background": bg})
    name = (
        cfg.name if recording.config_text is not None or base is not None else recording.path.stem
    )
    return cfg.model_copy(update={"pipeline": pipeline, "name": name})


def target_point_count(frame: Frame, truth: GroundTruth, radius: float) -> int:
    """Returns of the frame within ``radius`` of the true position at each return's time.

    The truth is taken as moving linearly between its values at the frame's start
    and end (exact when its samples are the frame ends, as in our recordings).
    Only returns whose range is within ``radius`` plus that motion and the
    sensor's own of the target's range can be the target's, so only those are
    moved to the world frame.
    """
    if len(frame) == 0:
        return 0
    g0, g1 = truth.at([frame.stamp, frame.end])
    end_pose = frame.poses[-1]
    origin = frame.poses[:, :3, 3]
    # | |p| − |g − o| | ≤ |p_world − g|, with slack for g's and o's motion in the frame
    slack = radius + float(np.linalg.norm(g1 - g0)) + float(np.ptp(origin, axis=0).max())
    toward = end_pose[:3, :3].T @ (g1 - end_pose[:3, 3])  # the target in the sensor frame
    reach = float(np.linalg.norm(toward))
    r = np.sqrt(np.einsum("ij,ij->i", frame.points, frame.points))
    near = np.abs(r - reach) <= slack
    if reach > slack:
        # ... and within the cone the sphere of radius ``slack`` subtends: cos θ ≥ cos α,
        # sin α = slack / reach (the sensor turns by less than α's margin in a frame).
        cos_alpha = np.sqrt(1.0 - (slack / reach) ** 2) - CONE_MARGIN
        near &= frame.points @ (toward / reach) >= r * cos_alpha
    if not near.any():
        return 0
    part = replace(
        frame,
        points=frame.points[near],
        t=frame.t[near],
        line=frame.line[near],
        intensity=frame.intensity[near],
    )
    # g(t) = g0 + u (g1 − g0),  u = (t − t_start) / duration
    u = np.clip((part.t - frame.stamp) / frame.duration, 0.0, 1.0)
    d = part.world_points() - (g0 + u[:, None] * (g1 - g0))
    return int(np.count_nonzero(np.einsum("ij,ij->i", d, d) <= radius * radius))


def run_replay(
    recording: Recording,
    cfg: ScenarioConfig,
    progress: Progress | None = None,
    viewers: Sequence[ViewerSink] = (),
) -> ReplayRun:
    """Replay every frame of ``recording`` through the pipeline ``cfg`` describes.

    The filter draws from the same seed as ``simulate`` of ``cfg``, so a recording
    of a simulated run replays as that run did.
    """
    cfg = resolve_run(cfg)
    period = recording.period
    spec = turret_spec(cfg.turret)
    _, filter_seed = np.random.SeedSequence(cfg.seed).spawn(2)
    pipeline = build_pipeline(
        cfg.pipeline,
        period,
        spec.mount,
        (spec.pan.lower, spec.pan.upper),
        (spec.tilt.lower, spec.tilt.upper),
        np.random.default_rng(filter_seed),
    )
    truth = recording.ground_truth
    radius = 0.5 * make_drone(cfg.drone.model).s_diag + TARGET_MARGIN_M
    log = TrackLog()
    commands: list[TurretCommand] = []
    total = int(getattr(recording, "n_frames", 0))
    start = time.perf_counter()
    n = 0
    first = last = math.nan
    for frame in recording.frames():
        result = pipeline.step(frame)
        n += 1
        first = frame.stamp if n == 1 else first
        last = frame.end
        if result.command is not None:
            commands.append(result.command)
        gt = truth.at(frame.end)[0] if truth is not None else None
        if result.phase == "track":
            _record(log, frame, result, gt, truth, radius)
        if viewers:
            view = view_frame(
                frame, result, gt, [NamedTransform("world", "lidar", frame.poses[-1])]
            )
            for sink in viewers:
                sink.log(view)
        if progress is not None:
            progress(n, max(total, n))
    if n == 0:
        raise RecordingError(f"{recording.path}: no LiDAR frame could be read")
    wall = time.perf_counter() - start
    run = SimulationRun(cfg, log, pipeline, wall, last - first)
    return ReplayRun(run, commands, dict(recording.skipped), truth is not None)


def _record(
    log: TrackLog,
    frame: Frame,
    result: StepResult,
    gt: FloatArray | None,
    truth: GroundTruth | None,
    radius: float,
) -> None:
    known = truth is not None and gt is not None and bool(np.all(np.isfinite(gt)))
    n_target = target_point_count(frame, truth, radius) if known and truth is not None else -1
    pan, tilt = pointing_angles(frame.poses[-1])
    log_result(log, frame, result, gt, n_target, float(pan), float(tilt))


def write_commands_csv(commands: Sequence[TurretCommand], path: Path) -> None:
    """The turret commands the pipeline issued (logged, not executed): t, mode, pan, tilt."""
    with path.open("w") as fh:
        fh.write("t,mode,pan_rad,tilt_rad\n")
        for c in commands:
            fh.write(f"{c.stamp:.6f},{c.mode},{c.pan:.6f},{c.tilt:.6f}\n")
