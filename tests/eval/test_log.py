"""TrackLog: one row appended per frame, read back as arrays."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.eval.log import TrackLog


def _append(log: TrackLog, k: int, rng: np.random.Generator) -> dict[str, object]:
    row: dict[str, object] = {
        "t": 0.1 * k,
        "gt": rng.normal(size=3),
        "est": rng.normal(size=3),
        "tracked": bool(k % 3),
        "sigma": float(rng.uniform()),
        "n_points": int(rng.integers(0, 50)),
        "n_target_points": int(rng.integers(-1, 5)),
        "range_m": float(rng.uniform(1, 100)),
        "pan": float(rng.uniform(-3, 3)),
        "tilt": float(rng.uniform(-1, 1)),
        "step_ms": float(rng.uniform()),
        "flags": ("gap", "repeated")[: k % 3],
        "pos_var": float(rng.uniform()),
        "vel_var": float(rng.uniform()),
        "measured": bool(k % 2),
        "meas_error": float(rng.uniform()),
    }
    log.append(**row)  # type: ignore[arg-type]
    return row


@settings(max_examples=25, deadline=None)
@given(n=st.integers(0, 700), seed=st.integers(0, 2**32 - 1))
def test_every_appended_row_reads_back_in_order(n: int, seed: int) -> None:
    """Across the block's growth (128, 256, 512, ...) no row is lost or altered."""
    rng = np.random.default_rng(seed)
    log = TrackLog()
    rows = [_append(log, k, rng) for k in range(n)]
    assert len(log) == n
    for name in ("t", "sigma", "n_points", "n_target_points", "range_m", "pan", "tilt"):
        np.testing.assert_array_equal(getattr(log, name), [r[name] for r in rows])
    gt = np.reshape([r["gt"] for r in rows], (-1, 3))
    np.testing.assert_array_equal(log.gt, gt)
    np.testing.assert_array_equal(log.tracked, [r["tracked"] for r in rows])
    assert list(log.flags) == [";".join(r["flags"]) for r in rows]  # type: ignore[arg-type]
    a = log.arrays()
    assert {len(v) for v in a.values()} <= {n}
    if n:
        last = log.row(-1)
        assert last["t"] == rows[-1]["t"]
        np.testing.assert_array_equal(last["est"], rows[-1]["est"])


def test_the_columns_are_read_only_views() -> None:
    log = TrackLog()
    rng = np.random.default_rng(0)
    _append(log, 0, rng)
    with pytest.raises(ValueError, match="read-only"):
        log.t[0] = 5.0
    with pytest.raises(ValueError, match="read-only"):
        log.arrays()["gt_x"][0] = 5.0
    # A row is a copy: changing it leaves the log alone.
    row = log.row(0)
    row["t"] = 5.0
    assert log.t[0] == 0.0
    with pytest.raises(IndexError, match="row 1 of a log of 1"):
        log.row(1)


def test_an_empty_log_has_empty_columns() -> None:
    log = TrackLog()
    assert len(log) == 0
    assert log.gt.shape == (0, 3)
    assert log.summary()["frames"] == 0


def _timed(latencies: list[float]) -> TrackLog:
    log = TrackLog()
    for k, ms in enumerate(latencies):
        log.append(
            t=0.1 * k, gt=np.full(3, np.nan), est=np.zeros(3), tracked=False, sigma=1.0,
            n_points=0, n_target_points=-1, range_m=np.nan, pan=0.0, tilt=0.0, step_ms=1.0,
            latency_ms=ms,
        )  # fmt: skip
    return log


def test_a_live_runs_latency_percentiles() -> None:
    """1, 2, ..., 100 ms: the median is 50.5 ms and the 99th percentile (linear between
    ranks) 99.01 ms; NaN rows (frames without a live arrival) are left out."""
    m = _timed([*map(float, range(1, 101)), float("nan")]).summary()
    assert m["latency_ms_p50"] == pytest.approx(50.5)
    assert m["latency_ms_p99"] == pytest.approx(99.01)


def test_a_run_that_is_not_live_has_no_latency_figures() -> None:
    m = _timed([float("nan")] * 5).summary()
    assert "latency_ms_p50" not in m
    assert "latency_ms_p99" not in m
