"""Figures like seed 000's, from a run's frame log (matplotlib, headless)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.eval.metrics import CORRECT_RADIUS_M, correct

__all__ = ["plot_error_and_spread", "plot_points_vs_distance", "plot_top_view"]


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_top_view(
    a: dict[str, NDArray[Any]], out: Path, title: str = "", radius: float = CORRECT_RADIUS_M
) -> None:
    """The flight from above, coloured by the points returned from the target (Fig. 2),
    with the maximum tracking distance (3-D error within ``radius``) marked."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 7))
    x, y, n = a["gt_x"], a["gt_y"], a["n_target_points"]
    none = n <= 0
    ax.scatter(x[none], y[none], s=6, c="red", label="no returns")
    sc = ax.scatter(
        x[~none],
        y[~none],
        s=8,
        c=n[~none],
        cmap="viridis",
        norm=plt.matplotlib.colors.LogNorm(vmin=1, vmax=max(2, int(n.max()))),
    )
    fig.colorbar(sc, ax=ax, label="points on the target per frame", shrink=0.6)
    ax.plot(0, 0, "k^", ms=9, label="turret")
    err = np.column_stack([a["est_x"] - x, a["est_y"] - y, a["est_z"] - a["gt_z"]])
    ok = correct(err, radius) & np.isfinite(a["range_m"])
    if np.any(ok):
        far = np.argmax(np.where(ok, a["range_m"], -np.inf))
        ax.annotate(
            f"max tracking distance {a['range_m'][far]:.0f} m",
            (x[far], y[far]),
            xytext=(-150, 20),
            textcoords="offset points",
            arrowprops={"arrowstyle": "->"},
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title or "top view")
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_error_and_spread(
    a: dict[str, NDArray[Any]], threshold: float, out: Path, title: str = ""
) -> None:
    """Position error and σ_particles against time, with σ_threshold (Figs. 8 and 12)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(10, 4.5))
    err = np.sqrt(
        (a["est_x"] - a["gt_x"]) ** 2
        + (a["est_y"] - a["gt_y"]) ** 2
        + (a["est_z"] - a["gt_z"]) ** 2
    )
    ax.plot(a["t"], err, color="tab:blue", lw=1, label="error ‖estimate − truth‖")
    ax.set_yscale("log")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("error [m]", color="tab:blue")
    ax2 = ax.twinx()
    ax2.plot(a["t"], a["sigma_particles"], color="tab:orange", lw=1, label="σ_particles")
    ax2.axhline(
        threshold, color="tab:orange", ls="--", lw=1, label=f"σ_threshold = {threshold:.2f} m"
    )
    ax2.set_yscale("log")
    ax2.set_ylabel("σ_particles [m]", color="tab:orange")
    lines = ax.get_legend_handles_labels()
    lines2 = ax2.get_legend_handles_labels()
    ax.legend(lines[0] + lines2[0], lines[1] + lines2[1], loc="upper right", fontsize=8)
    ax.set_title(title or "error and particle spread")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)


def plot_points_vs_distance(
    a: dict[str, NDArray[Any]], out: Path, title: str = "", bin_m: float = 10.0
) -> None:
    """Points returned from the target against its range (Fig. 7)."""
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.5))
    r, n = a["range_m"], a["n_target_points"].astype(float)
    ax.scatter(r, n, s=4, alpha=0.4, label="frames")
    ok = np.isfinite(r)
    if np.any(ok):
        edges = np.arange(0.0, r[ok].max() + bin_m, bin_m)
        which = np.digitize(r[ok], edges) - 1
        centre = 0.5 * (edges[:-1] + edges[1:])
        means = [
            n[ok][which == b].mean() if np.any(which == b) else np.nan for b in range(len(centre))
        ]
        ax.plot(centre, means, "o-", color="tab:red", label=f"mean per {bin_m:g} m")
    ax.set_xlabel("range [m]")
    ax.set_ylabel("points on the target per frame")
    ax.set_title(title or "points against distance")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    plt.close(fig)
