"""Run a comparison suite: every method on the same seeded scenarios, then its metrics.

Run ``r`` of a case is seed ``r``: the world and every filter draw from the
seeds it gives, so a method's run here is the same as ``dronetrack simulate``
of that scenario with that tracker, turret mode and seed.
"""

from __future__ import annotations

import math
import tracemalloc
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.config.run import ScenarioConfig, apply_overrides
from dronetrack.config.scenarios import get_scenario
from dronetrack.errors import ConfigError
from dronetrack.eval.metrics import (
    acquisition_metrics,
    first_lock,
    first_visible,
    rmse,
    scored_tracking,
)
from dronetrack.eval.objects import drone_summary
from dronetrack.experiments.compare.multi_suite import MULTI_METRICS
from dronetrack.experiments.compare.suite import Case, Suite
from dronetrack.geometry.transforms import FloatArray
from dronetrack.jobs.run import RunResult, detection_area
from dronetrack.jobs.simulate import run_lockstep, run_simulation
from dronetrack.pipeline.trackers import build_tracker
from dronetrack.sinks.strategy_logs import StrategyLogger
from dronetrack.types import Sample, StepResult

__all__ = ["RunMetrics", "case_config", "object_run_metrics", "run_metrics", "run_suite"]

Progress = Callable[[str, int, int], None]  # (what, done, total)


@dataclass(frozen=True, slots=True)
class RunMetrics:
    """One method's metrics on one run of one case."""

    case: str
    method: str
    run: int
    metrics: dict[str, float]
    # metrics.json's drones, mot and classes of the run, for the suites that score them
    objects: dict[str, Any] = field(default_factory=dict)
    # the run's resolved configuration: ``simulate --config`` of it is the same run
    config: ScenarioConfig | None = None
    # the run's metrics.json, as ``simulate`` writes it
    run_json: dict[str, Any] = field(default_factory=dict)


def case_config(
    case: Case, method: str, suite: Suite, seed: int, duration: float | None
) -> ScenarioConfig:
    """The scenario a method runs in a case: the named scenario with the suite's turret
    mode (or scan strategy), the method's tracker, the run's seed.  A run shortened by
    ``duration`` leaves out the vehicles that would park only after it ends
    (``apply_overrides``)."""
    base = _scored(get_scenario(case.scenario), suite)
    if suite.tracker is not None:  # the methods are scan strategies feeding one tracker
        return apply_overrides(
            base, seed=seed, duration=duration, tracker=suite.tracker, turret_mode=method
        )
    return apply_overrides(
        base, seed=seed, duration=duration, tracker=method, turret_mode=case.turret
    )


def _scored(cfg: ScenarioConfig, suite: Suite) -> ScenarioConfig:
    """``cfg`` with the suite's scoring rule and start on a clean view in its evaluation
    section and its choice of acquisition, so a method's run scores the same in
    ``simulate`` of its configuration as in the table."""
    evaluation = cfg.pipeline.evaluation.model_copy(
        update={
            "min_consecutive": suite.min_consecutive,
            "init_on_clean_view": suite.init_on_clean_view,
        }
    )
    acquire = cfg.pipeline.acquisition.model_copy(update={"enabled": suite.acquisition})
    pipeline = cfg.pipeline.model_copy(update={"evaluation": evaluation, "acquisition": acquire})
    return cfg.model_copy(update={"pipeline": pipeline})


def _select(suite: Suite, methods: Sequence[str] | None) -> tuple[str, ...]:
    if methods is None:
        return suite.methods
    unknown = [m for m in methods if m not in suite.methods]
    if unknown:
        raise ConfigError(
            f"method {unknown[0]!r} is not in suite {suite.name!r}; "
            f"choose from {', '.join(suite.methods)}"
        )
    return tuple(m for m in suite.methods if m in methods)


