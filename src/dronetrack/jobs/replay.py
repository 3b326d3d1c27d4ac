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
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numba as nb
import numpy as np

from dronetrack.config.run import ScenarioConfig, validate_scenario
from dronetrack.errors import ConfigError, RecordingError
from dronetrack.eval.log import TrackLog
from dronetrack.geometry.mount import pointing_angles
from dronetrack.geometry.transforms import FloatArray
from dronetrack.interrupt import stop_requested, stoppable
from dronetrack.jobs.factory import scan_duration
from dronetrack.jobs.kernels import REPLAY_WARM_UPS, CompileProgress, warm_up
from dronetrack.jobs.simulate import (
    LogSink,
    Progress,
    SimulationRun,
    log_result,
    resolve_run,
    run_seeds,
    turret_pipeline,
)
from dronetrack.pipeline import StepResult
from dronetrack.sim.build import turret_spec
from dronetrack.sim.drones import make_drone
from dronetrack.sinks.view import NamedTransform, ViewerSink, view_frame
from dronetrack.sources.recording import GroundTruth, Recording
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


@dataclass(frozen=True, slots=True)
class ReplayRun:
    """A finished replay: the run (as ``simulate`` gives it) and what was skipped."""

    run: SimulationRun
    commands: list[TurretCommand]
    skipped: dict[str, int]
    has_truth: bool
    warnings: tuple[str, ...] = ()  # what the replay had to assume (say, the sensor pose)

    def metrics(self) -> dict[str, Any]:
        out = self.run.metrics()
        out["skipped_messages"] = dict(self.skipped)
        out["turret_commands"] = len(self.commands)
        if self.warnings:
            out["warnings"] = list(self.warnings)
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


def target_point_count(frame: Frame, world: FloatArray, truth: GroundTruth, radius: float) -> int:
    """Returns of the frame within ``radius`` of the true position at each return's time;
    ``world`` (N, 3) are the frame's points in the world frame.

    The truth is taken as moving linearly between its values at the frame's start
    and end (exact when its samples are the frame ends, as in our recordings).
    """
    if len(frame) == 0:
        return 0
    g0, g1 = truth.at([frame.stamp, frame.end])
    return int(_count_near(world, frame.t, frame.stamp, frame.duration, g0, g1, radius))


@nb.njit(cache=True)
def _count_near(
    W: FloatArray, t: FloatArray, t0: float, T: float, g0: FloatArray, g1: FloatArray, r: float
) -> int:
    """Points of W (N, 3) within r of g(t_i) = g0 + u_i (g1 − g0), u_i = (t_i − t0) / T ∈ [0, 1]."""
    n = 0
    r2 = r * r
    for i in range(W.shape[0]):
        u = min(max((t[i] - t0) / T, 0.0), 1.0)
        d2 = 0.0
        for k in range(3):
            d = W[i, k] - (g0[k] + u * (g1[k] - g0[k]))
            d2 += d * d
        if d2 <= r2:
            n += 1
    return n


def run_replay(
    recording: Recording,
    cfg: ScenarioConfig,
    progress: Progress | None = None,
    viewers: Sequence[ViewerSink] = (),
    compiling: CompileProgress | None = None,
    log_sink: LogSink | None = None,
) -> ReplayRun:
    """Replay every frame of ``recording`` through the pipeline ``cfg`` describes.

    The filter draws from the same seed as ``simulate`` of ``cfg``, so a recording
    of a simulated run replays as that run did.  The numba kernels are compiled (or
    loaded from the cache) before the clock starts; ``compiling`` follows that.
    ``log_sink`` gets the log after each tracking frame.  A Ctrl-C handled by
    ``dronetrack.interrupt`` ends the replay after the frame in hand.
    """
    period = recording.period
    if not 1e-3 <= period <= 1.0:
        raise RecordingError(
            f"{recording.path}: frame period {period:g} s is outside 1 ms to 1 s; give --period"
        )
    # The filter's period (and eq. (11)'s σ values) follow the recording's frame rate.
    sensor = cfg.sensor.model_copy(update={"integration_time_s": period})
    cfg = resolve_run(cfg.model_copy(update={"sensor": sensor}))
    _, filter_seed = run_seeds(cfg.seed)
    pipeline = turret_pipeline(
        cfg, period, turret_spec(cfg.turret), np.random.default_rng(filter_seed)
    )
    truth = recording.ground_truth
    radius = 0.5 * make_drone(cfg.drone.model).s_diag + TARGET_MARGIN_M
    log = TrackLog()
    commands: list[TurretCommand] = []
    total = int(getattr(recording, "n_frames", 0))
    kernels = warm_up(REPLAY_WARM_UPS, compiling)
    start = time.perf_counter()
    n = 0
    first = last = math.nan
    with stoppable():
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
                if log_sink is not None:
                    log_sink(log)
            if viewers:
                view = view_frame(
                    frame, result, gt, [NamedTransform("world", "lidar", frame.poses[-1])]
                )
                for sink in viewers:
                    sink.log(view)
            if progress is not None:
                progress(n, max(total, n))
            if stop_requested():
                break
    interrupted = stop_requested()
    if n == 0:
        raise RecordingError(f"{recording.path}: no LiDAR frame could be read")
    if len(log) == 0 and not interrupted:
        scan_s = scan_duration(cfg.pipeline)
        raise RecordingError(
            f"{recording.path}: the recording lasts {last - first:.3g} s ({n} frames), no "
            f"longer than the background scan of {scan_s:g} s, so no frame was left to track; "
            "give a shorter --background-from, or --background FILE"
        )
    wall = time.perf_counter() - start
    run = SimulationRun(cfg, log, pipeline, wall, last - first, kernels, interrupted)
    warnings = (recording.pose_warning,) if recording.pose_warning else ()
    return ReplayRun(run, commands, dict(recording.skipped), truth is not None, warnings)


def _record(
    log: TrackLog,
    frame: Frame,
    result: StepResult,
    gt: FloatArray | None,
    truth: GroundTruth | None,
    radius: float,
) -> None:
    n_target = -1  # unknown: no truth, or the frame could not be placed in the world
    known = gt is not None and bool(np.all(np.isfinite(gt)))
    if truth is not None and known and len(result.world) == len(frame):
        n_target = target_point_count(frame, result.world, truth, radius)
    pan, tilt = pointing_angles(frame.poses[-1])
    log_result(log, frame, result, gt, n_target, float(pan), float(tilt))


def write_commands_csv(commands: Sequence[TurretCommand], path: Path) -> None:
    """The turret commands the pipeline issued (logged, not executed): t, mode, pan, tilt."""
    with path.open("w") as fh:
        fh.write("t,mode,pan_rad,tilt_rad\n")
        for c in commands:
            fh.write(f"{c.stamp:.6f},{c.mode},{c.pan:.6f},{c.tilt:.6f}\n")
