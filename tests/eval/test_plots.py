"""The run figures (top view, error and spread, points against range) on synthetic logs:
what a reader needs is on them and nothing misleading is."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Rectangle
from matplotlib.text import Text
from numpy.typing import NDArray

from dronetrack.errors import ConfigError
from dronetrack.eval.log import TrackLog
from dronetrack.eval.plots import (
    KALMAN_FILTERS,
    PARTICLE_FILTERS,
    log_limits,
    lost_stretches,
    plot_error_and_spread,
    plot_points_vs_distance,
    plot_top_view,
    spread_label,
)

PERIOD = 0.1


def _flight(lost: slice | None = None, n: int = 200) -> dict[str, NDArray[Any]]:
    """A drone flying out from (15, 0) to (30, −40), then north to (30, 40), the turret at
    the origin: the farthest point (the largest range) is the last, at the top of the
    view.  The estimate is 0.5 m east of the truth; frames in ``lost`` are not tracked."""
    s = np.linspace(0.0, 1.0, n)
    leg = s < 0.5
    x = np.where(leg, 15.0 + 30.0 * s, 30.0)
    y = np.where(leg, -80.0 * s, -40.0 + 160.0 * (s - 0.5))
    log = TrackLog()
    for k in range(n):
        truth = np.array([x[k], y[k], 10.0])
        log.append(
            t=10.0 + k * PERIOD,
            gt=truth,
            est=truth + np.array([0.5, 0.0, 0.0]),
            tracked=not (lost is not None and lost.start <= k < lost.stop),
            sigma=0.3 + 0.01 * k,
            n_points=50,
            n_target_points=int(max(0, 120 - k)),
            range_m=float(np.linalg.norm(truth)),
            pan=0.0,
            tilt=0.0,
            step_ms=1.0,
        )
    return log.arrays()


def _texts(fig: Figure) -> list[Text]:
    return [t for t in fig.findobj(Text) if t.get_visible() and t.get_text()]


def _all_text(fig: Figure) -> str:
    return "\n".join(t.get_text() for t in _texts(fig))


def test_top_view_max_distance_note_clear_of_the_title(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    plot_top_view(_flight(), tmp_path / "top.png", "default: a long title over the top view")
    fig = keep_figures()
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    title = fig.axes[0].title.get_window_extent(renderer)
    notes = [t for t in _texts(fig) if "max tracking distance" in t.get_text()]
    assert notes, "the maximum tracking distance is not on the figure"
    figure_box = fig.bbox
    for note in notes:
        box = note.get_window_extent(renderer)
        assert not box.overlaps(title), (box, title)
        # and it is on the figure, not cut off at an edge
        assert figure_box.x0 <= box.x0
        assert box.x1 <= figure_box.x1
        assert figure_box.y0 <= box.y0
        assert box.y1 <= figure_box.y1
    # The note gives the right distance: the last frame, at range √(30² + 40² + 10²).
    assert any(f"{np.sqrt(30**2 + 40**2 + 10**2):.3g} m" in t.get_text() for t in notes)


def _lines_through(fig: Figure, x: NDArray[Any], y: NDArray[Any]) -> list[Line2D]:
    ax = fig.axes[0]
    return [
        line
        for line in ax.get_lines()
        if len(line.get_xdata()) == len(x)
        and np.allclose(np.asarray(line.get_xdata(), dtype=float), x)
        and np.allclose(np.asarray(line.get_ydata(), dtype=float), y)
    ]


def test_top_view_draws_the_estimate_and_shades_the_lost_stretches(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    a = _flight(lost=slice(120, 150))
    plot_top_view(a, tmp_path / "top.png")
    fig = keep_figures()
    assert _lines_through(fig, a["est_x"], a["est_y"]), "no estimate line"
    # One shaded stretch, over exactly the lost frames of the truth path
    shade = _lines_through(fig, a["gt_x"][120:150], a["gt_y"][120:150])
    assert len(shade) == 1
    assert shade[0].get_linewidth() > 3.0  # a band under the path, not a thin line
    labels = fig.axes[0].get_legend_handles_labels()[1]
    assert "estimate" in labels
    assert "not tracked" in labels


def test_top_view_without_lost_frames_shades_nothing(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    plot_top_view(_flight(), tmp_path / "top.png")
    fig = keep_figures()
    assert "not tracked" not in fig.axes[0].get_legend_handles_labels()[1]


def test_lost_stretches_are_the_runs_of_untracked_frames() -> None:
    tracked = np.array([False, False, True, True, False, True, False])
    assert lost_stretches(tracked) == [(0, 2), (4, 5), (6, 7)]
    assert lost_stretches(np.ones(4, dtype=bool)) == []
    assert lost_stretches(np.zeros(3, dtype=bool)) == [(0, 3)]


def _shaded_spans(fig: Figure) -> list[tuple[float, float]]:
    """The time spans shaded across the error axes (axvspan rectangles)."""
    return [
        (r.get_x(), r.get_x() + r.get_width())
        for r in fig.axes[0].patches
        if isinstance(r, Rectangle)
    ]


@pytest.mark.parametrize("kind", sorted(PARTICLE_FILTERS))
def test_error_figure_of_a_particle_filter_names_the_particle_spread(
    tmp_path: Path, keep_figures: Callable[[], Figure], kind: str
) -> None:
    plot_error_and_spread(_flight(), 0.75, tmp_path / "err.png", kind=kind)
    text = _all_text(keep_figures())
    assert "σ_particles" in text
    assert "σ_threshold = 0.75 m" in text


@pytest.mark.parametrize("kind", sorted(PARTICLE_FILTERS))
def test_sigma_threshold_reads_the_same_on_both_axes(
    tmp_path: Path, keep_figures: Callable[[], Figure], kind: str
) -> None:
    threshold = 0.75
    plot_error_and_spread(_flight(), threshold, tmp_path / "err.png", kind=kind)
    fig = keep_figures()
    left, right = fig.axes[0], fig.axes[1]
    # the threshold line belongs to the spread's axis (the right), at y = σ_threshold
    flat = [
        line
        for line in right.get_lines()
        if len(set(np.asarray(line.get_ydata(), dtype=float))) == 1
    ]
    assert len(flat) == 1
    assert float(np.asarray(flat[0].get_ydata(), dtype=float)[0]) == pytest.approx(threshold)
    # where it is drawn reads as σ_threshold against the left axis too (both are metres)
    screen = right.transData.transform((0.5 * sum(right.get_xlim()), threshold))
    on_left = left.transData.inverted().transform(screen)[1]
    assert on_left == pytest.approx(threshold, rel=1e-6)
    assert left.get_yscale() == right.get_yscale() == "log"
    assert left.get_ylim() == pytest.approx(right.get_ylim())
    # and every drawn value lies within the limits: errors of 0.5 m, spreads 0.3-2.29 m
    lo, hi = left.get_ylim()
    assert lo < 0.3
    assert hi > 0.3 + 0.01 * 199


def test_log_limits_span_every_positive_value_with_a_margin() -> None:
    # 0.01 to 10: three decades, 5 % of them (0.15 decade) beyond each end
    lo, hi = log_limits(np.array([0.01, 1.0, np.nan, 0.0]), np.array([10.0, -1.0]))
    assert lo == pytest.approx(10.0**-2.15)
    assert hi == pytest.approx(10.0**1.15)
    # one value: a decade's span about it, at least
    lo, hi = log_limits(np.array([0.5]))
    assert lo == pytest.approx(0.5 * 10.0**-0.05)
    assert hi == pytest.approx(0.5 * 10.0**0.05)
    assert log_limits(np.array([np.nan, 0.0])) == (0.1, 10.0)


@pytest.mark.parametrize("kind", sorted(KALMAN_FILTERS))
def test_error_figure_of_a_kalman_filter_names_its_covariance(
    tmp_path: Path, keep_figures: Callable[[], Figure], kind: str
) -> None:
    plot_error_and_spread(_flight(lost=slice(50, 80)), 0.75, tmp_path / "err.png", kind=kind)
    fig = keep_figures()
    text = _all_text(fig)
    assert "particle" not in text
    assert "σ_threshold" not in text
    # The spread is √max(P_xx, P_yy, P_zz), on the right axis and in the legend
    assert "P_{xx}" in fig.axes[1].get_ylabel()
    assert any("P_{xx}" in t for t in fig.axes[0].get_legend_handles_labels()[1] + [text])
    # no horizontal threshold line on the spread axis
    flat = [
        line
        for line in fig.axes[1].get_lines()
        if len(set(np.asarray(line.get_ydata(), dtype=float))) == 1
    ]
    assert flat == []
    # The frames not tracked (5.0 s to 7.9 s after the start) are shaded, and only those
    spans = _shaded_spans(fig)
    assert len(spans) == 1
    assert spans[0][0] == pytest.approx(15.0 - 0.5 * PERIOD)
    assert spans[0][1] == pytest.approx(17.9 + 0.5 * PERIOD)


def test_spread_label_refuses_an_unknown_tracker() -> None:
    with pytest.raises(ConfigError, match="pf-nonsense"):
        spread_label("pf-nonsense")
    assert spread_label("pf-cv") == "σ_particles"
    assert "particles" not in spread_label("ekf-cv")


def _counts_against(ranges: NDArray[np.float64]) -> dict[str, NDArray[Any]]:
    n = len(ranges)
    return {
        "range_m": ranges,
        "n_target_points": np.round(400.0 / ranges**2).astype(np.int64),
        "t": np.arange(n) * PERIOD,
    }


def _mean_line(fig: Figure) -> NDArray[np.float64]:
    """The x of the per-bin means (the red line), finite entries only."""
    lines = [line for line in fig.axes[0].get_lines() if "mean per" in line.get_label()]
    assert len(lines) == 1
    x = np.asarray(lines[0].get_xdata(), dtype=float)
    return x[np.isfinite(x)]


def test_points_against_an_indoor_range_get_several_bins(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    ranges = np.linspace(1.0, 6.0, 300)
    plot_points_vs_distance(_counts_against(ranges), tmp_path / "pts.png")
    centres = _mean_line(keep_figures())
    assert len(centres) > 3
    assert centres.min() >= 1.0 - 0.5
    assert centres.max() <= 6.0 + 0.5


def test_points_against_a_far_range_get_sensible_bins(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    ranges = np.linspace(20.0, 300.0, 500)
    plot_points_vs_distance(_counts_against(ranges), tmp_path / "pts.png")
    centres = _mean_line(keep_figures())
    assert 8 <= len(centres) <= 22
    # equal, 1-2-5 wide bins: 280 m / 20 → 20 m
    np.testing.assert_allclose(np.diff(centres), 20.0)
