"""``sweep-report``'s figure on hand-written result lines: readable axes, an honest
colour scale, and every point named."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.text import Annotation, Text

from dronetrack.experiments.sweep.report import (
    nearby_groups,
    padded_limits,
    point_key,
    summarise,
    write_report,
)

EQ11 = {"sigma_pos": 0.5, "sigma_vel": 0.5, "sigma_acc": 0.0, "sigma_m": 0.2}


def _row(
    key: str, params: dict[str, Any], coverage: float, distance: float, sigma_pos: float
) -> dict[str, Any]:
    return {
        "key": key,
        "params": params,
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
