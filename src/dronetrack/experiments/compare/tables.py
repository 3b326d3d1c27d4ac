"""A suite's results as ``table.csv`` (``scenario,method,metric,mean,std,paper``) and
``table.md`` (the same side by side with the seed's figures, the run options, and
the rankings, written from the numbers in the table)."""

from __future__ import annotations

import csv
import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from itertools import combinations, pairwise
from pathlib import Path

import numpy as np

from dronetrack.config.scenarios import get_scenario
from dronetrack.experiments.compare.runner import RunMetrics
from dronetrack.experiments.compare.suites import Suite

__all__ = [
    "TABLE_COLUMNS",
    "Row",
    "Verdict",
    "aggregate",
    "combined_standard_error",
    "judge",
    "options_lines",
    "pair_lines",
    "ranking_differences",
    "ranking_lines",
    "table_markdown",
    "write_tables",
]

TABLE_COLUMNS = ("scenario", "method", "metric", "mean", "std", "paper")
# Metrics where a smaller value is better (for the rankings).
LOWER_IS_BETTER = {
    "rmse_m",
    "rmse_from_visible_m",
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
    "acquire_s",
    "reacquire_s",
    "reacquire_missed",
    "false_lock_pct",
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


class Verdict(Enum):
    """How the first of two methods compares with the second on one metric."""

    AHEAD = "ahead"  # better by more than the combined standard error
    BEHIND = "behind"  # worse by more than the combined standard error
    LEVEL = "level"  # equal means, or a difference within the combined standard error
    UNJUDGED = "unjudged"  # the means differ but one has fewer than two runs: no spread
    MISSING = "missing"  # one of the two has no number


def _badness(metric: str, value: float) -> float:
    """The value on a scale where smaller is better."""
    return value if metric in LOWER_IS_BETTER else -value


def _direction(metric: str) -> str:
    return "lower is better" if metric in LOWER_IS_BETTER else "higher is better"


def _better(metric: str) -> str:
    """The word for the better of two numbers."""
    return "lower" if metric in LOWER_IS_BETTER else "higher"


def combined_standard_error(a: Row, b: Row) -> float:
    """√(s_a²/n_a + s_b²/n_b) over the runs that gave a number; NaN without two of each."""
    if a.finite < 2 or b.finite < 2 or not (math.isfinite(a.std) and math.isfinite(b.std)):
        return math.nan
    return math.sqrt(a.std**2 / a.finite + b.std**2 / b.finite)


def judge(a: Row, b: Row) -> Verdict:
    """``a`` against ``b`` (same scenario and metric): a difference counts only when the
    means differ by more than their combined standard error."""
    if not (math.isfinite(a.mean) and math.isfinite(b.mean)):
        return Verdict.MISSING
    if a.mean == b.mean:
        return Verdict.LEVEL
    se = combined_standard_error(a, b)
    if math.isnan(se):
        return Verdict.UNJUDGED
    d = _badness(a.metric, b.mean) - _badness(a.metric, a.mean)  # > 0: a is better
    if abs(d) <= se:
        return Verdict.LEVEL
    return Verdict.AHEAD if d > 0 else Verdict.BEHIND


# How a ranking joins a method to the next one down (best first).
_CONNECTOR = {Verdict.AHEAD: "ahead of", Verdict.LEVEL: "level with", Verdict.UNJUDGED: "then"}

RANKING_LEGEND = (
    "Best first by the mean.  *ahead of*: the two means differ by more than their combined "
    "standard error √(s₁²/n₁ + s₂²/n₂) (s the sample std, n the runs with a number); "
    "*level with*: they do not (or are equal); *then*: one of the two has fewer than two "
    "runs with a number, so there is no spread to judge the difference by.  Each "
    "connector speaks of the two methods it joins only."
)


def _fmt(value: float) -> str:
    if not math.isfinite(value):
        return ""
    return f"{value:.4g}" if abs(value) < 1e4 else f"{value:.0f}"


def _num(r: Row) -> str:
    """The mean as the table shows it, n/a without a number."""
    return _fmt(r.mean) if math.isfinite(r.mean) else "n/a"


def _item(r: Row) -> str:
    """A method with its mean, its std and how many runs gave a number."""
    text = f"{r.method} {_num(r)}"
    if math.isfinite(r.std):
        text += f" ± {_fmt(r.std)}"
    if r.finite < r.runs:
        text += f" ({r.finite} of {r.runs} runs)"
    return text


def _groups(rows: Sequence[Row]) -> dict[tuple[str, str], list[Row]]:
    """Rows by (scenario, metric), in table order, ranked metrics only."""
    out: dict[tuple[str, str], list[Row]] = {}
    for r in rows:
        if r.metric not in UNRANKED:
            out.setdefault((r.scenario, r.metric), []).append(r)
    return out


def _chain(rows: Sequence[Row]) -> str:
    """Methods with numbers best first, each joined to the next by its verdict."""
    if not rows:
        return ""
    ranked = sorted(rows, key=lambda r: _badness(r.metric, r.mean))
    text = _item(ranked[0])
    for upper, lower in pairwise(ranked):
        text += f", {_CONNECTOR[judge(upper, lower)]} {_item(lower)}"
    return text


def ranking_lines(rows: Sequence[Row]) -> list[str]:
    """Per scenario and ranked metric, the methods best first with their numbers."""
    out: list[str] = []
    for (scenario, metric), group in _groups(rows).items():
        known = [r for r in group if math.isfinite(r.mean)]
        missing = [r.method for r in group if not math.isfinite(r.mean)]
        parts = []
        if len(known) >= 2:
            parts.append(_chain(known))
        elif known:
            parts.append(f"only {_item(known[0])} has a number")
        if missing:
            parts.append(f"no number: {', '.join(missing)}")
        if len(group) >= 2:
            out.append(f"{scenario}, {metric} ({_direction(metric)}): {'; '.join(parts)}")
    return out


def pair_lines(rows: Sequence[Row]) -> list[str]:
    """Per ranked metric and pair of methods, how the pair compares over the scenarios.

    Only a pair ahead by more than the combined standard error in every scenario is
    said to be ahead in all of them; any other pair names each scenario with both numbers.
    """
    groups = _groups(rows)
    metrics = dict.fromkeys(metric for _, metric in groups)
    out: list[str] = []
    for metric in metrics:
        scenarios = [s for s, m in groups if m == metric]
        if len(scenarios) < 2:
            continue
        methods = list(dict.fromkeys(r.method for s in scenarios for r in groups[s, metric]))
        everywhere: list[str] = []
        mixed: list[str] = []
        for a, b in combinations(methods, 2):
            cells: list[tuple[str, Row, Row]] = []
            for s in scenarios:
                by_method = {r.method: r for r in groups[s, metric]}
                if a in by_method and b in by_method:
                    cells.append((s, by_method[a], by_method[b]))
            verdicts = [judge(ra, rb) for _, ra, rb in cells]
            if len(cells) == len(scenarios) and all(v == Verdict.AHEAD for v in verdicts):
                everywhere.append(f"{a} ahead of {b}")
            elif len(cells) == len(scenarios) and all(v == Verdict.BEHIND for v in verdicts):
                everywhere.append(f"{b} ahead of {a}")
            elif cells:
                summary = _pair_summary(a, b, metric, cells, verdicts)
                mixed.append(f"{metric}, {a} vs {b}: {summary}")
        if everywhere:
            out.append(
                f"{metric} ({_direction(metric)}), in all {len(scenarios)} scenarios: "
                + "; ".join(everywhere)
            )
        out += mixed
    return out


def _pair_summary(
    a: str,
    b: str,
    metric: str,
    cells: Sequence[tuple[str, Row, Row]],
    verdicts: Sequence[Verdict],
) -> str:
    """Where ``a`` or ``b`` is ahead, level, better by the means alone (unjudged) or
    without a number, each scenario with both numbers (``a``'s first)."""
    word = _better(metric)
    phrases = [
        f"{a} ahead in",
        f"{b} ahead in",
        "level in",
        f"{a} {word}, unjudged, in",
        f"{b} {word}, unjudged, in",
        "no number in",
    ]
    where: dict[str, list[str]] = {phrase: [] for phrase in phrases}
    for (s, ra, rb), v in zip(cells, verdicts, strict=True):
        if v == Verdict.UNJUDGED:
            first = a if _badness(metric, ra.mean) < _badness(metric, rb.mean) else b
            phrase = f"{first} {word}, unjudged, in"
        else:
            phrase = {
                Verdict.AHEAD: phrases[0],
                Verdict.BEHIND: phrases[1],
                Verdict.LEVEL: phrases[2],
                Verdict.MISSING: phrases[5],
            }[v]
        where[phrase].append(f"{s} ({_num(ra)} vs {_num(rb)})")
    return "; ".join(f"{phrase} {', '.join(w)}" for phrase, w in where.items() if w)


def ranking_differences(rows: Sequence[Row]) -> list[str]:
    """Per case and metric, where our order of the methods differs from the seed's.

    A pair differs where the seed's figures order it one way and our means strictly the
    other; the line gives both orders with their numbers and how far ours can tell the
    swapped pairs apart.
    """
    out: list[str] = []
    for (scenario, metric), group in _groups(rows).items():
        both = [r for r in group if math.isfinite(r.paper) and math.isfinite(r.mean)]
        swapped = []
        for x, y in combinations(both, 2):
            seed = _badness(metric, x.paper) - _badness(metric, y.paper)  # < 0: x first
            ours = _badness(metric, x.mean) - _badness(metric, y.mean)
            if seed * ours < 0:
                better, worse = (x, y) if ours < 0 else (y, x)
                swapped.append(_swap(better, worse))
        if not swapped:
            continue
        seed_order = sorted(both, key=lambda r: _badness(metric, r.paper))
        out.append(
            f"{scenario}, {metric} ({_direction(metric)}): ours {_chain(both)}; seed "
            + ", ".join(f"{r.method} {_fmt(r.paper)}" for r in seed_order)
            + f".  Swapped against the seed: {'; '.join(swapped)}"
        )
    return out


def _swap(better: Row, worse: Row) -> str:
    """Our verdict on a pair the seed orders the other way (ours ``better`` first)."""
    verdict = judge(better, worse)
    words = {Verdict.AHEAD: "ahead of", Verdict.LEVEL: "level with"}.get(verdict, "before")
    text = f"{better.method} {_num(better)} {words} {worse.method} {_num(worse)}"
    return text + " (unjudged)" if verdict == Verdict.UNJUDGED else text


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
        lines += [
            "",
            f"**Shortened runs.**  These flights were cut to {duration:g} s "
            f"({lengths} at full length), while the seed's figures in brackets come "
            "from full-length flights: ours and the seed's are not measured over the "
            "same flight, so they do not compare like for like.",
        ]
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
                cell = _num(r)
                if math.isfinite(r.std):
                    cell += f" ± {_fmt(r.std)}"
                if 0 < r.finite < r.runs:
                    cell += f" ({r.finite} of {r.runs} runs)"
                if math.isfinite(r.paper):
                    cell += f" [{_fmt(r.paper)}]"
                cells.append(cell)
            lines.append(f"| {method} | " + " | ".join(cells) + " |")
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
                [r.scenario, r.method, r.metric, _fmt(r.mean), _fmt(r.std), _fmt(r.paper)]
            )
    md_path = out_dir / "table.md"
    md_path.write_text(table_markdown(suite, rows, runs=runs, duration=duration, methods=methods))
    return csv_path, md_path
