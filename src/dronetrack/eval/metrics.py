"""Metrics of a tracking run: arrays in, numbers out.

Seed 000 (§III-A, III-C, III-E):

- an estimate is *correct* when it lies within ``radius`` (4 m, the GPS
  accuracy) of the ground truth;
- track coverage = correct frames / all frames [%];
- maximum tracking distance = the largest sensor-to-target range among the
  correct frames whose update used a measurement near the truth (so a filter
  coasting on its prediction past the last return does not extend it);
- RMSE = √(1/n Σ ‖x̂_i − x_i‖²) (eq. 13), with the 95 % confidence interval
  from the chi-squared distribution: n·RMSE² / σ² ~ χ²(n), so
  σ ∈ [√(n RMSE² / χ²₀.₉₇₅(n)), √(n RMSE² / χ²₀.₀₂₅(n))].
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from dronetrack.geometry.transforms import FloatArray

__all__ = [
    "CORRECT_RADIUS_M",
    "HIDDEN_S",
    "Rmse",
    "acquire_time",
    "acquisition_metrics",
    "correct",
    "coverage_pct",
    "detection_gaps",
    "false_lock_pct",
    "lock_on_visible_pct",
    "lock_transfers",
    "locked_on",
    "longest_run",
    "max_tracking_distance",
    "nice_bin_width",
    "points_by_distance",
    "reacquire_times",
    "revisit_max_s",
    "rmse",
    "timing",
]

CORRECT_RADIUS_M = 4.0


def correct(errors: FloatArray, radius: float) -> NDArray[np.bool_]:
    """Frames whose 3-D error (N, 3) is within ``radius`` (NaN counts as wrong)."""
    norm = np.linalg.norm(errors, axis=1)
    ok: NDArray[np.bool_] = np.isfinite(norm) & (norm <= radius)
    return ok


def coverage_pct(errors: FloatArray, radius: float = CORRECT_RADIUS_M) -> float:
    """Share of frames with a correct estimate [%]; errors (N, 3) = estimate − truth."""
    if len(errors) == 0:
        return 0.0
    return 100.0 * float(np.mean(correct(errors, radius)))


def max_tracking_distance(
    errors: FloatArray,
    ranges: FloatArray,
    radius: float = CORRECT_RADIUS_M,
    meas_errors: FloatArray | None = None,
) -> float:
    """Largest sensor-to-target range [m] among the correct frames (0 if none).

    With ``meas_errors`` (N,), the distance of each frame's measurement from the
    truth (NaN: the update used none), only frames whose update used a measurement
    within ``radius`` of the truth count: an estimate coasting on the prediction
    is not tracking at that range, however close it happens to be.
    """
    ok = correct(errors, radius)
    if meas_errors is not None:
        m = np.asarray(meas_errors, dtype=np.float64)
        ok &= np.isfinite(m) & (m <= radius)
    return float(ranges[ok].max()) if np.any(ok) else 0.0


@dataclass(frozen=True, slots=True)
class Rmse:
    value: float  # [m]
    ci95: tuple[float, float]  # [m]
    per_axis: tuple[float, float, float]  # [m]
    n: int


def rmse(errors: FloatArray) -> Rmse:
    """RMSE of 3-D errors (N, 3) with its χ² 95 % interval and per-axis RMSE (eq. 13)."""
    e = errors[np.all(np.isfinite(errors), axis=1)]
    n = len(e)
    if n == 0:
        nan = float("nan")
        return Rmse(nan, (nan, nan), (nan, nan, nan), 0)
    sq = float(np.mean(np.sum(e**2, axis=1)))
    # n RMSE² / σ² ~ χ²(n)
    lo = np.sqrt(n * sq / chi2.ppf(0.975, n))
    hi = np.sqrt(n * sq / chi2.ppf(0.025, n))
    axes = np.sqrt(np.mean(e**2, axis=0))
    return Rmse(
        np.sqrt(sq), (float(lo), float(hi)), (float(axes[0]), float(axes[1]), float(axes[2])), n
    )


def nice_bin_width(lo: float, hi: float, most: int = 20) -> float:
    """The smallest width 1, 2 or 5 × 10ᵏ [m] that covers [lo, hi] in at most ``most`` bins
    (so 8 to 20 of them); a zero span is treated as 10 % of the value (1 m at 0)."""
    if not (math.isfinite(lo) and math.isfinite(hi)) or hi < lo or most < 1:
        raise ValueError(f"no bin width for the interval [{lo}, {hi}] in {most} bins")
    span = hi - lo
    if span <= 0.0:
        span = 0.1 * abs(hi) if hi != 0.0 else 1.0
    raw = span / most
    decade = 10.0 ** math.floor(math.log10(raw))
    for step in (1.0, 2.0, 5.0, 10.0):
        # the tolerance keeps an exact fit (span = most · width) in ``most`` bins
        if step * decade >= raw * (1.0 - 1e-9):
            return step * decade
    return 10.0 * decade  # not reached


def points_by_distance(
    ranges: FloatArray, counts: NDArray[np.int64] | FloatArray, bin_m: float | None = None
) -> list[dict[str, float]]:
    """Target points per frame against range, in bins of ``bin_m`` (seed 000 Fig. 7).

    Without ``bin_m`` the width follows the data: ``nice_bin_width`` over the 1st to
    99th percentile of the ranges, so an indoor flight over a few metres and an
    outdoor one over a hundred both get about 10 to 20 bins, and a few stray ranges
    do not coarsen the rest."""
    ok = np.isfinite(ranges)
    r, c = ranges[ok], np.asarray(counts, dtype=np.float64)[ok]
    if len(r) == 0:
        return []
    if bin_m is None:
        lo, hi = np.percentile(r, [1.0, 99.0])
        bin_m = nice_bin_width(float(lo), float(hi))
    if not bin_m > 0.0:
        raise ValueError(f"bin_m must be positive, got {bin_m}")
    # Bin b holds ranges in [b·bin, (b+1)·bin); only occupied bins are listed, so a
    # stray far range costs one row, not a row per empty bin.  The edges are rounded
    # to the bin width's digits (3.1, not 3.1000000000000005).
    digits = max(0, 2 - math.floor(math.log10(bin_m)))
    which = np.floor(r / bin_m + 1e-9).astype(np.int64)
    rows = []
    for b in np.unique(which):
        sel = which == b
        rows.append(
            {
                "range_from_m": round(float(b * bin_m), digits),
                "range_to_m": round(float((b + 1) * bin_m), digits),
                "frames": int(sel.sum()),
                "points_mean": float(c[sel].mean()),
                "points_max": float(c[sel].max()),
            }
        )
    return rows


def detection_gaps(t: FloatArray, detected: NDArray[np.bool_]) -> FloatArray:
    """Times [s] between consecutive frames that saw the target."""
    times = t[detected]
    gaps: FloatArray = np.diff(times)
    return gaps


def timing(step_ms: FloatArray) -> dict[str, float]:
    """Mean, standard deviation and worst case of the per-step compute time [ms]."""
    if len(step_ms) == 0:
        return {"mean": 0.0, "std": 0.0, "max": 0.0}
    return {
        "mean": float(np.mean(step_ms)),
        "std": float(np.std(step_ms)),
        "max": float(np.max(step_ms)),
    }


def longest_run(mask: NDArray[np.bool_]) -> int:
    """The longest stretch of consecutive True values."""
    m = np.asarray(mask, dtype=bool)
    if not m.any():
        return 0
    # Run boundaries: indices where the value changes, padded with False at both ends.
    edges = np.flatnonzero(np.diff(np.r_[False, m, False].astype(np.int8)))
    return int(np.max(edges[1::2] - edges[0::2]))


def scored_tracking(
    errors: FloatArray,
    range_m: FloatArray,
    radius: float,
    meas_error: FloatArray,
    min_consecutive: int = 0,
) -> tuple[float, float]:
    """``coverage_pct`` and ``max_tracking_distance_m`` of a run, as seed 000 scores them:
    a run whose longest stretch of correct frames is shorter than ``min_consecutive``
    scores 0 on both (its Tables II and III use 5; 0 counts every run)."""
    ok = correct(errors, radius)
    if len(ok) == 0 or longest_run(ok) < min_consecutive:
        return 0.0, 0.0
    return coverage_pct(errors, radius), max_tracking_distance(errors, range_m, radius, meas_error)


def first_lock(tracked: NDArray[np.bool_]) -> int:
    """Index of the first frame the tracker calls tracked; the length if none."""
    return int(np.argmax(tracked)) if np.any(tracked) else len(tracked)


def first_visible(n_points: NDArray[np.int64], n_target_points: NDArray[np.int64]) -> int:
    """Index of the first frame whose foreground holds returns from the drone (the same
    frame for every tracker of a lockstep run, as none can track a drone still hidden in
    the background model); the length if none."""
    seen = np.flatnonzero((n_target_points > 0) & (n_points > 0))
    return int(seen[0]) if len(seen) else len(n_points)


# ---------------------------------------------------------------------------------------
# Acquisition (issue: finding the drone by itself, and again after losing it).
#
# A frame is *visible* when the drone returns points in it and lies inside the field of
# regard; it is *locked on* when the tracker calls itself tracked and its estimate is
# correct (within the correct radius).  Times are frame end times [s].

HIDDEN_S = 0.5  # a gap in the drone's returns longer than this means it was out of view


def locked_on(errors: FloatArray, tracked: NDArray[np.bool_], radius: float) -> NDArray[np.bool_]:
    """Frames the tracker calls tracked with a correct estimate."""
    ok: NDArray[np.bool_] = np.asarray(tracked, dtype=bool) & correct(errors, radius)
    return ok


def acquire_time(
    t: FloatArray, visible: NDArray[np.bool_], locked: NDArray[np.bool_]
) -> float | None:
    """``acquire_s``: from the first visible frame to the first frame locked on at or after
    it [s]; 0 when the tracker is already on the drone then, None when it never locks on
    (or the drone is never visible)."""
    seen = np.flatnonzero(visible)
    if not len(seen):
        return None
    first = int(seen[0])
    later = np.flatnonzero(locked[first:])
    return float(t[first + int(later[0])] - t[first]) if len(later) else None


def _return_time(t: FloatArray, visible_idx: NDArray[np.intp], hidden_s: float) -> float:
    """The time the drone came back into view among visible frames ``visible_idx``: the
    first of them, or the first after the last gap in its returns longer than ``hidden_s``."""
    times = t[visible_idx]
    back = np.flatnonzero(np.diff(times) > hidden_s)
    return float(times[int(back[-1]) + 1] if len(back) else times[0])


def reacquire_times(
    t: FloatArray,
    visible: NDArray[np.bool_],
    locked: NDArray[np.bool_],
    hidden_s: float = HIDDEN_S,
) -> list[float | None]:
    """``reacquire_s``: one entry per loss of lock after the first lock-on.

    A loss is a stretch of frames not locked on; its entry runs from the frame the drone
    returns points again (the first visible frame of the stretch or the re-lock frame,
    or the first after the stretch's last gap in returns longer than ``hidden_s``) to
    the re-lock [s].  A loss the run ends in is None if the drone returned and is left
    out if it never did (nothing could have found it).
    """
    ok = np.asarray(locked, dtype=bool)
    n = len(ok)
    # Stretch boundaries after the first lock-on: falls (ok → not ok) and rises (→ ok).
    change = np.flatnonzero(np.diff(ok.astype(np.int8)))
    falls = change[~ok[change + 1]] + 1
    out: list[float | None] = []
    for s in falls:
        rises = np.flatnonzero(ok[s:])
        e = int(s + rises[0]) if len(rises) else n  # the re-lock frame, or n
        window = np.flatnonzero(visible[s : min(e + 1, n)]) + s
        if e == n:
            if len(window):
                out.append(None)
            continue
        if not len(window):  # back on the drone by prediction alone, before any return
            out.append(0.0)
            continue
        out.append(float(t[e]) - _return_time(t, window, hidden_s))
    return out


def lock_on_visible_pct(visible: NDArray[np.bool_], locked: NDArray[np.bool_]) -> float | None:
    """``lock_on_visible_pct``: locked-on frames among the visible ones [%]; None if none."""
    n = int(np.count_nonzero(visible))
    return 100.0 * int(np.count_nonzero(visible & locked)) / n if n else None


def revisit_max_s(
    t: FloatArray, locked: NDArray[np.bool_], present: NDArray[np.bool_]
) -> float | None:
    """``revisit_max_s``: the longest wait [s] of a drone for the turret, from its first
    locked-on frame on: the time it was ``present`` (in the field and within reach, where
    a look could find it) without a lock, between two locked-on frames or after the last
    one to the end.  Each frame counts its spacing from the one before (the first, the
    median spacing); a drone out of reach waits for no look, and one held whenever
    present waits 0.  None if it was never locked on while present.

        wait_s = Σ Δt_i over present, unlocked frames i with s_i = s,  s_i = Σ_{j ≤ i} [locked_j]
        revisit_max_s = max over s ≥ 1 of wait_s
    """
    t = np.asarray(t, dtype=np.float64)
    present = np.asarray(present, dtype=bool)
    served = np.asarray(locked, dtype=bool) & present
    if not served.any():
        return None
    dt = np.diff(t, prepend=t[0] - (np.median(np.diff(t)) if len(t) > 1 else 0.0))
    since = np.cumsum(served)  # s_i: the locks so far, the segment each frame waits in
    waiting = present & ~served & (since > 0)
    wait = np.bincount(since, weights=np.where(waiting, dt, 0.0))
    return float(wait.max())


def false_lock_pct(errors: FloatArray, tracked: NDArray[np.bool_], radius: float) -> float | None:
    """``false_lock_pct``: tracked frames whose estimate is more than ``radius`` from the
    drone, over the tracked frames with a known truth [%]; None if there are none."""
    known = np.all(np.isfinite(errors), axis=1) & np.asarray(tracked, dtype=bool)
    n = int(np.count_nonzero(known))
    if not n:
        return None
    wrong = known & ~correct(errors, radius)
    return 100.0 * int(np.count_nonzero(wrong)) / n


def lock_transfers(errors: FloatArray, tracked: NDArray[np.bool_], radius: float) -> int | None:
    """``lock_transfers``: how often the estimate went straight from correct to wrong while
    the tracker kept its lock (tracked in both frames, the truth known in both): the lock
    was carried off the drone, onto clutter or away from it, rather than lost and then
    taken on something else.  None if no frame has a truth."""
    known = np.all(np.isfinite(errors), axis=1)
    if not known.any():
        return None
    live = np.asarray(tracked, dtype=bool)
    right = correct(errors, radius)
    on, off = live & right, live & known & ~right
    return int(np.count_nonzero(on[:-1] & off[1:]))


def acquisition_metrics(
    t: FloatArray,
    errors: FloatArray,
    tracked: NDArray[np.bool_],
    n_target_points: NDArray[np.int64],
    radius: float,
    in_field: NDArray[np.bool_] | None = None,
    range_m: FloatArray | None = None,
    reach_m: float | None = None,
) -> dict[str, Any]:
    """The acquisition figures of a run with ground truth: ``false_lock_pct``,
    ``lock_transfers`` and, where
    the drone's returns are known (``n_target_points`` ≥ 0), ``acquire_s``,
    ``reacquire_s`` (the list), its worst entry ``reacquire_max_s``, ``losses`` (the
    list's length), ``reacquire_missed`` (its None entries) and ``lock_on_visible_pct``.
    ``in_field`` (N,) limits the visible frames to those with the drone inside the field
    of regard (all frames without it).  Given the drone's range (N,) [m] and the
    sensor's reach ``reach_m``, ``acquire_in_reach_s`` counts from its first visible
    frame within reach, so that returns from beyond it, which a passing search can draw
    one at a time, do not start the clock."""
    out: dict[str, Any] = {
        "false_lock_pct": false_lock_pct(errors, tracked, radius),
        "lock_transfers": lock_transfers(errors, tracked, radius),
    }
    counts = np.asarray(n_target_points)
    if len(counts) == 0 or np.any(counts < 0):
        return out
    visible = counts > 0
    if in_field is not None:
        visible &= np.asarray(in_field, dtype=bool)
    locked = locked_on(errors, tracked, radius)
    times = reacquire_times(t, visible, locked)
    done = [x for x in times if x is not None]
    out.update(
        {
            "acquire_s": acquire_time(t, visible, locked),
            "reacquire_s": times,
            "reacquire_max_s": max(done) if done else None,
            "losses": len(times),
            "reacquire_missed": len(times) - len(done),
            "lock_on_visible_pct": lock_on_visible_pct(visible, locked),
        }
    )
    if range_m is not None and reach_m is not None:
        in_reach = np.asarray(range_m) <= reach_m
        out["acquire_in_reach_s"] = acquire_time(t, visible & in_reach, locked)
    return out
