"""A suite's results as ``table.csv`` (``scenario,method,metric,mean,std,paper``) and
``table.md`` (the same side by side, with the seed's figures and the ranking notes)."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from dronetrack.compare.runner import RunMetrics
from dronetrack.compare.suites import Suite

__all__ = ["TABLE_COLUMNS", "Row", "aggregate", "ranking_differences", "write_tables"]

TABLE_COLUMNS = ("scenario", "method", "metric", "mean", "std", "paper")
# Metrics where a smaller value is better (for the rankings).
LOWER_IS_BETTER = {
    "rmse_m",
    "rmse_3d_m",
    "rmse_x_m",
    "rmse_y_m",
    "rmse_z_m",
    "gap_min_s",
    "gap_max_s",
    "gap_mean_s",
    "pos_var",
    "vel_var",
    "error_3d_m",
    "cpu_pct",
    "memory_mb",
}
# Interval ends are not rankings.
UNRANKED = {"rmse_ci_low_m", "rmse_ci_high_m", "gap_min_s"}


@dataclass(frozen=True, slots=True)
class Row:
    scenario: str  # the case label
    method: str
    metric: str
    mean: float
    std: float  # sample standard deviation over the runs (NaN for fewer than two)
    paper: float  # NaN where the seed has no figure
    runs: int
    finite: int  # runs that gave a number (e.g. an RMSE needs the target seen)


def aggregate(suite: Suite, results: Sequence[RunMetrics]) -> list[Row]:
    """Mean and standard deviation over runs, in suite order (case, method, metric)."""
    rows: list[Row] = []
    for case in suite.cases:
        for method in suite.methods:
            mine = [r for r in results if r.case == case.label and r.method == method]
            if not mine:
                continue
            for metric in suite.metrics:
                values = np.array([r.metrics.get(metric, math.nan) for r in mine], dtype=float)
                finite = values[np.isfinite(values)]
                mean = float(finite.mean()) if len(finite) else math.nan
                std = float(finite.std(ddof=1)) if len(finite) > 1 else math.nan
                paper = suite.paper.get((case.label, method, metric), math.nan)
                rows.append(
                    Row(case.label, method, metric, mean, std, paper, len(mine), len(finite))
                )
    return rows


def ranking_differences(rows: Sequence[Row]) -> list[str]:
    """Per case and metric, where our order of the methods differs from the seed's."""
    out: list[str] = []
    keys = dict.fromkeys((r.scenario, r.metric) for r in rows)
    for scenario, metric in keys:
        if metric in UNRANKED:
            continue
        both = [
            r
            for r in rows
            if r.scenario == scenario
            and r.metric == metric
            and math.isfinite(r.paper)
            and math.isfinite(r.mean)
        ]
        if len(both) < 2:
            continue
        if len({r.mean for r in both}) == 1:
            continue  # a tie (e.g. every method keeps up with the sensor) ranks nothing
        sign = 1.0 if metric in LOWER_IS_BETTER else -1.0
        ours = [r.method for r in sorted(both, key=lambda r: sign * r.mean)]
        paper = [r.method for r in sorted(both, key=lambda r: sign * r.paper)]
        if ours != paper:
            out.append(
                f"{scenario}, {metric} (best first): ours {', '.join(ours)}; "
                f"seed {', '.join(paper)}"
            )
    return out


def _fmt(value: float) -> str:
    if not math.isfinite(value):
        return ""
    return f"{value:.4g}" if abs(value) < 1e4 else f"{value:.0f}"


def write_tables(suite: Suite, rows: Sequence[Row], out_dir: Path) -> tuple[Path, Path]:
    """Write table.csv and table.md; return their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / "table.csv"
    with csv_path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(TABLE_COLUMNS)
        for r in rows:
            writer.writerow(
                [r.scenario, r.method, r.metric, _fmt(r.mean), _fmt(r.std), _fmt(r.paper)]
            )
    md_path = out_dir / "table.md"
    md_path.write_text(_markdown(suite, rows))
    return csv_path, md_path


def _markdown(suite: Suite, rows: Sequence[Row]) -> str:
    runs = max((r.runs for r in rows), default=0)
    lines = [f"# {suite.title}", "", f"Suite `{suite.name}`, {runs} run(s) per method.", ""]
    lines.append(
        "Each cell: our mean ± sample std over the runs, then the seed's figure in brackets; "
        "n/a where no run gave a number (e.g. no RMSE without returns from the target)."
    )
    for scenario in dict.fromkeys(r.scenario for r in rows):
        mine = [r for r in rows if r.scenario == scenario]
        metrics = list(dict.fromkeys(r.metric for r in mine))
        lines += ["", f"## {scenario}", ""]
        lines.append("| method | " + " | ".join(metrics) + " |")
        lines.append("|---|" + "---|" * len(metrics))
        for method in dict.fromkeys(r.method for r in mine):
            cells = []
            for metric in metrics:
                (r,) = [x for x in mine if x.method == method and x.metric == metric]
                cell = _fmt(r.mean) if math.isfinite(r.mean) else "n/a"
                if math.isfinite(r.std):
                    cell += f" ± {_fmt(r.std)}"
                if 0 < r.finite < r.runs:
                    cell += f" ({r.finite} of {r.runs} runs)"
                if math.isfinite(r.paper):
                    cell += f" [{_fmt(r.paper)}]"
                cells.append(cell)
            lines.append(f"| {method} | " + " | ".join(cells) + " |")
    lines += ["", suite.note]
    differences = ranking_differences(rows)
    if differences:
        lines += ["", "Where our ranking differs from the seed's:", ""]
        lines += [f"- {d}" for d in differences]
        if suite.ranking_note:
            lines += ["", suite.ranking_note]
    return "\n".join(lines) + "\n"
