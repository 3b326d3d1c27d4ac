"""``dronetrack sweep-report DIR``: seed 000's Fig. 3 and the best combinations
(``best.csv``, ``report.md``), from ``summary``'s combinations and ranks."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

from dronetrack.errors import ConfigError
from dronetrack.experiments.sweep.figure import write_figure
from dronetrack.experiments.sweep.store import RESULTS_FILE, read_results
from dronetrack.experiments.sweep.summary import (
    BEST,
    COVERAGE,
    DISTANCE,
    RESOLUTION,
    Combination,
    rank_numbers,
    ranked,
    summarise,
)

__all__ = ["Combination", "results_path", "summarise", "write_report"]


def _fmt(v: float, digits: int = 1) -> str:
    return "n/a" if not math.isfinite(v) else f"{v:.{digits}f}"


def results_path(path: Path) -> Path:
    """The result lines ``path`` names: a sweep's folder (its results.jsonl) or the file
    itself; ConfigError if there is none."""
    if not path.exists():
        raise ConfigError(f"sweep folder not found: {path}")
    results = path if path.is_file() else path / RESULTS_FILE
    if not results.is_file():
        raise ConfigError(
            f"{path}: no {RESULTS_FILE} in it (give a sweep's output folder or its {RESULTS_FILE})"
        )
    return results


def write_report(path: Path) -> tuple[list[Combination], list[Path]]:
    """Summarise a sweep's results (``path``: its folder or its results.jsonl); write the
    figure, ``best.csv`` and ``report.md`` beside them."""
    results = results_path(path)
    folder = results.parent
    rows = list(read_results(results))
    if not rows:
        raise ConfigError(f"{results}: no results to report")
    combos = ranked(summarise(rows))
    ranks = rank_numbers(combos)
    fig = folder / "coverage_vs_distance.png"
    write_figure(combos, ranks, fig)
    best = combos[:BEST]
    csv_path = folder / "best.csv"
    with csv_path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(
            [
                "rank",
                "params",
                "runs",
                "failed",
                "coverage_pct_mean",
                "coverage_pct_std",
                "max_tracking_distance_m_mean",
                "max_tracking_distance_m_std",
                "eq11_distance",
            ]
        )
        for rank, c in zip(ranks, best, strict=False):
            w.writerow(
                [
                    rank,
                    json.dumps(c.params, sort_keys=True),
                    c.runs,
                    c.failed,
                    *(f"{v:.6g}" for v in (c.coverage_mean, c.coverage_std)),
                    *(f"{v:.6g}" for v in (c.distance_mean, c.distance_std)),
                    f"{c.eq11_distance:.6g}",
                ]
            )
    md = folder / "report.md"
    lines = [
        f"# Sweep report: {len(rows)} runs, {len(combos)} combinations",
        "",
        f"The {len(best)} best combinations (coverage, then maximum tracking distance; "
        f"mean ± std over the runs; equal to {RESOLUTION[COVERAGE]:g} % and "
        f"{RESOLUTION[DISTANCE]:g} m, they share a rank):",
        "",
        "| rank | combination | runs | coverage % | max distance m | distance from eq. (11) |",
        "|---|---|---|---|---|---|",
    ]
    for rank, c in zip(ranks, best, strict=False):
        failed = f" ({c.failed} failed)" if c.failed else ""
        lines.append(
            f"| {rank} | {c.label} | {c.runs}{failed} | {_fmt(c.coverage_mean)} ± "
            f"{_fmt(c.coverage_std)} | {_fmt(c.distance_mean)} ± {_fmt(c.distance_std)} | "
            f"{_fmt(c.eq11_distance, 3)} |"
        )
    lines += ["", f"Figure: `{fig.name}` (seed 000's Fig. 3)."]
    md.write_text("\n".join(lines) + "\n")
    return combos, [fig, csv_path, md]
