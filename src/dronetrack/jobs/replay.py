"""Replay a recording through the pipeline (``dronetrack track``).

    recording ──frame──▶ pipeline.step ──command──▶ commands.csv (not executed)

The pipeline is the one ``simulate`` runs, built from the same configuration:
the scenario a simulated recording carries, ``--config``, or the defaults.  The
background is scanned from the first ``background.scan_s`` seconds (or
``--background-from S``) or loaded from a file.  With ground truth, each frame
is logged with it and the returns near it are counted as the target's.
"""

from __future__ import annotations

import tomllib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.actuators.command_log import CommandLog
from dronetrack.config.rig import resolve_turret, target_spec, turret_spec
from dronetrack.config.run import ScenarioConfig, validate_scenario
from dronetrack.errors import ConfigError, RecordingError
from dronetrack.eval.log import TrackLog
from dronetrack.jobs.lidar_model import adopt_lidar, recording_lidar
from dronetrack.jobs.run import RunResult, resolve_pipeline, run_seeds, turret_pipeline
from dronetrack.pipeline import run
from dronetrack.pipeline.factory import scan_duration
from dronetrack.pipeline.kernels import CompileProgress, warm_up
from dronetrack.seams import Sink
from dronetrack.sinks.track_log import TrackLogSink
from dronetrack.sinks.view import ViewerFeed, ViewerSink
from dronetrack.sources.recordings.kernels import REPLAY_WARM_UPS
from dronetrack.sources.recordings.playback import RecordingSource
from dronetrack.sources.recordings.recording import (
    Recording,
    ReplayOptions,
    truth_overlap_warning,
)
from dronetrack.types import TurretCommand

Progress = Callable[[int, int], None]
LogSink = Callable[[TrackLog], None]

__all__ = ["ReplayRun", "open_replay", "recording_config", "run_replay"]

# A return within the drone's half-diagonal plus this margin of the true position
# counts as the target's (the sensor's range noise and the truth's own error).
TARGET_MARGIN_M = 0.15


@dataclass(frozen=True, slots=True)
class ReplayRun:
    """A finished replay: the run (as ``simulate`` gives it) and what was skipped."""

    run: RunResult
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


def open_replay(
    path: Path,
    options: ReplayOptions,
    *,
    truth: Path | None = None,
    config: Path | None = None,
    tracker: str | None = None,
    background_file: Path | None = None,
    background_from: float | None = None,
) -> tuple[Recording, ScenarioConfig, str | None]:
    """``dronetrack track``'s recording (with the truth file's track, if given), the
    configuration to replay it with (``recording_config``, from ``config`` if given) set
    to the recording's LiDAR, and a warning if that LiDAR differs from the config's."""
    from dronetrack.config.run import load_scenario_file
    from dronetrack.config.scenarios import SCENARIOS
    from dronetrack.jobs.site import site_frame
    from dronetrack.sources.recordings.opener import open_recording
    from dronetrack.sources.truth_csv import read_truth_csv

    base = load_scenario_file(config, SCENARIOS) if config is not None else None
    if base is not None and base.site is not None and options.gt_origin is None:
        # GNSS truth in the site's world frame, as the tracks' WGS-84 columns are
        options = replace(options, gt_site=site_frame(base))
    source = open_recording(path, options)
    if truth is not None:
        source.ground_truth = read_truth_csv(truth)
    cfg = recording_config(
        source,
        base,
        tracker=tracker,
        background_file=background_file,
        background_from=background_from,
    )
    cfg, warning = adopt_lidar(cfg, recording_lidar(source), path.name)
    return source, cfg, warning


def recording_config(
    recording: Recording,
    base: ScenarioConfig | None,
    *,
    tracker: str | None = None,
    background_file: Path | None = None,
    background_from: float | None = None,
) -> ScenarioConfig:
    """The configuration to replay with: ``base`` (``--config``), else the scenario the
    recording carries, else the defaults with the recording's own LiDAR model if it
    names one (``lidar_model``); then the command line's choices."""
    if base is None and recording.config_text is not None:
        try:
            data = tomllib.loads(recording.config_text)
        except tomllib.TOMLDecodeError as err:
            raise RecordingError(f"{recording.path}: the carried configuration: {err}") from None
        base = validate_scenario(data, f"{recording.path} (carried configuration)")
    if base is None:  # the defaults claim no sensor: the recording's own, if it says
        base, _ = adopt_lidar(ScenarioConfig(name="replay"), recording_lidar(recording), "")
    cfg = base
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


def run_replay(
    recording: Recording,
    cfg: ScenarioConfig,
    progress: Progress | None = None,
    viewers: Sequence[ViewerSink] = (),
    compiling: CompileProgress | None = None,
    log_sink: LogSink | None = None,
    truth_file: Path | None = None,
    sinks: Sequence[Sink] = (),
) -> ReplayRun:
    """Replay every frame of ``recording`` through the pipeline ``cfg`` describes.

    The filter draws from the same seed as ``simulate`` of ``cfg``, so a recording
    of a simulated run replays as that run did.  The numba kernels are compiled (or
    loaded from the cache) before the clock starts; ``compiling`` follows that.
    ``log_sink`` gets the log after each tracking frame.  A Ctrl-C handled by
    ``dronetrack.interrupt`` ends the replay after the frame in hand.  ``truth_file``:
    the CSV the recording's ground truth was replaced from (``--truth``), for the
    warning when no truth sample falls inside the frames' span.  ``sinks`` see every
    frame after the run's log and the viewers.
    """
    period = recording.period
    if not 1e-3 <= period <= 1.0:
        raise RecordingError(
            f"{recording.path}: frame period {period:g} s is outside 1 ms to 1 s; give --period"
        )
    # The filter's period (and eq. (11)'s σ values) follow the recording's frame rate.
    sensor = cfg.sensor.model_copy(update={"integration_time_s": period})
    cfg = resolve_pipeline(
        cfg.model_copy(update={"sensor": sensor, "turret": resolve_turret(cfg.turret)})
    )
    _, filter_seed = run_seeds(cfg.seed)
    pipeline = turret_pipeline(
        cfg, period, turret_spec(cfg.turret), np.random.default_rng(filter_seed)
    )
    radius = 0.5 * target_spec(cfg.drone.model).s_diag + TARGET_MARGIN_M
    log = TrackLogSink(on_row=log_sink)
    commands = CommandLog()
    feed: list[Sink] = [ViewerFeed(viewers)] if viewers else []
    kernels = warm_up(REPLAY_WARM_UPS, compiling)
    source = RecordingSource(recording, radius)
    stats = run(
        source, pipeline, commands, [log, *feed, *sinks], progress=progress, total=len(source)
    )
    if stats.frames == 0:
        raise RecordingError(f"{recording.path}: no LiDAR frame could be read")
    if len(log.log) == 0 and not stats.interrupted:
        scan_s = scan_duration(cfg.pipeline)
        raise RecordingError(
            f"{recording.path}: the recording lasts {stats.span_s:.3g} s ({stats.frames} frames), "
            f"no longer than the background scan of {scan_s:g} s, so no frame was left to track; "
            "give a shorter --background-from, or --background FILE"
        )
    run_ = RunResult(cfg, log.log, pipeline, stats.wall_s, stats.span_s, kernels, stats.interrupted)
    truth = recording.ground_truth
    missed = None
    if truth is not None and not stats.interrupted:
        missed = truth_overlap_warning(truth, stats.start, stats.end, recording.origin, truth_file)
    warnings = tuple(w for w in (recording.pose_warning, missed) if w)
    return ReplayRun(run_, commands.commands, dict(recording.skipped), truth is not None, warnings)
