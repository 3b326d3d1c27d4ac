"""The acquisition figures: acquire_s, reacquire_s, lock_on_visible_pct, false_lock_pct,
revisit_max_s."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.eval.metrics import (
    acquire_time,
    acquisition_metrics,
    false_lock_pct,
    lock_on_visible_pct,
    lock_transfers,
    locked_on,
    reacquire_times,
    revisit_max_s,
)

T = 0.1 * np.arange(1, 31)  # frame ends of a 10 Hz run [s]


def _mask(n: int, *ranges: tuple[int, int]) -> np.ndarray:
    m = np.zeros(n, dtype=bool)
    for a, b in ranges:
        m[a:b] = True
    return m


def test_locked_on_needs_both_the_flag_and_a_correct_estimate() -> None:
    err = np.array([[1.0, 0, 0], [5.0, 0, 0], [1.0, 0, 0], [np.nan, 0, 0]])
    tracked = np.array([True, True, False, True])
    assert locked_on(err, tracked, 4.0).tolist() == [True, False, False, False]


def test_acquire_time_known_answers() -> None:
    visible = _mask(30, (3, 30))
    assert acquire_time(T, visible, _mask(30, (5, 30))) == pytest.approx(0.2)
    # Already on the drone when its first returns come: 0.
    assert acquire_time(T, visible, _mask(30, (0, 30))) == 0.0
    # Never locked on after the first returns, or never visible: None.
    assert acquire_time(T, visible, _mask(30, (0, 2))) is None
    assert acquire_time(T, _mask(30), _mask(30, (0, 30))) is None


def test_reacquire_from_the_return_after_a_long_gap() -> None:
    # Locked 2-4, lost from 5; no returns 5-7 (0.3 s), returns from 8, re-lock at 10.
    locked = _mask(30, (2, 5), (10, 30))
    visible = _mask(30, (0, 5), (8, 30))
    assert reacquire_times(T, visible, locked, hidden_s=0.25) == pytest.approx([0.2])
    # A 0.3 s gap is not out of view for hidden_s = 0.5: from the loss's first return.
    visible[5] = True
    assert reacquire_times(T, visible, locked, hidden_s=0.5) == pytest.approx([0.5])


def test_reacquire_lists_every_loss_and_the_unfinished_one() -> None:
    locked = _mask(30, (0, 5), (7, 12), (15, 20))
    visible = _mask(30, (0, 30))
    # Losses at 5-6 (back at 7), 12-14 (back at 15), and from 20 to the end with returns.
    got = reacquire_times(T, visible, locked)
    assert got[:2] == pytest.approx([0.2, 0.3])
    assert got[2] is None
    # A loss the run ends in with no returns left nothing to find: not listed.
    assert reacquire_times(T, _mask(30, (0, 20)), locked) == pytest.approx([0.2, 0.3])


def test_reacquire_by_prediction_alone_is_zero() -> None:
    locked = _mask(30, (0, 5), (6, 30))
    visible = _mask(30, (0, 5), (7, 30))  # no returns at the loss or the re-lock
    assert reacquire_times(T, visible, locked) == [0.0]


def test_lock_on_visible_and_false_lock_known_answers() -> None:
    visible = _mask(10, (0, 8))
    locked = _mask(10, (2, 10))
    assert lock_on_visible_pct(visible, locked) == pytest.approx(75.0)
    assert lock_on_visible_pct(_mask(10), locked) is None
    err = np.zeros((10, 3))
    err[:3, 0] = 10.0  # three tracked frames far off
    err[9] = np.nan  # no truth: not counted
    tracked = np.ones(10, dtype=bool)
    assert false_lock_pct(err, tracked, 4.0) == pytest.approx(100.0 * 3 / 9)
    assert false_lock_pct(err, np.zeros(10, dtype=bool), 4.0) is None


def test_summary_keys_and_field_of_regard_mask() -> None:
    err = np.zeros((30, 3))
    err[:10, 0] = 50.0
    tracked = np.ones(30, dtype=bool)
    counts = np.where(np.arange(30) >= 4, 5, 0)
    out = acquisition_metrics(T, err, tracked, counts, 4.0)
    assert out["acquire_s"] == pytest.approx(0.6)
    assert out["false_lock_pct"] == pytest.approx(100.0 / 3)
    assert out["lock_on_visible_pct"] == pytest.approx(100.0 * 20 / 26)
    assert (out["reacquire_s"], out["losses"], out["reacquire_missed"]) == ([], 0, 0)
    assert out["reacquire_max_s"] is None
    # Outside the field of regard until frame 9: visible from then, locked on at once.
    inside = np.arange(30) >= 9
    out = acquisition_metrics(T, err, tracked, counts, 4.0, inside)
    assert out["acquire_s"] == pytest.approx(0.1)
    # Unknown returns (-1): only false_lock_pct.
    assert set(acquisition_metrics(T, err, tracked, -np.ones(30, int), 4.0)) == {
        "false_lock_pct",
        "lock_transfers",
    }


@settings(max_examples=200)
@given(
    locked=st.lists(st.booleans(), min_size=1, max_size=60),
    seen=st.lists(st.booleans(), min_size=60, max_size=60),
)
def test_reacquire_properties(locked: list[bool], seen: list[bool]) -> None:
    ok = np.array(locked)
    visible = np.array(seen[: len(ok)])
    t = 0.1 * np.arange(len(ok))
    got = reacquire_times(t, visible, ok)
    falls = int(np.count_nonzero(ok[:-1] & ~ok[1:]))
    assert len(got) <= falls
    # Every loss that ends in a re-lock is listed, with 0 ≤ entry ≤ the loss's length.
    rises = int(np.count_nonzero(~ok[:-1] & ok[1:])) - int(not ok[0] and ok.any())
    finished = [x for x in got if x is not None]
    assert len(finished) == rises
    assert all(0.0 <= x <= 0.1 * len(ok) for x in finished)
    a = acquire_time(t, visible, ok)
    assert a is None or 0.0 <= a <= t[-1]


def test_acquire_in_reach_counts_from_the_first_returns_within_reach() -> None:
    """A drone flying in from 150 m at 15 m/s (1.5 m a frame): one return from beyond
    reach at frame 2, none until frame 12 (within 130 m from frame 14), locked on from
    frame 16.  acquire_s runs from frame 2, acquire_in_reach_s from frame 14."""
    err = np.zeros((30, 3))
    err[:16, 0] = 50.0
    tracked = np.ones(30, dtype=bool)
    counts = np.where(np.arange(30) >= 12, 3, 0)
    counts[2] = 1
    range_m = 150.0 - 1.5 * np.arange(30)
    inside = range_m <= 130.0
    assert np.flatnonzero(inside)[0] == 14
    out = acquisition_metrics(T, err, tracked, counts, 4.0, range_m=range_m, reach_m=130.0)
    assert out["acquire_s"] == pytest.approx(1.4)
    assert out["acquire_in_reach_s"] == pytest.approx(0.2)
    # Locked on before the drone came within reach: 0.
    err[:] = 0.0
    assert (
        acquisition_metrics(T, err, tracked, counts, 4.0, range_m=range_m, reach_m=130.0)[
            "acquire_in_reach_s"
        ]
        == 0.0
    )
    # Without a reach there is no such figure; never within reach: None.
    assert "acquire_in_reach_s" not in acquisition_metrics(T, err, tracked, counts, 4.0)
    assert range_m.min() > 100.0
    out = acquisition_metrics(T, err, tracked, counts, 4.0, range_m=range_m, reach_m=100.0)
    assert out["acquire_in_reach_s"] is None


@settings(max_examples=200)
@given(
    locked=st.lists(st.booleans(), min_size=30, max_size=30),
    seen=st.lists(st.booleans(), min_size=30, max_size=30),
    reach=st.lists(st.booleans(), min_size=30, max_size=30),
)
def test_acquire_in_reach_is_acquire_s_of_the_frames_within_reach(
    locked: list[bool], seen: list[bool], reach: list[bool]
) -> None:
    """Whatever the masks, the figure is acquire_time over visible ∧ in reach, and a
    reach beyond every range gives acquire_s itself."""
    err = np.where(np.array(locked)[:, None], 0.0, 50.0) * np.ones((30, 3))
    tracked = np.ones(30, dtype=bool)
    counts = np.array(seen, dtype=np.int64)
    inside = np.array(reach)
    range_m = np.where(inside, 100.0, 200.0)
    out = acquisition_metrics(T, err, tracked, counts, 4.0, range_m=range_m, reach_m=150.0)
    ok = np.array(locked)
    assert out["acquire_in_reach_s"] == acquire_time(T, counts.astype(bool) & inside, ok)
    full = acquisition_metrics(T, err, tracked, counts, 4.0, range_m=range_m, reach_m=250.0)
    assert full["acquire_in_reach_s"] == full["acquire_s"]


def test_lock_transfers_count_only_a_lock_carried_off_the_drone() -> None:
    """Frames 0-4 on the drone, 5-7 on a bird with no frame lost between (one transfer);
    lost at 8-9, then on a bird at 10-12 (a false lock, not a transfer); on the drone
    at 13-19, where the truth is missing at 16 (no transfer counted across it)."""
    err = np.zeros((20, 3))
    err[5:8, 0] = 30.0
    err[10:13, 0] = 60.0
    err[16] = np.nan
    tracked = _mask(20, (0, 8), (10, 20))
    assert lock_transfers(err, tracked, 4.0) == 1
    # A drift out of the radius while tracked is one too: the estimate left the drone.
    drift = np.zeros((20, 3))
    drift[12:, 0] = 5.0
    assert lock_transfers(drift, np.ones(20, dtype=bool), 4.0) == 1
    assert lock_transfers(np.full((20, 3), np.nan), tracked, 4.0) is None


@settings(max_examples=200)
@given(
    tracked=st.lists(st.booleans(), min_size=2, max_size=40),
    wrong=st.lists(st.booleans(), min_size=40, max_size=40),
)
def test_lock_transfers_are_false_lock_starts_after_a_correct_frame(
    tracked: list[bool], wrong: list[bool]
) -> None:
    """Never more than the false-lock stretches; none once every false lock follows a
    lost frame."""
    live = np.array(tracked)
    off_drone = np.array(wrong[: len(live)])
    err = np.where(off_drone[:, None], 10.0, 0.0) * np.ones((len(live), 3))
    n = lock_transfers(err, live, 4.0)
    assert n is not None
    off = live & off_drone
    starts = int(off[0]) + int(np.count_nonzero(off[1:] & ~off[:-1]))
    assert 0 <= n <= starts
    lost_before = live.copy()
    lost_before[:-1] &= ~off[1:]  # lose the lock the frame before each false one
    assert lock_transfers(err, lost_before, 4.0) == 0


def test_a_drones_longest_wait_for_the_turret_counts_only_where_a_look_could_find_it() -> None:
    """A turret shared by two drones over 5 s at 10 Hz: it holds A on frames 0-9 and
    40-49 and B on 10-39.  A waits 3.0 s, frames 10-39; B, served from frame 10, waits
    1.0 s after its last one (39) to the end.  With A out of reach on frames 15-34 it
    waits 1.0 s (frames 10-14 and 35-39); a drone never locked on has no wait."""
    t = 0.1 * np.arange(1, 51)
    a = _mask(50, (0, 10), (40, 50))
    everywhere = np.ones(50, dtype=bool)
    assert revisit_max_s(t, a, everywhere) == pytest.approx(3.0)
    assert revisit_max_s(t, ~a, everywhere) == pytest.approx(1.0)
    assert revisit_max_s(t, a, ~_mask(50, (15, 35))) == pytest.approx(1.0)
    assert revisit_max_s(t, everywhere, everywhere) == 0.0  # held throughout
    assert revisit_max_s(t, np.zeros(50, dtype=bool), everywhere) is None
    assert revisit_max_s(t, a, np.zeros(50, dtype=bool)) is None  # never present


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.booleans(), min_size=2, max_size=60),
    st.lists(st.booleans(), min_size=60, max_size=60),
)
def test_a_wait_is_at_most_the_time_present_unlocked_after_the_first_lock(
    locked: list[bool], present: list[bool]
) -> None:
    n = len(locked)
    t = 0.1 * np.arange(1, n + 1)
    held, here = np.array(locked), np.array(present[:n])
    wait = revisit_max_s(t, held, here)
    if not (held & here).any():
        assert wait is None
        return
    assert wait is not None
    after = np.arange(n) > np.flatnonzero(held & here)[0]
    assert 0.0 <= wait <= 0.1 * (here & ~held & after).sum() + 1e-9
    # a wait as long as its longest run of such frames, at least
    runs, run = [0], 0
    for waiting, lock in zip(here & ~held & after, held & here, strict=True):
        run = 0 if lock else run + int(waiting)
        runs.append(run)
    assert wait >= 0.1 * max(runs) - 1e-9
