"""A suite's per-run files: ``results.jsonl`` (every run's metrics, and for the suites
that score every object its ``drones``, ``mot`` and ``classes``), ``confusion.md``
(each case's class confusion matrix, summed over the runs) and each run's folder,
``runs/<case>/<method>/seed-<n>/``: its resolved ``config.toml``, of which
``dronetrack simulate --config`` is that run (``results.jsonl``'s ``config`` and
``command``), and its ``metrics.json``."""

from __future__ import annotations

import json
import shlex
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.config.run import dump_scenario
from dronetrack.eval.classes import row_percentages
from dronetrack.experiments.compare.ranking import format_number
from dronetrack.experiments.compare.runner import RunMetrics
from dronetrack.experiments.compare.suite import Suite
from dronetrack.experiments.compare.tables import options_lines
from dronetrack.sinks.run_folder import json_safe, write_metrics
from dronetrack.types import TRACK_CLASSES

__all__ = [
    "CONFUSION_FILE",
    "RESULTS_FILE",
    "RUNS_DIR",
    "confusion_markdown",
    "run_dir",
    "summed_confusion",
    "write_run_files",
]

RESULTS_FILE = "results.jsonl"
CONFUSION_FILE = "confusion.md"
RUNS_DIR = "runs"


def run_dir(out_dir: Path, result: RunMetrics) -> Path:
    """Run ``result``'s folder in a suite's folder ``out_dir`` (its seed is its run)."""
    return out_dir / RUNS_DIR / result.case / result.method / f"seed-{result.run}"


def result_line(suite: Suite, result: RunMetrics, config: Path | None = None) -> dict[str, Any]:
    """One run's line of results.jsonl; ``config``: where its configuration was written."""
    case = next(c for c in suite.cases if c.label == result.case)
    line: dict[str, Any] = {
        "suite": suite.name,
        "case": result.case,
        "scenario": case.scenario,
        "method": result.method,
        "run": result.run,
        "seed": result.run,
    }
    if config is not None:
        line["config"] = str(config)
        line["command"] = f"dronetrack simulate --config {shlex.quote(str(config))}"
    return {**line, "metrics": result.metrics, **result.objects}


def summed_confusion(
    results: Sequence[RunMetrics],
) -> tuple[list[str], list[str], np.ndarray] | None:
    """The class confusion matrices of ``results`` summed: (kinds, classes, counts),
    kinds in the runs' order; None if no run has one."""
    matrices = [r.objects["classes"]["confusion"] for r in results if "classes" in r.objects]
    if not matrices:
        return None
    kinds = list(dict.fromkeys(k for m in matrices for k in m))
    classes = list(dict.fromkeys([*TRACK_CLASSES, *(c for m in matrices for k in m for c in m[k])]))
    counts = np.zeros((len(kinds), len(classes)), dtype=np.int64)
    for m in matrices:
        for i, kind in enumerate(kinds):
            for j, cls in enumerate(classes):
                counts[i, j] += int(m.get(kind, {}).get(cls, 0))
    return kinds, classes, counts


def _matrix_lines(kinds: list[str], classes: list[str], counts: np.ndarray) -> list[str]:
    if not counts.any():
        return ["No track lived long enough to be counted."]
    shares = row_percentages(counts)
    lines = [
        "| truth \\ class | " + " | ".join(classes) + " | frames |",
        "|---|" + "---:|" * (len(classes) + 1),
    ]
    for i, kind in enumerate(kinds):
        total = int(counts[i].sum())
        if total == 0:
            continue
        cells = [f"{counts[i, j]} ({shares[i, j]:.1f} %)" for j in range(len(classes))]
        lines.append(f"| {kind} | " + " | ".join(cells) + f" | {total} |")
    return lines


def confusion_markdown(
    suite: Suite,
    results: Sequence[RunMetrics],
    *,
    runs: int,
    duration: float | None,
    methods: Sequence[str],
) -> str | None:
    """confusion.md: per case (and method, if several ran) the class confusion matrix
    summed over its runs; None if no run has one."""
    scored = [r for r in results if "classes" in r.objects]
    if not scored:
        return None
    first = scored[0].objects["classes"]
    lines = [f"# Class confusion: suite `{suite.name}`", ""]
    lines += options_lines(suite, runs, duration, methods)
    lines += [
        "",
        "Rows: what a track follows in truth, the object nearest to it within "
        f"{format_number(first['radius_m'])} m (the correct radius) at each frame, `none` "
        "where there is none (the static scene, clutter, or a track coasting away from "
        "what it followed); columns: the track's class.  Each cell: the frames of tracks "
        f"at least {format_number(first['min_age_s'])} s old, summed over the runs, and "
        "their share of the row.  Rows without frames are left out.",
    ]
    pairs = dict.fromkeys((r.case, r.method) for r in scored)
    several = len({m for _, m in pairs}) > 1
    for case, method in pairs:
        summed = summed_confusion([r for r in scored if (r.case, r.method) == (case, method)])
        assert summed is not None
        lines += ["", f"## {case}, {method}" if several else f"## {case}", ""]
        lines += _matrix_lines(*summed)
    return "\n".join(lines) + "\n"


def write_run_files(
    suite: Suite,
    results: Sequence[RunMetrics],
    out_dir: Path,
    *,
    runs: int,
    duration: float | None,
    methods: Sequence[str],
) -> list[Path]:
    """Write each run's folder (config.toml and metrics.json), results.jsonl and, where
    the runs have classes, confusion.md; return the paths of the last two written."""
    out_dir.mkdir(parents=True, exist_ok=True)
    configs: list[Path | None] = []
    for r in results:
        folder = run_dir(out_dir, r)
        folder.mkdir(parents=True, exist_ok=True)
        write_metrics(r.run_json, folder / "metrics.json")
        if r.config is None:
            configs.append(None)
            continue
        where = folder / "config.toml"
        where.write_text(dump_scenario(r.config))
        configs.append(where)
    path = out_dir / RESULTS_FILE
    with path.open("w") as fh:
        for r, written_to in zip(results, configs, strict=True):
            line = result_line(suite, r, written_to)
            fh.write(json.dumps(json_safe(line), allow_nan=False) + "\n")
    written = [path]
    text = confusion_markdown(suite, results, runs=runs, duration=duration, methods=methods)
    if text is not None:
        confusion = out_dir / CONFUSION_FILE
        confusion.write_text(text)
        written.append(confusion)
    return written
