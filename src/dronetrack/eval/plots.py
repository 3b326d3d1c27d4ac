"""Figures like seed 000's, from a run's frame log (matplotlib, headless)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError
from dronetrack.eval.metrics import CORRECT_RADIUS_M, correct, points_by_distance

__all__ = [
    "KALMAN_FILTERS",
    "PARTICLE_FILTERS",
    "log_limits",
    "lost_stretches",
    "plot_error_and_spread",
    "plot_points_vs_distance",
    "plot_top_view",
    "spread_label",
]

# The tracker kinds (config.TrackerKind) by what their logged spread (frames.csv
# ``sigma_particles``, TrackEstimate.spread) is.
PARTICLE_FILTERS = frozenset({"pf-delta", "pf-cv", "pf-ca", "pf-systematic"})
KALMAN_FILTERS = frozenset(
    {"ekf-dogru", "ekf-catalano", "ekf-catalano-mod", "ekf-cv", "kf-ca", "aekf-ca"}
)
LOST_COLOUR = "0.82"  # the shading of the frames the tracker reports as not tracked


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _plain(value: float, _pos: int | None = None) -> str:
    return f"{value:g}"


def _minor(value: float, _pos: int | None = None) -> str:
    """Minor log ticks: label 2 and 5 × 10ᵏ only."""
    mantissa = value / 10.0 ** np.floor(np.log10(value)) if value > 0 else 0.0
    return f"{value:g}" if round(mantissa) in (2, 5) else ""


def spread_label(kind: str) -> str:
    """What a tracker's logged spread is: the particles' σ for a particle filter,
    the largest position standard deviation √max(P_xx, P_yy, P_zz) for a Kalman one."""
    if kind in PARTICLE_FILTERS:
        return "σ_particles"
    if kind in KALMAN_FILTERS:
        return r"$\sqrt{\max(P_{xx}, P_{yy}, P_{zz})}$"
    raise ConfigError(f"unknown tracker kind {kind!r} for the spread's label")


def lost_stretches(tracked: NDArray[np.bool_]) -> list[tuple[int, int]]:
    """The runs of frames not tracked, as half-open index ranges [i₀, i₁)."""
    lost = ~np.asarray(tracked, dtype=bool)
    edges = np.flatnonzero(np.diff(np.r_[False, lost, False].astype(np.int8)))
    return [(int(i0), int(i1)) for i0, i1 in zip(edges[0::2], edges[1::2], strict=True)]


def _aspect_size(x: NDArray[Any], y: NDArray[Any]) -> tuple[float, float]:
    """A figure size whose axes fit data of this extent drawn at equal scale."""
    ok = np.isfinite(x) & np.isfinite(y)
    if not np.any(ok):
        return 8.0, 7.0
    w = float(np.ptp(x[ok])) or 1.0
    h = float(np.ptp(y[ok])) or 1.0
    ratio = float(np.clip(w / h, 0.6, 2.2))
    # axes about 6 in tall for tall data, 10 in wide for wide data; room for the colour
    # bar beside and the legend below
    ax_h = min(6.0, 10.0 / ratio)
    return ax_h * ratio + 2.2, ax_h + 2.3


def plot_top_view(
    a: dict[str, NDArray[Any]], out: Path, title: str = "", radius: float = CORRECT_RADIUS_M
) -> None:
    """The flight from above (Fig. 2): the truth coloured by the points returned from
    the target, the estimate beside it, the stretches the tracker lost shaded, and
    the frame of the maximum tracking distance (3-D error within ``radius``) marked."""
    plt = _pyplot()
    x, y, n = a["gt_x"], a["gt_y"], a["n_target_points"]
    ex, ey = a["est_x"], a["est_y"]
    fig, ax = plt.subplots(
        figsize=_aspect_size(np.r_[x, ex, 0.0], np.r_[y, ey, 0.0]), layout="constrained", dpi=110
    )
    # The lost stretches lie along the truth, or along the estimate where it is unknown.
    known = np.isfinite(x) & np.isfinite(y)
    px, py = np.where(known, x, ex), np.where(known, y, ey)
    for k, (i0, i1) in enumerate(lost_stretches(a["tracked"])):
        ax.plot(
            px[i0:i1],
            py[i0:i1],
            color=LOST_COLOUR,
            lw=9,
            solid_capstyle="round",
            zorder=1,
            label="not tracked" if k == 0 else None,
        )
    unknown, none, some = known & (n < 0), known & (n == 0), known & (n > 0)
    if np.any(unknown):
        ax.scatter(x[unknown], y[unknown], s=6, c="0.5", label="truth (returns unknown)", zorder=2)
    if np.any(none):
        ax.scatter(x[none], y[none], s=6, c="red", label="truth, no returns", zorder=2)
    if np.any(some):
        sc = ax.scatter(
            x[some],
            y[some],
            s=8,
            c=n[some],
            cmap="viridis",
            norm=plt.matplotlib.colors.LogNorm(vmin=1, vmax=max(2, int(n.max()))),
            label="truth",
            zorder=2,
        )
        fig.colorbar(sc, ax=ax, label="points on the target per frame", shrink=0.8)
    ax.plot(ex, ey, color="tab:orange", lw=1.2, label="estimate", zorder=3)
    ax.plot(0, 0, "k^", ms=9, ls="none", label="turret", zorder=4)
    err = np.column_stack([ex - x, ey - y, a["est_z"] - a["gt_z"]])
    ok = correct(err, radius) & np.isfinite(a["range_m"])
    if np.any(ok):
        far = np.argmax(np.where(ok, a["range_m"], -np.inf))
        ax.plot(
            x[far],
            y[far],
            marker="*",
            ms=14,
            mfc="gold",
            mec="k",
            ls="none",
            zorder=5,
            label=f"max tracking distance {a['range_m'][far]:.3g} m",
        )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title or "top view")
    # Below the axes: the legend covers no part of the flight and no title.
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=3, fontsize=8, frameon=False)
    # The equal aspect widens the limits when drawn, which can lengthen the tick
    # labels: lay out once more with the final limits before saving.
    fig.canvas.draw()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def log_limits(*series: NDArray[Any], margin: float = 0.05) -> tuple[float, float]:
    """Limits of a log axis spanning every finite positive value of the series, with
    ``margin`` of the span (in decades) beyond each end; (0.1, 10) without any value."""
    values = np.concatenate([np.ravel(np.asarray(v, dtype=np.float64)) for v in series])
    values = values[np.isfinite(values) & (values > 0)]
    if len(values) == 0:
        return 0.1, 10.0
    lo, hi = np.log10(values.min()), np.log10(values.max())
    pad = margin * max(hi - lo, 1.0)
    return float(10.0 ** (lo - pad)), float(10.0 ** (hi + pad))


def plot_error_and_spread(
    a: dict[str, NDArray[Any]],
    threshold: float,
    out: Path,
    title: str = "",
    *,
    kind: str,
) -> None:
    """Position error and the tracker's spread against time (Figs. 8 and 12), with the
    frames not tracked shaded.

    ``kind`` names the tracker: a particle filter's spread is σ_particles, drawn with
    its σ_threshold (tracked below it); a Kalman filter's is √max(P_xx, P_yy, P_zz)
    and ``threshold`` is not drawn, as each decides "tracked" by its own rule
    (covariance limits, time since the last fix), which the shading shows."""
    spread = spread_label(kind)
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(10, 4.8), layout="constrained", dpi=110)
    t = a["t"]
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.1
    for k, (i0, i1) in enumerate(lost_stretches(a["tracked"])):
        ax.axvspan(
            t[i0] - 0.5 * dt,
            t[i1 - 1] + 0.5 * dt,
            color=LOST_COLOUR,
            alpha=0.6,
            lw=0,
            label="not tracked" if k == 0 else None,
        )
    err = np.sqrt(
        (a["est_x"] - a["gt_x"]) ** 2
        + (a["est_y"] - a["gt_y"]) ** 2
        + (a["est_z"] - a["gt_z"]) ** 2
    )
    ax.plot(t, err, color="tab:blue", lw=1, label="error ‖estimate − truth‖")
    ax.set_yscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("error [m]", color="tab:blue")
    ax2 = ax.twinx()
    what = spread if kind in PARTICLE_FILTERS else f"{spread}, the largest position σ"
    ax2.plot(t, a["sigma_particles"], color="tab:orange", lw=1, label=what)
    if kind in PARTICLE_FILTERS:
        ax2.axhline(
            threshold, color="tab:orange", ls="--", lw=1, label=f"σ_threshold = {threshold:.2f} m"
        )
    ax2.set_yscale("log")
    ax2.set_ylabel(f"{spread} [m]", color="tab:orange")
    # Both are metres: the two axes get one scale, so the spread and its threshold read
    # the same against either (with a scale of its own, a line at σ_threshold on the
    # right would read as another value on the left).
    drawn = [err, a["sigma_particles"]] + (
        [np.array([threshold])] if kind in PARTICLE_FILTERS else []
    )
    lo, hi = log_limits(*drawn)
    ax.set_ylim(lo, hi)
    ax2.set_ylim(lo, hi)
    for axis in (ax.yaxis, ax2.yaxis):  # 0.1 and 2, not 10⁻¹ and 2 × 10⁰
        axis.set_major_formatter(plt.matplotlib.ticker.FuncFormatter(_plain))
        axis.set_minor_formatter(plt.matplotlib.ticker.FuncFormatter(_minor))
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(
        h1 + h2,
        l1 + l2,
        loc="lower center",
        bbox_to_anchor=(0.5, 1.0),
        ncol=4,
        fontsize=8,
        frameon=False,
    )
    ax.set_title(title or f"error and {spread} ({kind})", pad=24)
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_points_vs_distance(
    a: dict[str, NDArray[Any]], out: Path, title: str = "", bin_m: float | None = None
) -> None:
    """Points returned from the target against its range (Fig. 7), with the mean per
    range bin (``metrics.points_by_distance``: without ``bin_m``, scaled to the data)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5), layout="constrained", dpi=110)
    r, n = a["range_m"], a["n_target_points"].astype(float)
    known = np.isfinite(r) & (n >= 0)
    ax.scatter(r[known], n[known], s=4, alpha=0.4, label="frames")
    rows = points_by_distance(r[known], n[known], bin_m)
    if rows:
        lo = np.array([row["range_from_m"] for row in rows])
        hi = np.array([row["range_to_m"] for row in rows])
        mean = np.array([row["points_mean"] for row in rows])
        width = hi[0] - lo[0]
        # only occupied bins are listed: break the line across the empty ones
        gap = np.flatnonzero(lo[1:] > hi[:-1] + 1e-9 * width) + 1
        centre = np.insert(0.5 * (lo + hi), gap, np.nan)
        ax.plot(
            centre,
            np.insert(mean, gap, np.nan),
            "o-",
            color="tab:red",
            ms=4,
            label=f"mean per {width:g} m bin",
        )
        ax.legend(fontsize=8)
    else:
        ax.text(
            0.5,
            0.5,
            "no frame with both a range and a point count",
            transform=ax.transAxes,
            ha="center",
        )
    ax.ticklabel_format(axis="x", useOffset=False)
    ax.set_xlabel("range [m]")
    ax.set_ylabel("points on the target per frame")
    ax.set_title(title or "points against distance")
    fig.savefig(out, dpi=110)
    plt.close(fig)
