"""A suite's results as ``table.csv`` (``scenario,method,metric,mean,std,paper``) and
``table.md`` (the same side by side with the seed's figures, the run options, and
the rankings of ``compare/ranking.py``, written from the numbers in the table)."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dronetrack.config.scenarios import get_scenario
from dronetrack.experiments.compare.ranking import (
    RANKING_LEGEND,
    Row,
    format_number,
    mean_text,
    pair_lines,
    ranking_differences,
    ranking_lines,
)
from dronetrack.experiments.compare.runner import RunMetrics
from dronetrack.experiments.compare.suite import Suite

__all__ = [
    "TABLE_COLUMNS",
    "aggregate",
    "options_lines",
    "table_markdown",
    "write_tables",
]

TABLE_COLUMNS = ("scenario", "method", "metric", "mean", "std", "paper")


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


def _seeds(runs: int) -> str:
    if runs == 1:
        return "seed 0"
    if runs == 2:
        return "seeds 0 and 1"
    return f"seeds 0-{runs - 1}"


def _span(seconds: Sequence[float]) -> str:
    lo, hi = min(seconds), max(seconds)
    return f"{lo:g} s" if lo == hi else f"{lo:g}-{hi:g} s"


def options_lines(
    suite: Suite, runs: int, duration: float | None, methods: Sequence[str]
) -> list[str]:
    """The run options, and a plain warning where the flights were cut short."""
    full = {c.label: get_scenario(c.scenario).duration_s for c in suite.cases}
    span = _span(list(full.values()))
    cut = [label for label, t in full.items() if duration is not None and duration < t]
    lines = [
        "Run options:",
        "",
        f"- `--runs {runs}`: {_seeds(runs)} (run r of every method is seed r)",
    ]
    if duration is None:
        lines.append(f"- `--duration` not given: full length ({span})")
    else:
        if cut:
            how = f"shortened (the full flights last {span})"
        elif duration == max(full.values()) == min(full.values()):
            how = "full length"
        else:
            how = f"at least the full length ({span})"
        lines.append(f"- `--duration {duration:g}` s: {how}")
    rest = [m for m in suite.methods if m not in methods]
    which = f" (`--methods`; not run: {', '.join(rest)})" if rest else " (all of the suite's)"
    lines.append(f"- methods: {', '.join(methods)}{which}")
    if cut:
        lengths = ", ".join(f"{label} {full[label]:g} s" for label in cut)
        warning = (
            f"**Shortened runs.**  These flights were cut to {duration:g} s "
            f"({lengths} at full length)"
        )
        if suite.paper:
            warning += (
                ", while the seed's figures in brackets come from full-length flights: "
                "ours and the seed's are not measured over the same flight, so they do "
                "not compare like for like."
            )
        else:
            warning += ": the figures are not those of the full flights."
        lines += ["", warning]
    return lines


def _cell(r: Row) -> str:
    """A table cell: mean ± std, the runs with a number if not all, the seed's figure."""
    cell = mean_text(r)
    if math.isfinite(r.std):
        cell += f" ± {format_number(r.std)}"
    if 0 < r.finite < r.runs:
        cell += f" ({r.finite} of {r.runs} runs)"
    if math.isfinite(r.paper):
        cell += f" [{format_number(r.paper)}]"
    return cell


def _case_tables(rows: Sequence[Row]) -> list[str]:
    """One table per case: a row per method, a column per metric."""
    lines = [
        "",
        "Each cell: our mean ± sample std over the runs, then the seed's figure in brackets; "
        "n/a where no run gave a number (e.g. no RMSE without returns from the target).",
    ]
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
                cells.append(_cell(r))
            lines.append(f"| {method} | " + " | ".join(cells) + " |")
    return lines


def _grouped_tables(suite: Suite, rows: Sequence[Row]) -> list[str]:
    """One table per metric group of the suite: a row per case (and method, if the
    suite ran several), a column per metric."""
    lines = [
        "",
        "Each cell: the mean ± sample std over the runs; n/a where no run gave a number.",
    ]
    by_key = {(r.scenario, r.method, r.metric): r for r in rows}
    pairs = list(dict.fromkeys((r.scenario, r.method) for r in rows))
    several = len({method for _, method in pairs}) > 1
    head = "| scenario | method | " if several else "| scenario | "
    for group in suite.groups:
        lines += ["", f"## {group.title}", ""]
        lines.append(head + " | ".join(group.metrics) + " |")
        lines.append("|---|" + "---|" * (len(group.metrics) + several))
        for scenario, method in pairs:
            cells = [scenario, method] if several else [scenario]
            for metric in group.metrics:
                r = by_key.get((scenario, method, metric))
                cells.append(_cell(r) if r is not None else "")
            lines.append("| " + " | ".join(cells) + " |")
        if group.note:
            lines += ["", group.note]
    return lines


def table_markdown(
    suite: Suite,
    rows: Sequence[Row],
    *,
    runs: int,
    duration: float | None,
    methods: Sequence[str],
) -> str:
    """table.md: options, the side-by-side tables, and rankings written from ``rows``."""
    lines = [f"# {suite.title}", "", f"Suite `{suite.name}`.", ""]
    lines += options_lines(suite, runs, duration, methods)
    lines += [
        "",
        "A row is the mean over its runs.  To rerun one: its folder beside this file, "
        "`runs/<case>/<method>/seed-<n>/`, holds its `config.toml` and `metrics.json`; "
        "`dronetrack simulate --config runs/<case>/<method>/seed-<n>/config.toml` "
        "reruns it and gives the same metrics (`results.jsonl` holds each run's command).",
    ]
    if suite.groups:
        lines += _grouped_tables(suite, rows)
    else:
        lines += _case_tables(rows)
    if suite.note:
        lines += ["", suite.note]
    ranking = ranking_lines(rows)
    if ranking:
        lines += ["", "## Rankings", "", RANKING_LEGEND]
        if all(r.finite < 2 for r in rows):
            lines += [
                "",
                "No method has two runs with a number, so no difference below can be told "
                "from the run-to-run spread: the orders are those of the means alone "
                "(see `--runs`).",
            ]
        lines.append("")
        lines += [f"- {x}" for x in ranking]
    pairs = pair_lines(rows)
    if pairs:
        lines += ["", "## Pairs of methods over the scenarios", ""]
        lines += [f"- {x}" for x in pairs]
    differences = ranking_differences(rows)
    if differences:
        lines += ["", "## Where our ranking differs from the seed's", ""]
        lines += [f"- {d}" for d in differences]
    if suite.setup_note:
        lines += ["", "## How our set-up differs from the seed's", "", suite.setup_note]
    return "\n".join(lines) + "\n"


def write_tables(
    suite: Suite,
    rows: Sequence[Row],
    out_dir: Path,
    *,
    runs: int,
    duration: float | None,
    methods: Sequence[str],
) -> tuple[Path, Path]:
    """Write table.csv and table.md; return their paths.  ``runs``, ``duration`` (None:
    full length) and ``methods`` are the options the rows were run with."""
    out_dir.mkdir(parents=True, exist_ok=True)
    csv_path = out_dir / "table.csv"
    with csv_path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(TABLE_COLUMNS)
        for r in rows:
            writer.writerow(
                [
                    r.scenario,
                    r.method,
                    r.metric,
                    format_number(r.mean),
                    format_number(r.std),
                    format_number(r.paper),
                ]
            )
    md_path = out_dir / "table.md"
    md_path.write_text(table_markdown(suite, rows, runs=runs, duration=duration, methods=methods))
    return csv_path, md_path
