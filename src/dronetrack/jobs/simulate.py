"""The main job: a closed-loop run of seed 000's system on the simulator.

    simulator ──frame──▶ pipeline.step ──command──▶ simulated turret

The run starts as on a real site: the turret scans the background while the
target waits on the ground, then the target flies and the pipeline tracks it.
Frames of the tracking phase are logged with their ground truth.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.config.pipeline import TrackerConfig
from dronetrack.config.run import ScenarioConfig, dump_scenario
from dronetrack.control.aiming import aim_angles
from dronetrack.errors import ConfigError
from dronetrack.eval.log import TrackLog
from dronetrack.formats.background import read_background_settings
from dronetrack.geometry.mount import turret_links
from dronetrack.geometry.transforms import FloatArray
from dronetrack.interrupt import stop_requested, stoppable
from dronetrack.jobs.factory import build_pipeline, noise_parameters, resolve_tracker, scan_duration
from dronetrack.jobs.kernels import PIPELINE_WARM_UPS, CompileProgress, KernelWarmUp, warm_up
from dronetrack.pipeline import Pipeline, StepResult
from dronetrack.sim.build import build_world, resolve_scenario, turret_spec
from dronetrack.sim.drones import make_drone
from dronetrack.sim.turret import TurretSpec
from dronetrack.sim.world import FrameTruth, SimWorld
from dronetrack.sinks.run_folder import FramesCsvWriter, check_run_dir, prepare_run_dir
from dronetrack.sinks.view import NamedTransform, ViewerSink, view_frame
from dronetrack.types import Frame, TurretCommand

__all__ = [
    "LogSink",
    "RunFolder",
    "SimulationRun",
    "log_result",
    "resolve_run",
    "run_lockstep",
    "run_seeds",
    "run_simulation",
    "simulation_viewer_hook",
    "turret_pipeline",
    "write_run",
]

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


NO_WARM_UP = KernelWarmUp(0.0, 0)


@dataclass(frozen=True, slots=True)
class SimulationRun:
    """A finished closed-loop run."""

    config: ScenarioConfig  # resolved
    log: TrackLog
    pipeline: Pipeline
    wall_s: float
    simulated_s: float
    kernels: KernelWarmUp = NO_WARM_UP  # the warm-up before the timed loop
    interrupted: bool = False  # Ctrl-C ended it early: the log holds the frames done

    @property
    def realtime_factor(self) -> float:
        return self.simulated_s / self.wall_s if self.wall_s > 0 else math.inf

    def metrics(self) -> dict[str, Any]:
        out = self.log.summary(self.config.pipeline.evaluation.correct_radius_m)
        out["realtime_factor"] = self.realtime_factor
        out["wall_s"] = self.wall_s
        if self.interrupted:
            out["interrupted"] = True
        return out


FrameHook = Callable[[Frame, FrameTruth, StepResult], None]
LogSink = Callable[[TrackLog], None]


def run_simulation(
    cfg: ScenarioConfig,
    progress: Progress | None = None,
    *,
    init_on_clean_view: bool = False,
    hook: FrameHook | None = None,
    on_frame: FrameHook | None = None,
    compiling: CompileProgress | None = None,
    log_sink: LogSink | None = None,
) -> SimulationRun:
    """Run the scenario closed-loop; ``cfg`` is resolved first (see ``resolve_run``).

    ``init_on_clean_view``: a tracker that can be initialised on a position (the
    Kalman filters) is, once, on the centroid of the first frame whose foreground
    holds only the drone's points, as seed 000 did for its EKF baselines.
    ``hook`` sees every tracking frame with its ground truth and the pipeline's
    result; ``on_frame`` every frame, the background scan's too.  ``compiling``
    follows the kernels' warm-up before the first frame (see ``run_lockstep``);
    ``log_sink`` gets the log after each tracking frame is added to it.
    """
    return run_lockstep(
        cfg,
        [cfg.pipeline.tracker],
        progress,
        init_on_clean_view=init_on_clean_view,
        hooks=[hook] if hook is not None else None,
        on_frame=on_frame,
        compiling=compiling,
        log_sink=log_sink,
    )[0]


def run_lockstep(
    cfg: ScenarioConfig,
    trackers: Sequence[TrackerConfig],
    progress: Progress | None = None,
    *,
    init_on_clean_view: bool = False,
    hooks: Sequence[FrameHook] | None = None,
    on_frame: FrameHook | None = None,
    compiling: CompileProgress | None = None,
    log_sink: LogSink | None = None,
) -> list[SimulationRun]:
    """One simulated world feeding one pipeline per tracker configuration, frame by frame.

    The frames can be shared only if no tracker moves the turret, so with more
    than one tracker the controller must be ``truth`` or ``fixed``.  Each run is
    the same as ``run_simulation`` of the scenario with that tracker alone: the
    world and every filter draw from the seeds ``cfg.seed`` gives.  Each run's
    ``wall_s`` is the time of the whole lockstep (all pipelines and the simulator).
    ``on_frame`` sees every frame (scan phase included) with the first pipeline's result.
    The numba kernels are compiled (or loaded from numba's cache) before the clock
    starts, so ``wall_s`` and the step times hold no compilation; ``compiling`` is
    told after each warm-up step.  ``log_sink`` gets the first tracker's log after
    each of its tracking frames.  A Ctrl-C handled by ``dronetrack.interrupt`` ends
    the loop after the frame in hand; the runs then hold the frames done.
    """
    mode = cfg.pipeline.controller.mode
    if len(trackers) > 1 and mode not in ("truth", "fixed"):
        raise ConfigError(
            f"trackers can share frames only with the turret on 'truth' or 'fixed', not {mode!r}"
        )
    if cfg.observer is not None and mode != "fixed":
        raise ConfigError(
            f"with an [observer] the turret must be 'fixed' (it rides on the drone), not {mode!r}"
        )
    if hooks is not None and len(hooks) != len(trackers):
        raise ConfigError("give one hook per tracker")
    configs = [
        resolve_run(
            cfg.model_copy(update={"pipeline": cfg.pipeline.model_copy(update={"tracker": t})})
        )
        for t in trackers
    ]
    cfg = configs[0]
    scan_s = scan_duration(cfg.pipeline)
    # The flight starts after the background scan: the target waits on the ground.
    flight = cfg.model_copy(
        update={
            "trajectory": cfg.trajectory.model_copy(
                update={"hold_s": cfg.trajectory.hold_s + scan_s}
            )
        }
    )
    sim_seed, filter_seed = run_seeds(cfg.seed)
    world = build_world(flight, np.random.default_rng(sim_seed))
    period = cfg.sensor.integration_time_s
    pipelines = [
        turret_pipeline(c, period, world.plant.spec, np.random.default_rng(filter_seed))
        for c in configs
    ]
    lead = pipelines[0]
    s_diag = make_drone(cfg.drone.model).s_diag
    start_cmd = lead.controller.scanning(0.0) if lead.scanning else None
    if start_cmd is not None:
        world.place_turret(start_cmd.pan, start_cmd.tilt)
    elif mode == "fixed":
        world.place_turret(*lead.controller.home)
    elif mode == "truth":
        world.place_turret(*aim_angles(world.target_position(0.0), world.mount))
    n_frames = max(1, math.ceil((scan_s + cfg.duration_s) / period - 1e-9))
    logs = [TrackLog() for _ in pipelines]
    waiting = [init_on_clean_view and hasattr(p.tracker, "initialize") for p in pipelines]
    kernels = warm_up((*PIPELINE_WARM_UPS, world.warm_up), compiling)
    begin = time.perf_counter()
    done = 0
    with stoppable():
        while done < n_frames and not stop_requested():
            _lockstep_frame(world, pipelines, logs, waiting, mode, s_diag, on_frame, hooks)
            done += 1
            if log_sink is not None and len(logs[0]) > 0:
                log_sink(logs[0])
            if progress is not None:
                progress(done, n_frames)
    wall = time.perf_counter() - begin
    return [
        SimulationRun(c, log, p, wall, done * period, kernels, done < n_frames)
        for c, log, p in zip(configs, logs, pipelines, strict=True)
    ]


def _lockstep_frame(
    world: SimWorld,
    pipelines: Sequence[Pipeline],
    logs: Sequence[TrackLog],
    waiting: list[bool],
    mode: str,
    s_diag: float,
    on_frame: FrameHook | None,
    hooks: Sequence[FrameHook] | None,
) -> None:
    """One frame of ``run_lockstep``: simulate, step every pipeline, steer, log."""
    lead = pipelines[0]
    period = world.integration_time
    frame, truth = world.step()
    results = [p.step(frame) for p in pipelines]
    command = results[0].command
    if mode == "truth" and results[0].phase == "track":
        t_cmd = frame.end + lead.latency_s
        command = TurretCommand(t_cmd, *aim_angles(world.target_position(t_cmd), world.mount))
    if command is not None:
        world.command(command)
    if on_frame is not None:
        on_frame(frame, truth, results[0])
    for k, result in enumerate(results):
        if result.phase != "track":
            continue
        _record(logs[k], frame, truth, result)
        if waiting[k] and _clean_view(result.foreground, truth, s_diag, period):
            pipelines[k].tracker.initialize(result.foreground.mean(axis=0))  # type: ignore[attr-defined]
            waiting[k] = False
        if hooks is not None:
            hooks[k](frame, truth, result)


def run_seeds(seed: int) -> tuple[np.random.SeedSequence, np.random.SeedSequence]:
    """The simulator's and the filters' seeds of a run with ``seed``: a replay of a
    recorded run draws its filter from the same one."""
    sim, filters = np.random.SeedSequence(seed).spawn(2)
    return sim, filters


def turret_pipeline(
    cfg: ScenarioConfig, period: float, turret: TurretSpec, rng: np.random.Generator
) -> Pipeline:
    """The pipeline ``cfg`` describes, for frames of ``period`` s from this turret."""
    return build_pipeline(
        cfg.pipeline,
        period,
        turret.mount,
        (turret.pan.lower, turret.pan.upper),
        (turret.tilt.lower, turret.tilt.upper),
        rng,
    )


def _clean_view(points: FloatArray, truth: FrameTruth, s_diag: float, period: float) -> bool:
    """The foreground holds the drone's points and nothing else: every point lies within
    the drone's diagonal (plus a frame's motion) of its true position."""
    if len(points) == 0:
        return False
    reach = s_diag + float(np.linalg.norm(truth.target_velocity)) * period
    return bool(np.all(np.linalg.norm(points - truth.target_position, axis=1) <= reach))


def _record(log: TrackLog, frame: Frame, truth: FrameTruth, result: StepResult) -> None:
    pan, tilt = truth.turret.pan, truth.turret.tilt
    log_result(log, frame, result, truth.target_position, truth.n_target_points, pan, tilt)


def log_result(
    log: TrackLog,
    frame: Frame,
    result: StepResult,
    gt: FloatArray | None,
    n_target_points: int,
    pan: float,
    tilt: float,
) -> None:
    """Append a tracking frame's result to ``log``; ``gt`` None (or NaN) when unknown."""
    est = result.estimate
    assert est is not None
    sensor = frame.poses[-1, :3, 3]
    gt = np.full(3, np.nan) if gt is None else gt
    var = est.variance
    if est.measurement is not None:  # a Kalman filter's z
        meas_error = float(np.linalg.norm(est.measurement - gt))
    elif est.particles is not None and result.periods > 0 and len(result.foreground):
        # a particle filter updates on every foreground point: the nearest counts
        meas_error = float(np.min(np.linalg.norm(result.foreground - gt, axis=1)))
    else:
        meas_error = math.nan
    log.append(
        t=frame.end,
        gt=gt,
        est=est.position,
        tracked=est.tracked,
        sigma=est.spread,
        n_points=result.n_points,
        n_target_points=n_target_points,
        range_m=float(np.linalg.norm(gt - sensor)),
        pan=pan,
        tilt=tilt,
        step_ms=result.step_ms,
        flags=result.flags,
        pos_var=float(var[0]) if var is not None else math.nan,
        vel_var=float(var[3]) if var is not None else math.nan,
        measured=est.measurement is not None,
        meas_error=meas_error,
    )