def run_suite(
    suite: Suite,
    runs: int = 5,
    *,
    duration: float | None = None,
    methods: Sequence[str] | None = None,
    log_dir: Path | None = None,
    progress: Progress | None = None,
) -> list[RunMetrics]:
    """Every (case, method, run) of the suite; ``duration`` shortens each flight.

    ``log_dir`` receives seed 003's CSV logs for strategy suites.
    """
    if runs < 1:
        raise ConfigError(f"runs must be at least 1, got {runs}")
    chosen = _select(suite, methods)
    memory = "memory_mb" in suite.metrics
    out: list[RunMetrics] = []
    for case in suite.cases:
        for r in range(runs):
            what = f"{case.label}, run {r + 1}/{runs}"
            foregrounds: list[list[tuple[float, FloatArray]]] = [[] for _ in chosen]
            if suite.lockstep:
                cfgs = [case_config(case, m, suite, r, duration) for m in chosen]
                done = run_lockstep(
                    cfgs[0],
                    [c.pipeline.tracker for c in cfgs],
                    _progress(progress, what),
                    sinks=[[ForegroundCollector(f)] for f in foregrounds] if memory else None,
                )
            else:
                done = []
                for m in chosen:
                    logger = None
                    if log_dir is not None:
                        logger = StrategyLogger(log_dir / case.label / m / f"run{r}")
                    cfg = case_config(case, m, suite, r, duration)
                    done.append(
                        run_simulation(
                            cfg,
                            _progress(progress, f"{what}, {m}"),
                            sinks=[logger] if logger is not None else (),
                        )
                    )
                    if logger is not None:
                        logger.close(done[-1].pipeline.controller)
                    if done[-1].interrupted:
                        break
            if any(sim.interrupted for sim in done):
                # Ctrl-C ended a run early: the tables need whole runs, so stop here
                # (the logs of the runs already done stay written).
                raise KeyboardInterrupt
            for m, sim, fg in zip(chosen, done, foregrounds, strict=True):
                every = sim.object_metrics()
                objects = every if _scores_objects(suite) else {}
                values = run_metrics(suite, sim, objects)
                if memory:
                    values["memory_mb"] = tracker_memory_mb(sim.config, fg)
                full = sim.metrics(every)
                out.append(RunMetrics(case.label, m, r, values, objects, sim.config, full))
    return out


def _progress(progress: Progress | None, what: str) -> Callable[[int, int], None] | None:
    if progress is None:
        return None
    return lambda i, n: progress(what, i, n)


def _scores_objects(suite: Suite) -> bool:
    """Whether the suite's metrics need every object's figures (``object_metrics``)."""
    return bool(set(suite.metrics) & set(MULTI_METRICS))


def object_run_metrics(objects: dict[str, Any]) -> dict[str, float]:
    """The multi suite's figures from a run's ``object_metrics`` (metrics.json's
    ``drones``, ``mot`` and ``classes``) as numbers (NaN for none): the drones'
    ``drone_summary``, motmetrics' ``mota``, ``motp_m``, ``idf1``, ``id_switches``,
    and every number of ``classes`` but its confusion matrix."""
    out = drone_summary(objects.get("drones", []))
    mot = objects.get("mot", {})
    for key in ("mota", "motp_m", "idf1", "id_switches"):
        out[key] = mot.get(key, math.nan)
    for key, value in objects.get("classes", {}).items():
        if key != "confusion":
            out[key] = value
    return {k: math.nan if v is None else float(v) for k, v in out.items()}


