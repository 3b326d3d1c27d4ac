"""Run metrics against hand-computed answers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.eval.log import TrackLog
from dronetrack.eval.metrics import (
    coverage_pct,
    detection_gaps,
    longest_run,
    max_tracking_distance,
    nice_bin_width,
    points_by_distance,
    rmse,
    timing,
)


def test_coverage_and_max_distance() -> None:
    err = np.array([[0, 0, 1.0], [3, 0, 0], [0, 4.1, 0], [np.nan, 0, 0], [2, 2, 2]])
    ranges = np.array([10.0, 50.0, 80.0, 90.0, 30.0])
    # Within 4 m: rows 0, 1 and 4 (‖(2, 2, 2)‖ = 3.46); NaN counts as wrong.
    assert coverage_pct(err) == pytest.approx(60.0)
    assert max_tracking_distance(err, ranges) == 50.0
    assert max_tracking_distance(err[2:4], ranges[2:4]) == 0.0
    assert coverage_pct(np.empty((0, 3))) == 0.0


def test_max_distance_counts_only_frames_updated_near_the_truth() -> None:
    """A filter coasting on its prediction past the last return is close to the truth
    for a while; those frames do not extend the maximum tracking distance."""
    err = np.zeros((5, 3))  # every estimate correct
    ranges = np.array([30.0, 31.0, 33.8, 34.9, 35.9])
    # Measurement errors: frames 3 and 4 had no update (NaN), frame 1 updated on
    # a return 6 m from the truth (clutter).
    meas = np.array([0.2, 6.0, 0.3, np.nan, np.nan])
    assert max_tracking_distance(err, ranges) == 35.9
    assert max_tracking_distance(err, ranges, 4.0, meas) == 33.8
    # An update near the truth with a wrong estimate does not count either.
    err[2] = [5.0, 0.0, 0.0]
    assert max_tracking_distance(err, ranges, 4.0, meas) == 30.0
    assert max_tracking_distance(err, ranges, 4.0, np.full(5, np.nan)) == 0.0


@given(
    st.lists(
        st.tuples(
            st.floats(0, 10),
            st.floats(0, 200),
            st.one_of(st.just(float("nan")), st.floats(0, 10)),
        ),
        min_size=1,
        max_size=30,
    )
)
def test_max_distance_with_measurements_never_exceeds_the_plain_one(
    rows: list[tuple[float, float, float]],
) -> None:
    err = np.array([[e, 0.0, 0.0] for e, _, _ in rows])
    ranges = np.array([r for _, r, _ in rows])
    meas = np.array([m for _, _, m in rows])
    plain = max_tracking_distance(err, ranges, 4.0)
    supported = max_tracking_distance(err, ranges, 4.0, meas)
    assert supported <= plain
    ok = (err[:, 0] <= 4.0) & (meas <= 4.0)
    assert supported == (ranges[ok].max() if ok.any() else 0.0)


def test_rmse_and_its_chi_square_interval() -> None:
    err = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, 0.0], [1.0, 2.0, 2.0]])
    r = rmse(err)
    # √((25 + 0 + 9) / 3)
    assert r.value == pytest.approx(np.sqrt(34 / 3))
    assert r.per_axis == pytest.approx((np.sqrt(10 / 3), np.sqrt(20 / 3), np.sqrt(4 / 3)))
    assert r.ci95[0] < r.value < r.ci95[1]


def test_the_interval_covers_the_truth_95_percent_of_the_time() -> None:
    g = np.random.default_rng(0)
    sigma = 0.1  # per axis, so the true RMSE is σ √3
    hits = 0
    for _ in range(2000):
        r = rmse(g.normal(0.0, sigma, (40, 3)))
        # n·RMSE²/σ_e² ~ χ²(n) holds for the squared 3-D error; here each term is
        # a χ²(3) sum, so the interval is conservative: it must cover ≥ 95 %.
        hits += r.ci95[0] <= sigma * np.sqrt(3) <= r.ci95[1]
    assert hits / 2000 >= 0.95


def test_points_by_distance_gaps_and_timing() -> None:
    rows = points_by_distance(np.array([5.0, 15.0, 16.0, 27.0]), np.array([10, 4, 6, 0]), 10.0)
    assert [(r["range_from_m"], r["frames"], r["points_mean"]) for r in rows] == [
        (0.0, 1, 10.0),
        (10.0, 2, 5.0),
        (20.0, 1, 0.0),
    ]
    # A stray huge range adds one row; a bin edge belongs to the upper bin.
    far = points_by_distance(np.array([10.0, 1e9, np.nan]), np.array([3, 1, 7]), 10.0)
    assert [(r["range_from_m"], r["range_to_m"], r["frames"]) for r in far] == [
        (10.0, 20.0, 1),
        (1e9, 1e9 + 10.0, 1),
    ]
    gaps = detection_gaps(
        np.array([0.0, 0.1, 0.2, 0.3, 0.4]), np.array([True, False, False, True, True])
    )
    np.testing.assert_allclose(gaps, [0.3, 0.1])
    assert timing(np.array([1.0, 3.0])) == {"mean": 2.0, "std": 1.0, "max": 3.0}


def test_log_summary_without_ground_truth() -> None:
    log = TrackLog()
    for k in range(5):
        log.append(
            t=0.1 * k,
            gt=np.full(3, np.nan),
            est=np.zeros(3),
            tracked=k > 1,
            sigma=0.1,
            n_points=3,
            n_target_points=-1,
            range_m=np.nan,
            pan=0.0,
            tilt=0.0,
            step_ms=1.0,
            flags=("gap",) if k == 3 else (),
        )
    m = log.summary()
    assert m["frames"] == 5
    assert m["first_lock_s"] == pytest.approx(0.2)
    assert m["bad_frames"] == {"gap": 1}
    assert "coverage_pct" not in m


@settings(max_examples=200, deadline=None)
@given(st.lists(st.booleans(), max_size=60))
def test_longest_run_counts_the_longest_stretch(values: list[bool]) -> None:
    best = current = 0
    for v in values:
        current = current + 1 if v else 0
        best = max(best, current)
    assert longest_run(np.array(values, dtype=bool)) == best


@pytest.mark.parametrize(
    ("lo", "hi", "width"),
    [
        (1.0, 6.0, 0.5),  # 5 m / 20 = 0.25 → 0.5: 10 bins
        (0.0, 100.0, 5.0),  # exactly 20 bins of 5
        (0.0, 200.0, 10.0),
        (20.0, 300.0, 20.0),  # 14 m → 20
        (3.03, 3.13, 0.005),
        (7.0, 7.0, 0.05),  # no span: 10 % of the value in 20 bins
        (0.0, 0.0, 0.05),
    ],
)
def test_nice_bin_width_known_answers(lo: float, hi: float, width: float) -> None:
    assert nice_bin_width(lo, hi) == pytest.approx(width)


def test_nice_bin_width_refuses_a_reversed_or_infinite_interval() -> None:
    for lo, hi in ((2.0, 1.0), (0.0, np.inf), (np.nan, 1.0)):
        with pytest.raises(ValueError, match="bin width"):
            nice_bin_width(lo, hi)


@settings(max_examples=200, deadline=None)
@given(
    st.floats(0.0, 500.0),
    st.floats(1e-2, 500.0),
    st.integers(50, 400),
)
def test_data_scaled_bins_cover_the_ranges_in_8_to_22_bins(lo: float, span: float, n: int) -> None:
    """Whatever the scale (a 1 cm indoor wobble to 500 m outdoors), the ranges spread
    evenly over [lo, lo + span] fill about 10 to 20 bins of a 1-2-5 width, and every
    frame is in the bin whose edges hold its range."""
    ranges = np.linspace(lo, lo + span, n)
    counts = np.arange(n)
    rows = points_by_distance(ranges, counts)
    assert 8 <= len(rows) <= 22
    widths = {round(r["range_to_m"] - r["range_from_m"], 12) for r in rows}
    assert len(widths) == 1
    w = widths.pop()
    mantissa = w / 10.0 ** np.floor(np.log10(w))
    assert min(abs(mantissa - m) for m in (1.0, 2.0, 5.0, 10.0)) < 1e-6
    assert sum(r["frames"] for r in rows) == n
    tol = 1e-9 * max(1.0, lo + span)
    assert rows[0]["range_from_m"] <= ranges[0] + tol
    assert rows[-1]["range_to_m"] >= ranges[-1] - tol
    for row in rows:
        inside = (ranges >= row["range_from_m"] - tol) & (ranges < row["range_to_m"] - tol)
        assert row["frames"] == int(inside.sum())
        assert row["points_max"] == counts[inside].max()


def test_indoor_ranges_get_more_than_three_bins() -> None:
    ranges = np.linspace(1.0, 6.0, 120)
    rows = points_by_distance(ranges, np.full(120, 40))
    assert len(rows) > 3
    assert rows[0]["range_from_m"] == 1.0
    assert rows[-1]["range_to_m"] == 6.5
    # the same keys as before the bins scaled with the data
    assert set(rows[0]) == {"range_from_m", "range_to_m", "frames", "points_mean", "points_max"}
