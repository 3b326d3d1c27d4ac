"""The whole suite: every measurement, its statistics and the speed targets.

``bench`` runs the measurements of ``pipeline``, ``sim`` and ``replay`` with the
``Settings`` given (``FULL`` or ``QUICK``) and returns the dictionary that
``dronetrack bench`` writes as ``bench.json``, with ``machine_info`` and each of
``TARGETS`` marked met or missed by ``evaluate_targets``.

Every measurement runs ``rounds`` times and keeps the round with the lowest
median (``best_round``; replay: the fastest round), as ``timeit`` does: on a
shared virtual machine the neighbours only ever add time.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.errors import ConfigError
from dronetrack.experiments.bench.learning import MAP_S, learning_map
from dronetrack.experiments.bench.machine import machine_info
from dronetrack.experiments.bench.multi import multi_step_ms
from dronetrack.experiments.bench.pipeline import (
    PF_PARTICLES,
    AviaFrames,
    pipeline_step_ms,
    tracker_step_ms,
    worst_case_frames,
)
from dronetrack.experiments.bench.replay import MIN_REPLAY_S, REPLAY_FORMATS, replay_format
from dronetrack.experiments.bench.sim import SENSORS, SIM_CASES, SIM_WARMUP, sim_frame_ms
from dronetrack.geometry.transforms import FloatArray
from dronetrack.pipeline.trackers import TRACKER_NAMES

__all__ = [
    "FULL",
    "QUICK",
    "STAT_KEYS",
    "TARGETS",
    "Settings",
    "Target",
    "bench",
    "best_round",
    "evaluate_targets",
    "heavy_repeats",
    "stats",
]


# --- statistics and targets ------------------------------------------------------------


STAT_KEYS = ("median", "mean", "std", "max")


def stats(ms: FloatArray) -> dict[str, float]:
    """The four statistics bench.json gives of a round of timings [ms]."""
    return {
        "median": float(np.median(ms)),
        "mean": float(ms.mean()),
        "std": float(ms.std()),
        "max": float(ms.max()),
    }


@dataclass(frozen=True, slots=True)
class Target:
    """A speed target: the value at ``path`` in bench.json must not exceed ``limit``."""

    path: tuple[str, ...]
    limit: float
    unit: str
    label: str

    @property
    def key(self) -> str:
        return ".".join(self.path)


TARGETS: tuple[Target, ...] = (
    Target(("pf_step_ms", "5000", "median"), 2.0, "ms", "pipeline step, 5,000 particles"),
    Target(("pf_step_ms", "100000", "median"), 50.0, "ms", "pipeline step, 100,000 particles"),
    Target(("sim_frame_ms", "avia"), 10.0, "ms", "simulator frame, Avia"),
    Target(
        ("multi_step_ms", "p99"), 10.0, "ms", "pipeline step, ≥ 10 tracks and 50 candidates, p99"
    ),
    Target(("learning_map", "peak_mb"), 200.0, "MB", "learning map, all-round sweep, peak"),
)


def _lookup(results: dict[str, Any], path: tuple[str, ...]) -> float:
    value: Any = results
    for part in path:
        value = value[part]
    return float(value)


def evaluate_targets(
    results: dict[str, Any], targets: tuple[Target, ...] = TARGETS
) -> dict[str, dict[str, Any]]:
    """Each of ``targets``: its value in ``results``, its limit and whether it is met."""
    out: dict[str, dict[str, Any]] = {}
    for target in targets:
        value = _lookup(results, target.path)
        out[target.key] = {
            "label": target.label,
            "value": value,
            "limit": target.limit,
            "unit": target.unit,
            "comparison": "<=",
            "met": value <= target.limit,
        }
    return out


def best_round(measure: Callable[[], FloatArray], rounds: int) -> FloatArray:
    """The timings [ms] of the round with the lowest median among ``rounds`` calls."""
    return min((measure() for _ in range(rounds)), key=lambda ms: float(np.median(ms)))


def heavy_repeats(repeats: int) -> int:
    """Timed steps at 100,000 particles: a fifth of ``repeats``, at least 20 (or ``repeats``)."""
    return max(min(repeats, 20), repeats // 5)


# --- the suite -------------------------------------------------------------------------

Progress = Callable[[str, int, int], None]


@dataclass(frozen=True, slots=True)
class Settings:
    """How much of each measurement: timed steps, rounds, the replay's length [s], the
    learning map's all-round run [s]."""

    repeats: int
    rounds: int
    replay_s: float
    map_s: float = MAP_S

    def checked(self) -> Settings:
        """These settings, or ConfigError naming the bad value."""
        if self.repeats < 1 or self.rounds < 1:
            raise ConfigError(
                f"repeats and rounds must be at least 1, got {self.repeats}, {self.rounds}"
            )
        if not self.replay_s >= MIN_REPLAY_S:
            raise ConfigError(
                f"the replay recording needs at least {MIN_REPLAY_S:g} s, got {self.replay_s}"
            )
        return self


FULL = Settings(repeats=200, rounds=3, replay_s=30.0)
QUICK = Settings(repeats=5, rounds=1, replay_s=8.0, map_s=20.0)  # a smoke test
STAGES = len(PF_PARTICLES) + 2 + len(TRACKER_NAMES) + len(SENSORS) + len(REPLAY_FORMATS)


