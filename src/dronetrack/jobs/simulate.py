"""The main job: a closed-loop run of seed 000's system on the simulator.

    SimSource ──frame──▶ Pipeline.step ──command──▶ SimTurret
                               └──result──▶ sinks (log, viewers, truth aimer, ...)

The run starts as on a real site: the turret scans the background while the
target waits on the ground, then the target flies and the pipeline tracks it.
Frames of the tracking phase are logged with their ground truth.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

from dronetrack.config.pipeline import TrackerConfig
from dronetrack.config.rig import target_spec
from dronetrack.config.run import ScenarioConfig
from dronetrack.control.aiming import aim_angles
from dronetrack.errors import ConfigError
from dronetrack.eval.log import TrackLog
from dronetrack.geometry.transforms import FloatArray
from dronetrack.jobs.run import RunResult, resolve_pipeline, run_seeds, turret_pipeline
from dronetrack.pipeline import Pipeline, Stage, run
from dronetrack.pipeline.factory import scan_duration
from dronetrack.pipeline.kernels import PIPELINE_WARM_UPS, CompileProgress, warm_up
from dronetrack.seams import Sink
from dronetrack.sim.build import build_world, resolve_scenario
from dronetrack.sim.rig import SimSource, SimTurret, TruthAimer
from dronetrack.sim.world import SimWorld
from dronetrack.sinks.track_log import TrackLogSink
from dronetrack.track.base import PositionStart
from dronetrack.types import Sample, StepResult

__all__ = [
    "CleanViewStart",
    "flight_config",
    "hold_still",
    "place_at_start",
    "resolve_run",
    "run_lockstep",
    "run_simulation",
    "start_angles",
]

Progress = Callable[[int, int], None]
LogSink = Callable[[TrackLog], None]


def resolve_run(cfg: ScenarioConfig) -> ScenarioConfig:
    """The configuration with every derived value written out: sensor, turret, the
    drone's diagonal and the σ values of eq. (11), and a background file's own settings
    and absolute path."""
    return resolve_pipeline(resolve_scenario(cfg))


def run_simulation(
    cfg: ScenarioConfig,
    progress: Progress | None = None,
    *,
    sinks: Sequence[Sink] = (),
    compiling: CompileProgress | None = None,
    log_sink: LogSink | None = None,
) -> RunResult:
    """Run the scenario closed-loop; ``cfg`` is resolved first (see ``resolve_run``).

    With ``[pipeline.evaluation] init_on_clean_view``, a tracker that can be initialised
    on a position (the Kalman filters) is, once, on the centroid of the first frame whose
    foreground holds only the drone's points, as seed 000 did for its EKF baselines.
    ``sinks`` see every frame, the background scan's too, after the run's own log.
    ``compiling`` follows the kernels' warm-up before the first frame (see
    ``run_lockstep``); ``log_sink`` gets the log after each tracking frame is added.
    """
    return run_lockstep(
        cfg,
        [cfg.pipeline.tracker],
        progress,
        sinks=[sinks],
        compiling=compiling,
        log_sink=log_sink,
    )[0]


def run_lockstep(
    cfg: ScenarioConfig,
    trackers: Sequence[TrackerConfig],
    progress: Progress | None = None,
    *,
    sinks: Sequence[Sequence[Sink]] | None = None,
    compiling: CompileProgress | None = None,
    log_sink: LogSink | None = None,
) -> list[RunResult]:
    """One simulated world feeding one pipeline per tracker configuration, frame by frame.

    The frames can be shared only if no tracker moves the turret, so with more
    than one tracker the controller must be ``truth`` or ``fixed``.  Each run is
    the same as ``run_simulation`` of the scenario with that tracker alone: the
    world and every filter draw from the seeds ``cfg.seed`` gives.  Each run's
    ``wall_s`` is the time of the whole lockstep (all pipelines and the simulator).
    ``sinks`` holds each pipeline's own sinks (one sequence per tracker).  The numba
    kernels are compiled (or loaded from numba's cache) before the clock starts, so
    ``wall_s`` and the step times hold no compilation; ``compiling`` is told after
    each warm-up step.  ``log_sink`` gets the first tracker's log after each of its
    tracking frames.  A Ctrl-C handled by ``dronetrack.interrupt`` ends the loop after
    the frame in hand; the runs then hold the frames done.
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
    if sinks is not None and len(sinks) != len(trackers):
        raise ConfigError("give one sequence of sinks per tracker")
    configs = [
        resolve_run(
            cfg.model_copy(update={"pipeline": cfg.pipeline.model_copy(update={"tracker": t})})
        )
        for t in trackers
    ]
    cfg = configs[0]
    scan_s = scan_duration(cfg.pipeline)
    sim_seed, filter_seed = run_seeds(cfg.seed)
    world = build_world(flight_config(cfg), np.random.default_rng(sim_seed))
    period = cfg.sensor.integration_time_s
    pipelines = [
        turret_pipeline(c, period, world.plant.spec, np.random.default_rng(filter_seed))
        for c in configs
    ]
    lead = pipelines[0]
    place_at_start(world, lead, mode)
    n_frames = max(1, math.ceil((scan_s + cfg.duration_s) / period - 1e-9))
    logs: list[TrackLogSink] = []
    stages: list[tuple[Stage, list[Sink]]] = []
    for k, pipe in enumerate(pipelines):
        log = TrackLogSink(on_row=log_sink if k == 0 else None)
        own: list[Sink] = [log]
        if k == 0 and mode == "truth":
            own.insert(0, TruthAimer(world, lead.latency_s))
        if configs[k].pipeline.evaluation.init_on_clean_view and isinstance(
            pipe.tracker, PositionStart
        ):
            own.append(CleanViewStart(pipe.tracker, configs[k].drone.model, period))
        own.extend(sinks[k] if sinks is not None else ())
        logs.append(log)
        stages.append((pipe, own))
    kernels = warm_up((*PIPELINE_WARM_UPS, world.warm_up), compiling)
    stats = run(
        SimSource(world, n_frames),
        lead,
        SimTurret(world),
        stages[0][1],
        followers=stages[1:],
        progress=progress,
        total=n_frames,
    )
    return [
        RunResult(c, log.log, p, stats.wall_s, stats.frames * period, kernels, stats.interrupted)
        for c, log, p in zip(configs, logs, pipelines, strict=True)
    ]


def flight_config(cfg: ScenarioConfig) -> ScenarioConfig:
    """The scenario whose flight starts after the background scan: the target waits on
    the ground for ``scan_s`` more, the other drones ([[targets]]) enter ``scan_s`` later
    and the vehicles park ``scan_s`` later (their ``start_s`` and ``arrive_s`` count from
    the scan's end, as ``duration_s`` does).  Walkers walk from the start, the scan's
    too."""
    scan_s = scan_duration(cfg.pipeline)
    targets = tuple(t.model_copy(update={"start_s": t.start_s + scan_s}) for t in cfg.targets)
    vehicles = tuple(v.model_copy(update={"arrive_s": v.arrive_s + scan_s}) for v in cfg.vehicles)
    return cfg.model_copy(
        update={
            "trajectory": cfg.trajectory.model_copy(
                update={"hold_s": cfg.trajectory.hold_s + scan_s}
            ),
            "targets": targets,
            "vehicles": vehicles,
        }
    )


def hold_still(cfg: ScenarioConfig) -> ScenarioConfig:
    """A resolved ``cfg`` whose turret never moves, as a rig with a fixed LiDAR: the
    ``fixed`` mode at home, and the background scan held there too (its pan and tilt
    ranges the home angles), so the background is what the fixed sensor sees."""
    from dronetrack.config.rig import turret_spec

    mount = turret_spec(cfg.turret).mount
    pan, tilt = (math.degrees(a) for a in aim_angles(cfg.pipeline.controller.home_m, mount))
    pipeline = cfg.pipeline
    background = pipeline.background.model_copy(
        update={"scan_pan_deg": (pan, pan), "scan_tilt_deg": (tilt, tilt)}
    )
    controller = pipeline.controller.model_copy(update={"mode": "fixed"})
    update = {"background": background, "controller": controller}
    return cfg.model_copy(update={"pipeline": pipeline.model_copy(update=update)})


def start_angles(world: SimWorld, pipeline: Pipeline, mode: str) -> tuple[float, float] | None:
    """Where the turret starts (pan, tilt) [rad]: on the scan's first goal, at home
    (``fixed``), or on the true target (``truth``); None: where the scenario's turret
    section puts it."""
    start_cmd = pipeline.controller.scanning(0.0) if pipeline.scanning else None
    if start_cmd is not None:
        return start_cmd.pan, start_cmd.tilt
    if mode == "fixed":
        pan, tilt = pipeline.controller.home
        return pan, tilt
    if mode == "truth":
        return aim_angles(world.target_position(0.0), world.mount)
    return None


def place_at_start(world: SimWorld, pipeline: Pipeline, mode: str) -> None:
    """Put the turret where a run starts it (``start_angles``)."""
    angles = start_angles(world, pipeline, mode)
    if angles is not None:
        world.place_turret(*angles)


class CleanViewStart:
    """Starts a Kalman tracker, once, on the centroid of the first tracking frame whose
    foreground holds the drone's points and nothing else, as seed 000 started its EKF
    baselines: every point lies within the drone's diagonal (plus a frame's motion) of
    its true position."""

    def __init__(self, tracker: PositionStart, drone: str, period: float) -> None:
        self.tracker = tracker
        self.s_diag = target_spec(drone).s_diag
        self.period = period
        self.waiting = True

    def write(self, sample: Sample, result: StepResult) -> None:
        if not self.waiting or result.phase != "track" or sample.truth is None:
            return
        velocity = getattr(sample.truth, "target_velocity", np.zeros(3))
        if _clean_view(result.foreground, sample.truth.target_position, velocity, self):
            self.tracker.initialize(result.foreground.mean(axis=0))
            self.waiting = False


def _clean_view(
    points: FloatArray, position: FloatArray, velocity: FloatArray, start: CleanViewStart
) -> bool:
    """Every point within s_diag + |v| T of the true position (and at least one point)."""
    if len(points) == 0:
        return False
    reach = start.s_diag + float(np.linalg.norm(velocity)) * start.period
    return bool(np.all(np.linalg.norm(points - position, axis=1) <= reach))
