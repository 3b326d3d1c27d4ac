"""``sweep-report``'s figure, seed 000's Fig. 3: each combination's coverage against its
maximum tracking distance, numbered by rank, coloured by its distance from eq. (11)'s σ.

What is drawn where is computed by small pure functions (the key, the limits, which
points coincide, how tied points are set side by side, the title); ``coverage_figure``
draws it."""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.experiments.sweep.summary import BEST, Combination

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

__all__ = [
    "coverage_figure",
    "dodge_offsets",
    "group_label",
    "nearby_groups",
    "padded_limits",
    "point_key",
    "spread_title",
    "varying_keys",
    "write_figure",
]

LABEL_ALL = 20  # up to this many combinations every point is numbered, else the BEST
# In fractions of the axes: points closer than about a marker's width and a label's
# height share one label; tied points are set side by side this far apart (a marker
# of 40 pt² is 0.011 of the axes' width across).
NEAR = (0.02, 0.018)
SIDE_BY_SIDE = 0.016
MARKER: dict[str, Any] = {"s": 40, "edgecolors": "k", "zorder": 2}


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


def dodge_offsets(groups: list[list[int]], n: int) -> NDArray[np.float64]:
    """Each of ``n`` points' offset, in steps, that sets the points of a group side by
    side about their place, in the group's order: −½, +½ for two; −1, 0, +1 for three."""
    out = np.zeros(n)
    for g in groups:
        out[g] = np.arange(len(g)) - 0.5 * (len(g) - 1)
    return out


def group_label(ranks: list[int]) -> str:
    """The label of points that share one place, by rank: ``"1 (3 tied), 4"``."""
    parts = []
    for r in dict.fromkeys(ranks):
        k = ranks.count(r)
        parts.append(f"{r} ({k} tied)" if k > 1 else str(r))
    return ", ".join(parts)


def spread_title(combos: list[Combination]) -> str:
    """The title: how many combinations, and what the points and their bars are."""
    runs = sorted({c.runs for c in combos})
    many = f"{runs[0]}" if len(runs) == 1 else f"{runs[0]}–{runs[-1]}"
    head = f"{len(combos)} parameter combinations"
    if runs[-1] <= 1:
        return f"{head}, one run each (no spread to show)"
    std = np.array([[c.distance_std, c.coverage_std] for c in combos])
    if np.any(np.nan_to_num(std) > 0.0):
        return f"{head}: mean ± std (bars) over {many} runs"
    return f"{head}: mean over {many} runs (std 0)"


def _error_bars(ax: Axes, x: NDArray[Any], y: NDArray[Any], combos: list[Combination]) -> None:
    """± std about each combination's mean, where it has one (two runs or more)."""
    xe = np.array([c.distance_std for c in combos])
    ye = np.array([c.coverage_std for c in combos])
    has = np.isfinite(xe) | np.isfinite(ye)
    if has.any():
        ax.errorbar(
            x[has],
            y[has],
            xerr=np.nan_to_num(xe[has]),
            yerr=np.nan_to_num(ye[has]),
            fmt="none",
            ecolor="grey",
            lw=0.8,
            capsize=3,
            zorder=1,
        )


def _markers(fig: Figure, ax: Axes, x: NDArray[Any], y: NDArray[Any], d: NDArray[Any]) -> None:
    """The points, coloured by ‖σ − σ_eq11‖ ``d`` when it varies (a colour bar), in one
    colour named in the legend when it does not, and grey without one (Kalman)."""
    has = np.isfinite(d)
    if has.any() and np.ptp(d[has]) > 0.0:
        sc = ax.scatter(
            x[has],
            y[has],
            c=d[has],
            cmap="viridis_r",
            vmin=d[has].min(),
            vmax=d[has].max(),
            **MARKER,
        )
        fig.colorbar(
            sc, ax=ax, label="‖σ − σ_eq11‖ over σ_pos, σ_vel, σ_acc, σ_m\n(m, m/s, m/s², m)"
        )
    elif has.any():
        label = f"‖σ − σ_eq11‖ = {float(d[has][0]):g} for all particle filters"
        ax.scatter(x[has], y[has], c="tab:green", label=label, **MARKER)
    if (~has).any():
        ax.scatter(x[~has], y[~has], c="lightgrey", label="no σ (Kalman)", **MARKER)
    if ax.get_legend_handles_labels()[0]:
        # below the axes: the legend covers no point
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), fontsize=8, frameon=False)


def coverage_figure(combos: list[Combination], ranks: list[int]) -> Figure:
    """Coverage against maximum tracking distance, one point per ``ranked`` combination,
    numbered by rank with a key of its varying parameters.  Points that coincide share
    one label and are set side by side in the key's order, so each shows its colour."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = len(combos) if len(combos) <= LABEL_ALL else min(BEST, len(combos))
    header, rows = point_key(combos)  # what varies over the whole grid
    key = [f"rank  {header}"] + [
        f"{r:>4}  {row}" for r, row in zip(ranks[:shown], rows[:shown], strict=True)
    ]
    if shown < len(combos):
        key.append(f"({len(combos) - shown} more, unnumbered)")
    x = np.array([c.distance_mean for c in combos])
    y = np.array([c.coverage_mean for c in combos])
    xe = np.nan_to_num(np.array([c.distance_std for c in combos]))
    ye = np.nan_to_num(np.array([c.coverage_std for c in combos]))
    xlim = padded_limits(*_extent(x, xe), 1.0)
    ylim = padded_limits(*_extent(y, ye), 1.0)
    u = (x[:shown] - xlim[0]) / (xlim[1] - xlim[0])
    v = (y[:shown] - ylim[0]) / (ylim[1] - ylim[0])
    groups = nearby_groups(u, v, NEAR)
    if any(len(g) > 1 for g in groups):
        key.append("(at one place: left to right as listed)")
    # the tied points' rows widen the limits as far as they reach
    step = SIDE_BY_SIDE * (xlim[1] - xlim[0])
    xd = x + step * dodge_offsets(groups, len(x))
    xlim = padded_limits(
        min(xlim[0], float(np.nanmin(xd))), max(xlim[1], float(np.nanmax(xd))), 1.0
    )
    # The key's column: as wide as its longest line (9 pt monospace: under 0.08 in a character)
    key_w = max(1.5, 0.08 * max(map(len, key)) + 0.3)
    fig, (ax, side) = plt.subplots(
        1, 2, figsize=(8.5 + key_w, 6), width_ratios=(8.5, key_w), layout="constrained", dpi=110
    )
    side.axis("off")
    _error_bars(ax, x, y, combos)
    _markers(fig, ax, xd, y, np.array([c.eq11_distance for c in combos]))
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    for g in groups:  # numbered by rank (as in report.md), by the group's last point
        ax.annotate(
            group_label([ranks[i] for i in g]),
            (xd[g[-1]], y[g[0]]),
            xytext=(4, 4),  # up and right: clear of the error bars
            textcoords="offset points",
            va="bottom",
            fontsize=8,
        )
    ax.ticklabel_format(useOffset=False)
    ax.set_xlabel("maximum tracking distance [m]")
    ax.set_ylabel("coverage [%]")
    ax.set_title(spread_title(combos))
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
    return fig


def write_figure(combos: list[Combination], ranks: list[int], path: Path) -> None:
    """Save ``coverage_figure`` as a PNG."""
    import matplotlib.pyplot as plt

    fig = coverage_figure(combos, ranks)
    fig.savefig(path, dpi=110)
    plt.close(fig)