def _pf_suite(cfg: Settings, report: Callable[[str], None]) -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    frames: AviaFrames | None = None
    for n in PF_PARTICLES:
        report(f"pipeline step, {n:,} particles")
        frames = worst_case_frames() if frames is None else frames
        steps = cfg.repeats if n <= 10_000 else heavy_repeats(cfg.repeats)
        out[str(n)] = stats(best_round(partial(pipeline_step_ms, n, steps, frames), cfg.rounds))
    return out


def _multi_suite(cfg: Settings, report: Callable[[str], None]) -> dict[str, float]:
    """The pipeline step with many objects in view (``multi``): the four statistics, the
    99th percentile and the fewest tracks and clusters of a timed frame."""
    report("pipeline step, many objects")
    best: tuple[FloatArray, int, int] | None = None
    for _ in range(cfg.rounds):
        run = multi_step_ms(cfg.repeats)
        if best is None or np.median(run[0]) < np.median(best[0]):
            best = run
    assert best is not None
    ms, tracks, clusters = best
    return {
        **stats(ms),
        "p99": float(np.percentile(ms, 99)),
        "tracks": tracks,
        "clusters": clusters,
    }


def _tracker_suite(cfg: Settings, report: Callable[[str], None]) -> dict[str, dict[str, float]]:
    out: dict[str, dict[str, float]] = {}
    for kind in TRACKER_NAMES:
        report(f"tracker step, {kind}")
        out[kind] = stats(best_round(partial(tracker_step_ms, kind, cfg.repeats), cfg.rounds))
    return out


def _sim_suite(cfg: Settings, report: Callable[[str], None]) -> dict[str, dict[str, float]]:
    """The four statistics and the 95th percentile of each sensor's frame time."""
    out: dict[str, dict[str, float]] = {}
    warmup = min(SIM_WARMUP, cfg.repeats)
    for sensor, (scenario, override) in SIM_CASES.items():
        report(f"simulator frame, {sensor}")
        measure = partial(sim_frame_ms, scenario, override, cfg.repeats, warmup)
        ms = best_round(measure, cfg.rounds)
        out[sensor] = {**stats(ms), "p95": float(np.percentile(ms, 95))}
    return out


def _replay_suite(
    cfg: Settings, report: Callable[[str], None], workdir: Path | None
) -> dict[str, dict[str, Any]]:
    out: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory(dir=workdir, prefix="dronetrack-bench-") as tmp:
        for fmt, livox, name, key in REPLAY_FORMATS:
            report(f"replay, {key} ({cfg.replay_s:g} s)")
            out[key] = replay_format(Path(tmp) / name, fmt, livox, cfg.replay_s, cfg.rounds)
    return out


def bench(
    repeats: int | None = None,
    rounds: int | None = None,
    quick: bool = False,
    replay_s: float | None = None,
    progress: Progress | None = None,
    workdir: Path | None = None,
) -> dict[str, Any]:
    """Run the suite; return the contents of bench.json.

    ``repeats``: timed steps per measurement (pipeline steps up to 10,000
    particles, tracker steps, simulator frames; ``heavy_repeats`` of it at 100,000
    particles); ``rounds``: rounds per measurement, the best kept; ``replay_s``:
    the replay recording's length.  Defaults: ``FULL`` (200, 3, 30 s), or with
    ``quick`` ``QUICK`` (5, 1, 8 s); a value given wins.  The learning map's all-round
    run lasts ``map_s`` of them (600 s, or 20 s with ``quick``).  The recordings are
    written to ``workdir`` (default: a temporary folder) and deleted after use.
    ``progress(what, done, total)`` is called before each measurement and at the end.
    """
    base = QUICK if quick else FULL
    cfg = Settings(
        base.repeats if repeats is None else repeats,
        base.rounds if rounds is None else rounds,
        base.replay_s if replay_s is None else replay_s,
        base.map_s,
    ).checked()
    stage = iter(range(STAGES + 1))

    def report(what: str) -> None:
        done = next(stage)
        if progress is not None:
            progress(what, done, STAGES)

    pf = _pf_suite(cfg, report)
    multi = _multi_suite(cfg, report)
    report(f"learning map, {cfg.map_s:g} s all-round sweep")
    learning = learning_map(cfg.map_s)
    trackers = _tracker_suite(cfg, report)
    sim = _sim_suite(cfg, report)
    formats = _replay_suite(cfg, report, workdir)
    report("done")
    results: dict[str, Any] = {
        "machine": machine_info(),
        "settings": {
            "repeats": cfg.repeats,
            "rounds": cfg.rounds,
            "replay_s": cfg.replay_s,
            "quick": quick,
        },
        "pf_step_ms": pf,
        "multi_step_ms": multi,
        "learning_map": learning,
        "tracker_step_ms": trackers,
        "sim_frame_ms": {sensor: row["median"] for sensor, row in sim.items()},
        "sim_frame_stats_ms": sim,
        "replay_x_realtime": min(row["x_realtime"] for row in formats.values()),
        "replay_formats": formats,
    }
    results["targets"] = evaluate_targets(results)
    return results
