"""``dronetrack sweep-report DIR``: seed 000's Fig. 3 and the best combinations.

Each grid combination is summarised over its runs (seeds): mean and standard
deviation of coverage and of maximum tracking distance.  Its distance from the
analytic parameter set is the Euclidean distance of its
(σ_pos, σ_vel, σ_acc, σ_m) from eq. (11)'s for the same drone and frame period,
in their own units (m, m/s, m/s², m), as in the seed's figure; it is empty for
the Kalman filters, which have no such σ.
"""

from __future__ import annotations

import csv
import json
import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.errors import ConfigError
from dronetrack.sweep.runner import SIGMA_KEYS
from dronetrack.sweep.store import read_results

__all__ = ["Combination", "summarise", "write_report"]

COVERAGE, DISTANCE = "coverage_pct", "max_tracking_distance_m"
BEST = 10  # rows in the table of the best combinations


@dataclass(frozen=True, slots=True)
class Combination:
    """One grid point over its runs."""

    params: dict[str, Any]
    runs: int
    failed: int
    coverage_mean: float
    coverage_std: float
    distance_mean: float
    distance_std: float
    eq11_distance: float  # NaN without σ values

    @property
    def label(self) -> str:
        return ", ".join(f"{k}={v}" for k, v in sorted(self.params.items())) or "(base)"


def _stats(values: list[float]) -> tuple[float, float]:
    a = np.array([v for v in values if v is not None and math.isfinite(v)], dtype=np.float64)
    if len(a) == 0:
        return math.nan, math.nan
    return float(a.mean()), float(a.std(ddof=1)) if len(a) > 1 else math.nan


def eq11_distance(sigma: dict[str, Any], eq11: dict[str, Any]) -> float:
    """‖σ − σ_eq11‖ over σ_pos, σ_vel, σ_acc, σ_m; NaN if a value is missing."""
    try:
        d = np.array([float(sigma[k]) - float(eq11[k]) for k in SIGMA_KEYS])
    except (KeyError, TypeError):
        return math.nan
    return float(np.sqrt(np.sum(d * d)))


def summarise(rows: list[dict[str, Any]]) -> list[Combination]:
    """The combinations of a sweep's result lines, in first-seen order."""
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        groups[json.dumps(row.get("params", {}), sort_keys=True)].append(row)
    out = []
    for params, group in groups.items():
        ok = [r for r in group if "error" not in r and isinstance(r.get("metrics"), dict)]
        cov = _stats([r["metrics"].get(COVERAGE) for r in ok])
        dist = _stats([r["metrics"].get(DISTANCE) for r in ok])
        d = [eq11_distance(r.get("sigma") or {}, r.get("eq11") or {}) for r in ok]
        out.append(
            Combination(
                params=json.loads(params),
                runs=len(ok),
                failed=len(group) - len(ok),
                coverage_mean=cov[0],
                coverage_std=cov[1],
                distance_mean=dist[0],
                distance_std=dist[1],
                eq11_distance=float(np.mean(d)) if d else math.nan,
            )
        )
    return out


def _ranked(combos: list[Combination]) -> list[Combination]:
    """Best first: coverage, then maximum tracking distance (NaN last)."""

    def score(c: Combination) -> tuple[float, float]:
        cov = c.coverage_mean if math.isfinite(c.coverage_mean) else -math.inf
        dist = c.distance_mean if math.isfinite(c.distance_mean) else -math.inf
        return (-cov, -dist)

    return sorted(combos, key=score)


def _fmt(v: float, digits: int = 1) -> str:
    return "n/a" if not math.isfinite(v) else f"{v:.{digits}f}"


def _figure(combos: list[Combination], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 6))
    x = np.array([c.distance_mean for c in combos])
    y = np.array([c.coverage_mean for c in combos])
    colour = np.array([c.eq11_distance for c in combos])
    has = np.isfinite(colour)
    if has.any():
        sc = ax.scatter(x[has], y[has], c=colour[has], cmap="viridis_r", s=40, edgecolors="k")
        fig.colorbar(sc, ax=ax, label="distance from the eq. (11) parameters")
    if (~has).any():
        ax.scatter(x[~has], y[~has], c="lightgrey", s=40, edgecolors="k", label="no σ (Kalman)")
        ax.legend(loc="best", fontsize=8)
    xe = np.array([c.distance_std for c in combos])
    ye = np.array([c.coverage_std for c in combos])
    ax.errorbar(
        x, y, xerr=np.nan_to_num(xe), yerr=np.nan_to_num(ye), fmt="none", ecolor="grey", lw=0.8
    )
    ax.set_xlabel("maximum tracking distance [m]")
    ax.set_ylabel("coverage [%]")
    ax.set_title("parameter combinations (mean ± std over runs)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def write_report(folder: Path) -> tuple[list[Combination], list[Path]]:
    """Summarise ``folder/results.jsonl``; write the figure, ``best.csv`` and ``report.md``."""
    rows = list(read_results(folder / "results.jsonl"))
    if not rows:
        raise ConfigError(f"{folder}: no results.jsonl with results to report")
    combos = _ranked(summarise(rows))
    fig = folder / "coverage_vs_distance.png"
    _figure(combos, fig)
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
        for i, c in enumerate(best, start=1):
            w.writerow(
                [
                    i,
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
        "mean ± std over the runs):",
        "",
        "| rank | combination | runs | coverage % | max distance m | distance from eq. (11) |",
        "|---|---|---|---|---|---|",
    ]
    for i, c in enumerate(best, start=1):
        failed = f" ({c.failed} failed)" if c.failed else ""
        lines.append(
            f"| {i} | {c.label} | {c.runs}{failed} | {_fmt(c.coverage_mean)} ± "
            f"{_fmt(c.coverage_std)} | {_fmt(c.distance_mean)} ± {_fmt(c.distance_std)} | "
            f"{_fmt(c.eq11_distance, 3)} |"
        )
    lines += ["", f"Figure: `{fig.name}` (seed 000's Fig. 3)."]
    md.write_text("\n".join(lines) + "\n")
    return combos, [fig, csv_path, md]