def simulation_viewer_hook(viewers: Sequence[ViewerSink], cfg: ScenarioConfig) -> FrameHook:
    """An ``on_frame`` hook that shows every frame in ``viewers``, with the turret's links
    (on a moving observer: the sensor's pose alone)."""
    mount = turret_spec(cfg.turret).mount

    def show(frame: Frame, truth: FrameTruth, result: StepResult) -> None:
        if cfg.observer is None:
            pan, tilt = truth.turret.pan, truth.turret.tilt
            links = [NamedTransform(*link) for link in turret_links(pan, tilt, mount)]
        else:
            links = [NamedTransform("world", "lidar", frame.poses[-1])]
        view = view_frame(frame, result, truth.target_position, links)
        for sink in viewers:
            sink.log(view)

    return show


class RunFolder:
    """A run's output folder, written as the run goes: ``frames.csv`` row by row from
    the first tracking frame (flushed, so an interrupted or crashed run keeps its
    frames), then at the end config.toml, metrics.json, the plots and the scanned
    background.  The folder is checked at once and created at the first row, so a
    run refused before it tracks anything leaves nothing behind.

    ``log_sink`` is the ``log_sink`` of ``run_simulation`` and ``run_replay``.
    """

    def __init__(self, out_dir: Path) -> None:
        self.out_dir = check_run_dir(out_dir)
        self._frames: FramesCsvWriter | None = None

    def log_sink(self, log: TrackLog) -> None:
        if self._frames is None:
            self._frames = FramesCsvWriter(prepare_run_dir(self.out_dir) / "frames.csv")
        self._frames.write(log)

    def close(self) -> None:
        if self._frames is not None:
            self._frames.close()

    def finish(self, run: SimulationRun, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """Write the rest of the run (see ``write_run``); return its metrics."""
        from dronetrack.formats.background import save_background
        from dronetrack.sinks.run_folder import write_metrics, write_plots

        self.log_sink(run.log)
        self.close()
        out_dir = self.out_dir
        background = run.pipeline.background
        config = run.config
        if background is not None and background.ready and config.pipeline.background.file is None:
            save_background(background, out_dir / "background.npz")
        (out_dir / "config.toml").write_text(dump_scenario(config))
        metrics = run.metrics() if extra is None else extra
        write_metrics(metrics, out_dir / "metrics.json")
        noise = noise_parameters(config.pipeline.tracker, config.sensor.integration_time_s)
        radius = config.pipeline.evaluation.correct_radius_m
        write_plots(
            run.log, out_dir, noise.threshold, config.name, radius, config.pipeline.tracker.kind
        )
        return metrics


def write_run(
    run: SimulationRun, out_dir: Path, extra: dict[str, Any] | None = None
) -> dict[str, Any]:
    """Write config.toml, frames.csv, metrics.json, the plots and the scanned background
    (``background.npz``, to load with ``[pipeline.background] file``); return the metrics
    (``extra`` replaces the run's own)."""
    return RunFolder(out_dir).finish(run, extra)
