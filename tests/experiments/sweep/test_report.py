"""``sweep-report``'s figure on hand-written result lines: readable axes, an honest
colour scale, and every point named."""

from __future__ import annotations

import csv
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
from matplotlib.collections import PathCollection
from matplotlib.container import ErrorbarContainer
from matplotlib.figure import Figure
from matplotlib.text import Annotation, Text

from dronetrack.experiments.sweep.figure import (
    dodge_offsets,
    group_label,
    nearby_groups,
    padded_limits,
    point_key,
    spread_title,
)
from dronetrack.experiments.sweep.report import summarise, write_report
from dronetrack.experiments.sweep.summary import rank_numbers, ranked

EQ11 = {"sigma_pos": 0.5, "sigma_vel": 0.5, "sigma_acc": 0.0, "sigma_m": 0.2}


def _row(
    key: str,
    params: dict[str, Any],
    coverage: float,
    distance: float,
    sigma_pos: float,
    tracker: str = "pf-ca",
) -> dict[str, Any]:
    return {
        "key": key,
        "params": params,
        "tracker": tracker,
        "metrics": {"coverage_pct": coverage, "max_tracking_distance_m": distance},
        "sigma": {**EQ11, "sigma_pos": sigma_pos},
        "eq11": EQ11,
    }


def _write(folder: Path, rows: list[dict[str, Any]]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "results.jsonl").write_text("".join(json.dumps(r) + "\n" for r in rows))
    return folder


def _close_distances(folder: Path, sigma_pos: list[float]) -> Path:
    """Four combinations whose maximum tracking distances differ by fractions of a
    millimetre (the flights reach the same far point), as a real sweep gives."""
    rows = [
        _row(
            f"k{i}",
            {"particles": p, "tracker": t},
            coverage=60.0 + 5.0 * i,
            distance=19.0891 + 1e-5 * i,
            sigma_pos=sigma_pos[i],
        )
        for i, (p, t) in enumerate(
            [(500, "pf-delta"), (500, "pf-cv"), (1000, "pf-delta"), (1000, "pf-cv")]
        )
    ]
    return _write(folder, rows)


def _colour_bars(fig: Figure) -> list[tuple[float, float]]:
    """The limits of every colour bar on the figure, as drawn."""
    bars = []
    for ax in fig.axes:
        for coll in ax.collections:
            bar = getattr(coll, "colorbar", None)
            if bar is not None:
                bars.append(bar.ax.get_ylim())
    return [(float(lo), float(hi)) for lo, hi in bars]


def test_axes_carry_no_offset(tmp_path: Path, keep_figures: Callable[[], Figure]) -> None:
    write_report(_close_distances(tmp_path / "s", [0.4, 0.5, 0.6, 0.5]))
    fig = keep_figures()
    ax = fig.axes[0]
    assert ax.xaxis.get_offset_text().get_text() == ""
    assert ax.yaxis.get_offset_text().get_text() == ""
    # ...and the ticks are readable distances, not a sub-millimetre scale
    lo, hi = ax.get_xlim()
    assert hi - lo >= 1.0
    assert lo <= 19.0891 <= hi