def run_metrics(
    suite: Suite, sim: RunResult, objects: dict[str, Any] | None = None
) -> dict[str, float]:
    """The suite's metrics of one finished run (see the suite notes for definitions);
    ``objects``: the run's ``object_metrics``, if already computed."""
    a = sim.log.arrays()
    gt = np.column_stack([a["gt_x"], a["gt_y"], a["gt_z"]])
    est = np.column_stack([a["est_x"], a["est_y"], a["est_z"]])
    err = est - gt
    evaluation = sim.config.pipeline.evaluation
    period = sim.config.sensor.integration_time_s
    coverage, distance = scored_tracking(
        err,
        a["range_m"],
        evaluation.correct_radius_m,
        a["meas_error_m"],
        evaluation.min_consecutive,
    )
    # rmse_m (eq. 13) from the first lock, as metrics.json; Table IV's window opens
    # with the first frame whose foreground holds returns from the drone: the same
    # frame for every method of a lockstep run, and none can track a drone still
    # hidden in the background model (seed 000 windowed its indoor runs too).
    r = rmse(err[first_visible(a["n_points"], a["n_target_points"]) :])
    step_ms = float(np.mean(a["step_ms"])) if len(a["step_ms"]) else 0.0
    out = {
        "coverage_pct": coverage,
        "max_tracking_distance_m": distance,
        "rmse_m": rmse(err[first_lock(a["tracked"]) :]).value,
        "rmse_from_visible_m": r.value,
        "rmse_3d_m": r.value,
        "rmse_ci_low_m": r.ci95[0],
        "rmse_ci_high_m": r.ci95[1],
        "rmse_x_m": r.per_axis[0],
        "rmse_y_m": r.per_axis[1],
        "rmse_z_m": r.per_axis[2],
        # A real-time node processing every frame: its share of one core, and the
        # rate it keeps up with (at most the sensor's).
        "cpu_pct": 100.0 * step_ms / (1e3 * period),
        "update_hz": min(1.0 / period, 1e3 / step_ms) if step_ms > 0 else 1.0 / period,
    }
    out.update(_detection_metrics(a, err))
    out.update(_acquisition_metrics(sim.config, a, err, evaluation.correct_radius_m))
    if _scores_objects(suite):
        out.update(object_run_metrics(sim.object_metrics() if objects is None else objects))
    return {k: v for k, v in out.items() if k in suite.metrics}


def _acquisition_metrics(
    cfg: ScenarioConfig, a: dict[str, np.ndarray], err: FloatArray, radius: float
) -> dict[str, float]:
    """metrics.json's acquisition figures as numbers (NaN for none): ``reacquire_s`` is
    the run's longest re-acquisition, with ``reacquire_missed`` counting the losses never
    re-acquired."""
    gt = np.column_stack([a["gt_x"], a["gt_y"], a["gt_z"]])
    area = detection_area(cfg, gt)
    found = acquisition_metrics(
        a["t"],
        err,
        a["tracked"],
        a["n_target_points"],
        radius,
        area,
        a["range_m"],
        cfg.pipeline.evaluation.reach_m,
    )
    found["reacquire_s"] = found.pop("reacquire_max_s", None)
    return {k: math.nan if v is None else float(v) for k, v in found.items()}


def _detection_metrics(a: dict[str, np.ndarray], err: FloatArray) -> dict[str, float]:
    """Seed 003 Table 1: detections (frames whose foreground reached the EKF), the time
    between them, and the EKF's mean x and v_x variances and mean 3-D error over the
    frames it is tracking (seed 003's EKF runs when centroids arrive and is restarted
    once lost, so its table leaves out the lost stretches)."""
    detected = a["n_points"] > 0
    gaps = np.diff(a["t"][detected])
    live = a["tracked"]
    dist = np.linalg.norm(err[live], axis=1)
    pos_var = a["pos_var"][live]
    vel_var = a["vel_var"][live]
    nan = math.nan
    return {
        "n_detections": float(detected.sum()),
        "gap_min_s": float(gaps.min()) if len(gaps) else nan,
        "gap_max_s": float(gaps.max()) if len(gaps) else nan,
        "gap_mean_s": float(gaps.mean()) if len(gaps) else nan,
        "pos_var": float(np.nanmean(pos_var)) if np.isfinite(pos_var).any() else nan,
        "vel_var": float(np.nanmean(vel_var)) if np.isfinite(vel_var).any() else nan,
        "error_3d_m": float(dist.mean()) if len(dist) else nan,
    }


class ForegroundCollector:
    """A run loop's sink that keeps every tracking frame's (time, foreground)."""

    def __init__(self, into: list[tuple[float, FloatArray]]) -> None:
        self.into = into

    def write(self, sample: Sample, result: StepResult) -> None:
        if result.phase == "track":
            self.into.append((result.t, result.foreground))


def tracker_memory_mb(cfg: ScenarioConfig, foreground: Sequence[tuple[float, FloatArray]]) -> float:
    """Peak memory [MB] a fresh tracker of the run's configuration allocates, state
    included, while it processes the run's foreground again (traced by tracemalloc)."""
    period = cfg.sensor.integration_time_s
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        tracker = build_tracker(cfg.pipeline.tracker, period, np.random.default_rng(0))
        for t, points in foreground:
            tracker.step(t, points, 1)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    return (peak - before) / 2**20
