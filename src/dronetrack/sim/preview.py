"""A preview of a simulated run: a bird's-eye view and the sensor's own view."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dronetrack.geometry.transforms import FloatArray, azimuth_elevation
from dronetrack.sim.primitives import BOX, CYLINDER, ELLIPSOID
from dronetrack.sim.scene import Scene
from dronetrack.types import Frame

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

    from dronetrack.sim.world import FrameTruth

__all__ = ["legend_below", "plot_preview", "preview_figure"]

MAX_POINTS = 60_000
# The views' place on the figure, in fractions of it (subplots_adjust)
MARGINS = {"left": 0.05, "right": 0.96, "bottom": 0.15, "top": 0.88, "wspace": 0.3}


def _draw_scene(ax: Axes, scene: Scene) -> None:
    from matplotlib.patches import Ellipse, Polygon

    p = scene.prims
    x0, y0, x1, y1 = scene.extent
    view_area = (x1 - x0) * (y1 - y0)
    for k in range(len(p)):
        c, h, R = p.center[k], p.half[k], p.rotation[k]
        if 4 * h[0] * h[1] > 0.25 * view_area:
            continue  # floors and ceilings would hide everything
        if p.kind[k] == BOX:
            corners = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]]) * h[:2]
            xy = corners @ R[:2, :2].T + c[:2]
            ax.add_patch(Polygon(xy, closed=True, fc="0.75", ec="0.4", lw=0.5, zorder=1))
        elif p.kind[k] in (ELLIPSOID, CYLINDER):
            ax.add_patch(
                Ellipse(
                    tuple(c[:2]),
                    2 * h[0],
                    2 * h[1],
                    fc="#b5d6a7",
                    ec="#5a8a4a",
                    lw=0.5,
                    zorder=1,
                )
            )


def _draw_sensor_view(fig: Figure, view: Axes, last: Frame, truth: FrameTruth) -> None:
    """The frame in the sensor's azimuth/elevation, coloured by range, target returns circled."""
    from matplotlib.colors import LogNorm

    az, el = np.degrees(azimuth_elevation(last.points))
    if len(last):
        r = np.linalg.norm(last.points, axis=1)
        norm = LogNorm(vmin=max(float(r.min()), 0.5), vmax=max(float(r.max()), 1.0))
        sc = view.scatter(az, el, c=r, s=0.5, cmap="plasma", norm=norm)
        fig.colorbar(sc, ax=view, label="range [m]", shrink=0.8)
        h = truth.hit_target
        label = f"target returns ({int(h.sum())})"
        view.scatter(az[h], el[h], s=30, facecolors="none", edgecolors="red", label=label)
    T = last.poses[-1]
    rel = T[:3, :3].T @ (truth.target_position - T[:3, 3])
    taz, tel = np.degrees(azimuth_elevation(rel))
    view.plot(taz, tel, "r+", ms=14, label="true target direction")
    view.set_title(f"sensor view, last frame (t = {last.stamp:.1f} s, {len(last)} points)")
    legend_below(fig, view)
    if len(last) and np.ptp(az) < 120:
        view.set_aspect("equal")


LEGEND_DROP_PT = 32.0  # from the axes' bottom edge down to the legend: the tick labels
# and the x label (10 pt) lie between


def legend_below(fig: Figure, ax: Axes) -> None:
    """The axes' legend under its x label, outside the axes: it covers no data."""
    from matplotlib.transforms import offset_copy

    below = offset_copy(ax.transAxes, fig=fig, y=-LEGEND_DROP_PT, units="points")
    ax.legend(
        loc="upper center",
        bbox_to_anchor=(0.5, 0.0),
        bbox_transform=below,
        ncol=3,
        fontsize=8,
        frameon=False,
    )


def preview_figure(
    scene: Scene,
    frames: Sequence[Frame],
    truths: Sequence[FrameTruth],
    world: Sequence[FloatArray],
    title: str = "",
) -> Figure:
    """A bird's-eye view of all returns, and the last frame as the sensor saw it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    # A fixed layout (no layout engine: with axes of a fixed shape those drift from one
    # drawing to the next): margins for the tick labels, the x labels and the legends
    # below, and between the views room for a colour bar and the next y label.
    fig, (top, view) = plt.subplots(1, 2, figsize=(15, 7), width_ratios=(1.1, 1), dpi=110)
    fig.subplots_adjust(**MARGINS)
    pts = np.concatenate(world) if world else np.empty((0, 3))
    hit = np.concatenate([tr.hit_target for tr in truths]) if truths else np.empty(0, bool)
    rng = np.random.default_rng(0)
    bg = np.flatnonzero(~hit)
    if len(bg) > MAX_POINTS:
        bg = rng.choice(bg, MAX_POINTS, replace=False)
    _draw_scene(top, scene)
    sc = top.scatter(
        pts[bg, 0],
        pts[bg, 1],
        c=pts[bg, 2],
        s=0.3,
        cmap="viridis",
        zorder=2,
        vmin=0.0,
        vmax=max(5.0, float(np.percentile(pts[bg, 2], 99)) if len(bg) else 5.0),
    )
    fig.colorbar(sc, ax=top, label="height [m]", shrink=0.8)
    path = np.array([tr.target_position for tr in truths])
    if len(path):
        top.plot(
            path[:, 0], path[:, 1], "-", color="tab:orange", lw=1.2, label="target path", zorder=3
        )
    top.scatter(pts[hit, 0], pts[hit, 1], s=6, c="red", label="returns from the target", zorder=4)
    if frames:
        base = frames[0].poses[0, :3, 3]
        top.plot(base[0], base[1], "k^", ms=8, label="sensor", zorder=5)
    x0, y0, x1, y1 = scene.extent
    top.set_xlim(x0, x1)
    top.set_ylim(y0, y1)
    top.set_aspect("equal")
    top.set_xlabel("x [m]")
    top.set_ylabel("y [m]")
    top.set_title("bird's-eye view, all frames")
    legend_below(fig, top)

    if frames:
        _draw_sensor_view(fig, view, frames[-1], truths[-1])
    view.set_xlabel("azimuth [deg]")
    view.set_ylabel("elevation [deg]")
    view.invert_xaxis()  # left of the sensor (+y) on the left
    fig.suptitle(title)
    return fig


def plot_preview(
    scene: Scene,
    frames: Sequence[Frame],
    truths: Sequence[FrameTruth],
    world: Sequence[FloatArray],
    out: Path,
    title: str = "",
) -> None:
    """Save ``preview_figure`` as a PNG."""
    import matplotlib.pyplot as plt

    fig = preview_figure(scene, frames, truths, world, title)
    # The views keep their shapes (equal scale), which leaves margins: trim them.
    fig.savefig(out, dpi=110, bbox_inches="tight", pad_inches=0.15)
    plt.close(fig)
