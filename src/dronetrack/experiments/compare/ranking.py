"""Ranking the methods of a suite from its aggregated rows: which is ahead of which
on each metric, judged against the run-to-run spread, and where our order differs from
the seed's.  The sentences of ``table.md`` about the order of the methods come from here.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum
from itertools import combinations, pairwise

__all__ = [
    "LOWER_IS_BETTER",
    "RANKING_LEGEND",
    "UNRANKED",
    "Row",
    "Verdict",
    "combined_standard_error",
    "format_number",
    "judge",
    "mean_text",
    "pair_lines",
    "ranking_differences",
    "ranking_lines",
]

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
    "acquire_in_reach_s",
    "reacquire_s",
    "reacquire_missed",
    "false_lock_pct",
    "lock_transfers",
}
# Interval ends are not rankings.
UNRANKED = {"rmse_ci_low_m", "rmse_ci_high_m", "gap_min_s"}


@dataclass(frozen=True, slots=True)
class Row:
    """One method's figure on one metric of one case, over the suite's runs."""

    scenario: str  # the case label
    method: str
    metric: str
    mean: float
    std: float  # sample standard deviation over the runs (NaN for fewer than two)
    paper: float  # NaN where the seed has no figure
    runs: int
    finite: int  # runs that gave a number (e.g. an RMSE needs the target seen)


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


def format_number(value: float) -> str:
    """A figure as the tables print it: 4 significant digits (whole numbers from 10⁴
    up), and nothing for a missing one."""
    if not math.isfinite(value):
        return ""
    return f"{value:.4g}" if abs(value) < 1e4 else f"{value:.0f}"


def mean_text(r: Row) -> str:
    """The mean as the table shows it, n/a without a number."""
    return format_number(r.mean) if math.isfinite(r.mean) else "n/a"


def _item(r: Row) -> str:
    """A method with its mean, its std and how many runs gave a number."""
    text = f"{r.method} {mean_text(r)}"
    if math.isfinite(r.std):
        text += f" ± {format_number(r.std)}"
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
        where[phrase].append(f"{s} ({mean_text(ra)} vs {mean_text(rb)})")
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
            + ", ".join(f"{r.method} {format_number(r.paper)}" for r in seed_order)
            + f".  Swapped against the seed: {'; '.join(swapped)}"
        )
    return out


def _swap(better: Row, worse: Row) -> str:
    """Our verdict on a pair the seed orders the other way (ours ``better`` first)."""
    verdict = judge(better, worse)
    words = {Verdict.AHEAD: "ahead of", Verdict.LEVEL: "level with"}.get(verdict, "before")
    text = f"{better.method} {mean_text(better)} {words} {worse.method} {mean_text(worse)}"
    return text + " (unjudged)" if verdict == Verdict.UNJUDGED else text