def test_a_constant_distance_from_eq11_gets_no_fabricated_colour_scale(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    write_report(_close_distances(tmp_path / "s", [0.5, 0.5, 0.5, 0.5]))  # all at eq. (11)
    fig = keep_figures()
    # one value has no scale: a colour bar would have to invent its ends
    assert _colour_bars(fig) == []
    text = "\n".join(t.get_text() for t in fig.axes[0].get_legend().get_texts())
    assert "= 0 for all" in text


def test_a_varying_distance_from_eq11_spans_exactly_its_values(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    write_report(_close_distances(tmp_path / "s", [0.4, 0.5, 0.7, 0.5]))
    bars = _colour_bars(keep_figures())
    assert len(bars) == 1
    assert bars[0] == pytest.approx((0.0, 0.2))


def test_every_point_is_numbered_and_its_parameters_named(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    # Well separated points: coverages 10 % apart, distances 10 m apart
    rows = [
        _row(f"k{i}", {"particles": p, "track.sigma_pos": s}, 10.0 * (i + 1), 10.0 * i, s)
        for i, (p, s) in enumerate([(500, 0.4), (500, 0.6), (1000, 0.4), (1000, 0.6)])
    ]
    combos, _ = write_report(_write(tmp_path / "s", rows))
    fig = keep_figures()
    ax = fig.axes[0]
    labels = {a.get_text(): a.xy for a in ax.texts if isinstance(a, Annotation)}
    # ranked best first: rank k is at its combination's mean (distance, coverage)
    assert set(labels) == {"1", "2", "3", "4"}
    for rank, c in enumerate(combos, start=1):
        assert labels[str(rank)] == pytest.approx((c.distance_mean, c.coverage_mean))
    text = "\n".join(t.get_text() for t in fig.findobj(Text))
    assert "particles, sigma_pos" in text
    for rank, c in enumerate(combos, start=1):
        line = f"{rank:>4}  {c.params['particles']}, {c.params['track.sigma_pos']}"
        assert line in text


def test_points_that_coincide_share_one_label() -> None:
    u = np.array([0.5, 0.505, 0.9, 0.51, np.nan])
    v = np.array([0.5, 0.51, 0.5, 0.2, 0.5])
    assert nearby_groups(u, v, (0.02, 0.03)) == [[0, 1], [2], [3]]


def test_point_key_names_only_what_varies() -> None:
    rows = [
        _row("a", {"particles": 500, "tracker": "pf-cv", "track.sigma_m": 0.2}, 50, 20, 0.5),
        _row("b", {"particles": 1000, "tracker": "pf-cv", "track.sigma_m": 0.2}, 60, 20, 0.5),
    ]
    header, lines = point_key(summarise(rows))
    assert header == "particles"
    assert lines == ["500", "1000"]


def test_padded_limits_keep_a_least_span() -> None:
    assert padded_limits(19.0891, 19.0892, 1.0) == pytest.approx((18.58915, 19.58915))
    lo, hi = padded_limits(0.0, 100.0, 1.0)
    assert lo == pytest.approx(-5.0)
    assert hi == pytest.approx(105.0)


# --- ties, coinciding points, error bars, and ‖σ − σ_eq11‖ for Kalman filters


def _tied(folder: Path) -> Path:
    """Four combinations that reach the same coverage and the same far point, their
    distances differing by fractions of a millimetre (the largest last), their σ_pos
    0.4-0.7 m; and a fifth 0.2 m short of them."""
    rows = [
        _row(f"k{i}", {"track.sigma_pos": sp}, 87.5, 24.1323 + 1e-5 * i, sp)
        for i, sp in enumerate([0.4, 0.5, 0.6, 0.7])
    ]
    rows.append(_row("k4", {"track.sigma_pos": 0.8}, 87.5, 23.9323, 0.8))
    return _write(folder, rows)


def test_combinations_equal_at_the_reports_precision_share_a_rank(tmp_path: Path) -> None:
    combos, _ = write_report(_tied(tmp_path / "s"))
    # the sub-millimetre differences rank nothing: the grid's order stays
    assert [c.params["track.sigma_pos"] for c in combos] == [0.4, 0.5, 0.6, 0.7, 0.8]
    with (tmp_path / "s" / "best.csv").open() as fh:
        ranks = [int(r["rank"]) for r in csv.DictReader(fh)]
    assert ranks == [1, 1, 1, 1, 5]
    table = (tmp_path / "s" / "report.md").read_text()
    assert table.count("\n| 1 | ") == 4
    assert "\n| 5 | track.sigma_pos=0.8" in table


def test_rank_numbers_skip_past_a_tie() -> None:
    rows = [
        _row("a", {"p": 1}, 50.0, 20.0, 0.5),
        _row("b", {"p": 2}, 60.0, 20.0, 0.5),
        _row("c", {"p": 3}, 60.04, 20.04, 0.5),  # equal to b at 0.1 % and 0.1 m
        _row("d", {"p": 4}, 60.0, 19.0, 0.5),
        _row("e", {"p": 5}, 50.0, 20.01, 0.5),  # equal to a
    ]
    combos = ranked(summarise(rows))
    assert [c.params["p"] for c in combos] == [2, 3, 4, 1, 5]
    assert rank_numbers(combos) == [1, 1, 3, 4, 4]


def _markers(fig: Figure) -> tuple[np.ndarray, np.ndarray]:
    """Every point marker on the plot, in display coordinates, and its colour value."""
    ax = fig.axes[0]
    pts, values = [], []
    for coll in ax.collections:
        if isinstance(coll, PathCollection):
            xy = np.asarray(coll.get_offsets(), dtype=float)
            pts.append(ax.transData.transform(xy))
            a = coll.get_array()
            values.append(np.asarray(a, dtype=float) if a is not None else np.full(len(xy), -1.0))
    return np.concatenate(pts), np.concatenate(values)


def test_combinations_at_one_place_are_each_visible(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    write_report(_tied(tmp_path / "s"))
    fig = keep_figures()
    pts, values = _markers(fig)
    assert len(pts) == 5
    # no marker hides another: centres at least a marker's width apart (40 pt² ≈ 6.3 pt)
    width_px = np.sqrt(40.0) * fig.dpi / 72.0
    gaps = np.linalg.norm(pts[:, None] - pts[None, :], axis=2) + np.eye(5) * 1e9
    assert gaps.min() >= width_px
    # every combination's colour is on the figure: ‖σ − σ_eq11‖ = 0.1 ... 0.3
    np.testing.assert_allclose(np.sort(values), [0.0, 0.1, 0.1, 0.2, 0.3], atol=1e-9)
    # the tied four share one label that names their rank and how many
    labels = [a.get_text() for a in fig.axes[0].texts if isinstance(a, Annotation)]
    assert sorted(labels) == ["1 (4 tied)", "5"]


def test_dodge_offsets_centre_each_group_on_its_place() -> None:
    off = dodge_offsets([[0, 2], [1], [3, 4, 5]], 7)
    np.testing.assert_allclose(off, [-0.5, 0.0, 0.5, -1.0, 0.0, 1.0, 0.0])


def test_group_label_counts_the_tied() -> None:
    assert group_label([1, 1, 1, 4]) == "1 (3 tied), 4"
    assert group_label([2]) == "2"
    assert group_label([2, 3]) == "2, 3"


def _seeds(folder: Path, per_combination: list[list[tuple[float, float]]]) -> Path:
    rows = [
        {**_row(f"k{i}", {"particles": 500 * (i + 1)}, cov, dist, 0.5), "seed": seed}
        for i, runs in enumerate(per_combination)
        for seed, (cov, dist) in enumerate(runs)
    ]
    return _write(folder, rows)


def test_error_bars_are_the_std_over_the_runs(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    # coverage 40 and 60 (std 14.14), distances 10 and 14 (std 2.83); a second
    # combination far from it, with std 0
    folder = _seeds(tmp_path / "s", [[(40.0, 10.0), (60.0, 14.0)], [(90.0, 30.0), (90.0, 30.0)]])
    combos, _ = write_report(folder)
    fig = keep_figures()
    ax = fig.axes[0]
    bars = [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
    assert len(bars) == 1
    segments = [np.asarray(s) for lc in bars[0].lines[2] for s in lc.get_segments()]
    half = sorted(float(np.ptp(s[:, 0]) + np.ptp(s[:, 1])) / 2.0 for s in segments)
    std_cov, std_dist = np.sqrt(200.0), np.sqrt(8.0)
    np.testing.assert_allclose(half, [0.0, 0.0, std_dist, std_cov], atol=1e-9)
    assert "mean ± std" in ax.get_title()
    assert "2 runs" in ax.get_title()
    # the figure's combinations are the report's, best first
    assert combos[0].coverage_mean == 90.0


def test_one_run_each_claims_no_std(tmp_path: Path, keep_figures: Callable[[], Figure]) -> None:
    write_report(_close_distances(tmp_path / "s", [0.4, 0.5, 0.6, 0.5]))
    ax = keep_figures().axes[0]
    assert not [c for c in ax.containers if isinstance(c, ErrorbarContainer)]
    assert "std" not in ax.get_title().replace("no spread", "")
    assert "one run each" in ax.get_title()


def test_spread_title_says_what_the_bars_are() -> None:
    one = summarise([_row("a", {"p": 1}, 50.0, 20.0, 0.5)])
    assert spread_title(one) == "1 parameter combinations, one run each (no spread to show)"
    same = summarise([{**_row("a", {"p": 1}, 50.0, 20.0, 0.5), "seed": s} for s in (0, 1, 2)])
    assert spread_title(same) == "1 parameter combinations: mean over 3 runs (std 0)"


def test_kalman_filters_get_no_distance_from_eq11(
    tmp_path: Path, keep_figures: Callable[[], Figure]
) -> None:
    # An EKF's σ settings are the defaults, eq. (11)'s up to float rounding
    noisy = {**EQ11, "sigma_pos": 0.5 + 1e-16}
    rows = [
        {**_row(f"k{i}", {"tracker": t}, 50.0 + 10 * i, 20.0 + 5 * i, 0.5, t), "sigma": noisy}
        for i, t in enumerate(["ekf-cv", "kf-ca", "pf-cv"])
    ]
    combos, _ = write_report(_write(tmp_path / "s", rows))
    by_tracker = {c.params["tracker"]: c.eq11_distance for c in combos}
    assert np.isnan(by_tracker["ekf-cv"])
    assert np.isnan(by_tracker["kf-ca"])
    assert by_tracker["pf-cv"] == 0.0  # float noise is no distance
    fig = keep_figures()
    legend = fig.axes[0].get_legend()
    texts = [t.get_text() for t in legend.get_texts()]
    assert texts == ["‖σ − σ_eq11‖ = 0 for all particle filters", "no σ (Kalman)"]
    assert "n/a |" in (tmp_path / "s" / "report.md").read_text()
    # the legend covers no point
    renderer = fig.canvas.get_renderer()  # type: ignore[attr-defined]
    box = legend.get_window_extent(renderer)
    pts, _ = _markers(fig)
    inside = (box.x0 <= pts[:, 0]) & (pts[:, 0] <= box.x1)
    inside &= (box.y0 <= pts[:, 1]) & (pts[:, 1] <= box.y1)
    assert not inside.any()
