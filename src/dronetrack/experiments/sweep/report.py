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
from numpy.typing import NDArray

from dronetrack.errors import ConfigError
from dronetrack.experiments.sweep.runner import SIGMA_KEYS
from dronetrack.experiments.sweep.store import read_results

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


LABEL_ALL = 20  # up to this many combinations every point is numbered, else the BEST


def _short(key: str) -> str:
    """A grid key without its config section: ``sigma_pos``, not ``track.sigma_pos``."""
    return key.rsplit(".", 1)[-1]


def varying_keys(combos: list[Combination]) -> list[str]:
    """The parameters whose value differs between combinations (all of them if none do)."""
    keys = sorted({k for c in combos for k in c.params})
    varying = [k for k in keys if len({json.dumps(c.params.get(k)) for c in combos}) > 1]
    return varying or keys


def point_key(combos: list[Combination]) -> tuple[str, list[str]]:
    """The header and one line per combination naming its varying parameters, compactly:
    ``("tracker, particles", ["pf-cv, 3000", …])``."""
    keys = varying_keys(combos)
    header = ", ".join(_short(k) for k in keys) or "(base)"
    rows = [", ".join(str(c.params.get(k, "–")) for k in keys) or "(base)" for c in combos]
    return header, rows


def padded_limits(lo: float, hi: float, least: float) -> tuple[float, float]:
    """[lo, hi] with a 5 % margin, widened about its centre to span at least ``least``."""
    centre, half = 0.5 * (lo + hi), max(0.5 * (hi - lo) * 1.1, 0.5 * least)
    return centre - half, centre + half


def _extent(values: NDArray[np.float64], spread: NDArray[np.float64]) -> tuple[float, float]:
    """The range of ``values ± spread`` over the finite values ((0, 0) if none)."""
    ok = np.isfinite(values)
    if not ok.any():
        return 0.0, 0.0
    return float((values - spread)[ok].min()), float((values + spread)[ok].max())


def nearby_groups(
    u: NDArray[np.float64], v: NDArray[np.float64], near: tuple[float, float]
) -> list[list[int]]:
    """Indices of the finite points (u, v) grouped in order: a point joins the first
    group whose first point is within ``near`` = (Δu, Δv) of it."""
    groups: list[list[int]] = []
    for i in np.flatnonzero(np.isfinite(u) & np.isfinite(v)):
        for g in groups:
            if abs(u[i] - u[g[0]]) <= near[0] and abs(v[i] - v[g[0]]) <= near[1]:
                g.append(int(i))
                break
        else:
            groups.append([int(i)])
    return groups


def _figure(combos: list[Combination], path: Path) -> None:
    """Coverage against maximum tracking distance, one point per combination (ranked, best
    first), numbered by rank with a key of its varying parameters; coloured by the
    distance from eq. (11)'s σ when it varies (a colour bar), else in one colour named
    in the legend."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = len(combos) if len(combos) <= LABEL_ALL else min(BEST, len(combos))
    header, rows = point_key(combos)  # what varies over the whole grid
    key = [f"rank  {header}"] + [f"{i:>4}  {row}" for i, row in enumerate(rows[:shown], start=1)]
    if shown < len(combos):
        key.append(f"({len(combos) - shown} more, unnumbered)")
    # The key's column: as wide as its longest line (9 pt monospace: under 0.08 in a character)
    key_w = max(1.5, 0.08 * max(map(len, key)) + 0.3)
    fig, (ax, side) = plt.subplots(
        1, 2, figsize=(8.5 + key_w, 6), width_ratios=(8.5, key_w), layout="constrained", dpi=110
    )
    side.axis("off")
    x = np.array([c.distance_mean for c in combos])
    y = np.array([c.coverage_mean for c in combos])
    xe = np.nan_to_num(np.array([c.distance_std for c in combos]))
    ye = np.nan_to_num(np.array([c.coverage_std for c in combos]))
    ax.errorbar(x, y, xerr=xe, yerr=ye, fmt="none", ecolor="grey", lw=0.8, zorder=1)
    colour = np.array([c.eq11_distance for c in combos])
    has = np.isfinite(colour)
    style = {"s": 40, "edgecolors": "k", "zorder": 2}
    if has.any() and np.ptp(colour[has]) > 0.0:
        sc = ax.scatter(
            x[has],
            y[has],
            c=colour[has],
            cmap="viridis_r",
            vmin=colour[has].min(),
            vmax=colour[has].max(),
            **style,
        )
        fig.colorbar(
            sc, ax=ax, label="‖σ − σ_eq11‖ over σ_pos, σ_vel, σ_acc, σ_m\n(m, m/s, m/s², m)"
        )
    elif has.any():
        d = float(colour[has][0])
        ax.scatter(x[has], y[has], c="tab:green", label=f"‖σ − σ_eq11‖ = {d:.3g} for all", **style)
    if (~has).any():
        ax.scatter(x[~has], y[~has], c="lightgrey", label="no σ (Kalman)", **style)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(loc="lower right", fontsize=8)
    xlim = padded_limits(*_extent(x, xe), 1.0)
    ylim = padded_limits(*_extent(y, ye), 1.0)
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    # Number the points by rank (as in report.md); points that (nearly) coincide on
    # the figure share one label, "2,3".
    u = (x[:shown] - xlim[0]) / (xlim[1] - xlim[0])
    v = (y[:shown] - ylim[0]) / (ylim[1] - ylim[0])
    # about a marker's width and a label's height, in fractions of the axes
    for group in nearby_groups(u, v, (0.02, 0.018)):
        ax.annotate(
            ",".join(str(i + 1) for i in group),
            (x[group[0]], y[group[0]]),
            xytext=(6, 0),
            textcoords="offset points",
            va="center",
            fontsize=8,
        )
    ax.ticklabel_format(useOffset=False)
    ax.set_xlabel("maximum tracking distance [m]")
    ax.set_ylabel("coverage [%]")
    ax.set_title(f"{len(combos)} parameter combinations (mean ± std over runs)")
    side.text(
        0.0,
        1.0,
        "\n".join(key),
        va="top",
        ha="left",
        family="monospace",
        fontsize=9,
        transform=side.transAxes,
    )
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
