"""render's preview.png, as a reader sees it: every label on the figure, and the legends
clear of the scene and of the returns."""

from __future__ import annotations

import functools
from collections.abc import Callable
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
from matplotlib.axes import Axes
from matplotlib.backend_bases import RendererBase
from matplotlib.figure import Figure
from matplotlib.legend import Legend
from matplotlib.transforms import Bbox

from dronetrack.config.scenarios import SCENARIOS
from dronetrack.jobs.render import Rendering, render_scenario
from dronetrack.sim.preview import plot_preview


@functools.cache
def _rendering(scenario: str) -> Rendering:
    return render_scenario(SCENARIOS[scenario].model_copy(update={"duration_s": 0.3}))


def _preview(scenario: str, out: Path, keep: Callable[[], Figure]) -> Figure:
    r = _rendering(scenario)
    world = [f.world_points() for f in r.frames]
    plot_preview(r.scene, r.frames, r.truths, world, out, title=scenario)
    return keep()


def _axes(fig: Figure) -> list[Axes]:
    """The two plots (not the colour bars): the bird's-eye view and the sensor view."""
    plots = [ax for ax in fig.axes if ax.get_legend() is not None]
    assert len(plots) == 2
    return plots


def _inside(box: Bbox, outer: Bbox) -> bool:
    return bool(
        outer.x0 <= box.x0 and box.x1 <= outer.x1 and outer.y0 <= box.y0 and box.y1 <= outer.y1
    )


def _within(pts: np.ndarray, box: Bbox) -> np.ndarray:
    x, y = pts[:, 0], pts[:, 1]
    return (box.x0 <= x) & (x <= box.x1) & (box.y0 <= y) & (y <= box.y1)


def _points_in(ax: Axes, box: Bbox) -> int:
    """How many of the axes' drawn points and line vertices lie within ``box``, on screen."""
    xy = [np.asarray(c.get_offsets(), dtype=float) for c in ax.collections]
    xy += [np.asarray(line.get_xydata(), dtype=float) for line in ax.get_lines()]
    pts = ax.transData.transform(np.concatenate([a.reshape(-1, 2) for a in xy]))
    return int(np.count_nonzero(_within(pts, ax.bbox) & _within(pts, box)))


# an outdoor scene 300 m wide, and a room 8 m wide
@pytest.mark.parametrize("scenario", ["default", "indoor-horizontal"])
@pytest.mark.slow
def test_preview_labels_lie_on_the_figure(
    scenario: str, tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    fig = _preview(scenario, tmp_path / "preview.png", keep_figures)
    renderer: RendererBase = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    for ax in _axes(fig):
        for label in (ax.xaxis.label, ax.yaxis.label, ax.title):
            assert label.get_text()
            box = label.get_window_extent(renderer)
            assert _inside(box, fig.bbox), (label.get_text(), box, fig.bbox)
        legend = ax.get_legend()
        assert isinstance(legend, Legend)
        assert _inside(legend.get_window_extent(renderer), fig.bbox)
    # No label of one axes (the views and their colour bars) runs into another's
    labels = [
        (i, label.get_window_extent(renderer))
        for i, ax in enumerate(fig.axes)
        for label in (ax.xaxis.label, ax.yaxis.label)
        if label.get_text()
    ]
    assert len(labels) == 6
    for i, box in labels:
        assert _inside(box, fig.bbox)
        assert not any(j != i and box.overlaps(other) for j, other in labels)


def test_preview_legends_cover_neither_the_scene_nor_the_returns(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    fig = _preview("default", tmp_path / "preview.png", keep_figures)
    renderer: RendererBase = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    top, view = _axes(fig)
    assert top.get_title().startswith("bird's-eye")
    # the default scene's trees and buildings are drawn, and some lie within the view
    objects = [Bbox.intersection(p.get_window_extent(renderer), top.bbox) for p in top.patches]
    shown = [box for box in objects if box is not None and box.width > 0 and box.height > 0]
    assert len(shown) > 10
    for ax in (top, view):
        legend = ax.get_legend().get_window_extent(renderer)
        assert not any(legend.overlaps(box) for box in shown), "a legend covers the scene"
        assert _points_in(ax, legend) == 0, f"{ax.get_title()}: the legend covers returns"
