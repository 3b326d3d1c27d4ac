"""The lock's history: established and continued locks, the reach gate, and the
switch from a target that never hovered to one that did."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.detect.lock import LockBook
from dronetrack.detect.tentative import ConfirmationSettings
from dronetrack.types import Candidates, TrackEstimate

T = 0.1
S = ConfirmationSettings(v_max=15.0, gate_m=1.0)


def _est(t: float, p: tuple[float, float, float], tracked: bool = True) -> TrackEstimate:
    return TrackEstimate(t, np.array(p, dtype=float), np.zeros(3), tracked, 0.3)


def _cands(*rows: tuple[tuple[float, float, float], bool]) -> Candidates:
    k = len(rows)
    pos = np.array([r[0] for r in rows], dtype=float).reshape(k, 3)
    one = np.ones(k, dtype=np.int64)
    return Candidates(
        pos,
        np.zeros((k, 3)),
        3 * one,
        np.full(k, 0.4),
        np.arange(k),
        np.array([r[1] for r in rows], dtype=bool),
    )


def _lock_for(book: LockBook, t0: float, seconds: float, p: tuple[float, float, float]) -> float:
    t = t0
    for _ in range(round(seconds / T)):
        book.update(_est(t, p), None)
        t += T
    return t


def test_a_short_lock_sets_no_gate_an_established_one_does() -> None:
    book = LockBook(S)
    far = _cands(((100.0, 0.0, 10.0), False))
    t = _lock_for(book, 0.0, 0.5, (20.0, 0.0, 5.0))
    book.update(_est(t, (20.0, 0.0, 5.0), tracked=False), None)
    assert book.fix is None
    assert len(book.reachable(t + T, far)) == 1
    t = _lock_for(book, t + T, 1.5, (20.0, 0.0, 5.0))
    book.update(_est(t, (20.0, 0.0, 5.0), tracked=False), None)
    assert book.fix is not None
    # 80 m away: out of reach for (80 − 1)/15 = 5.3 s after the fix
    assert len(book.reachable(book.fix.t + 5.2, far)) == 0
    assert len(book.reachable(book.fix.t + 5.4, far)) == 1


def test_after_a_loss_the_hovered_then_the_nearest_to_the_fix_come_first() -> None:
    book = LockBook(S)
    p = (135.0, 15.0, 20.0)
    t = _lock_for(book, 0.0, 1.5, p)
    book.update(_est(t, p, tracked=False), None)
    bird, drone, hoverer = (61.0, 0.0, 40.0), (128.0, 35.0, 20.0), (90.0, -20.0, 25.0)
    # The bird is first in the detect stage's order (more hits), 78 m from the fix;
    # the drone 21 m from it.  Both are within the 91 m reach 6 s on.
    out = book.reachable(t + 6.0, _cands((bird, False), (drone, False)))
    assert out is not None
    np.testing.assert_allclose(out.positions, [drone, bird])
    out = book.reachable(t + 6.0, _cands((bird, False), (drone, False), (hoverer, True)))
    assert out is not None
    np.testing.assert_allclose(out.positions, [hoverer, drone, bird])
    # Before any established lock there is no fix: the given order stands.
    fresh = LockBook(S)
    out = fresh.reachable(0.0, _cands((bird, False), (drone, False)))
    assert out is not None
    np.testing.assert_allclose(out.positions, [bird, drone])


def test_a_relock_within_reach_continues_the_established_lock() -> None:
    book = LockBook(S)
    t = _lock_for(book, 0.0, 1.5, (100.0, 0.0, 20.0))
    book.update(_est(t, (100.0, 0.0, 20.0), tracked=False), None)
    # re-locked 0.3 s later 3 m away (reach 15·0.4 + 1 = 7 m): the fix moves at once
    book.update(_est(t + 0.3, (103.0, 0.0, 20.0)), None)
    assert book.continued
    assert book.fix is not None
    assert book.fix.t == t + 0.3


def test_far_out_flickers_chain_the_fix_across_gaps_up_to_continue_s() -> None:
    """A drone at the edge of reach is locked for 0.2-0.5 s at a time with gaps of
    1.2-1.4 s: each lock continues the last, so the fix keeps up with the drone and
    a bird 60 m away stays out of reach, 1 s after the last lock."""
    book = LockBook(S)
    p = np.array([135.0, -40.0, 20.0])
    t = _lock_for(book, 0.0, 1.5, tuple(p))
    for gap, hold in ((1.2, 0.2), (1.4, 0.5), (1.3, 0.3)):
        book.update(_est(t, tuple(p), tracked=False), None)
        t += gap
        p = p + np.array([0.0, 10.0, 0.0])  # 10 m along in each gap
        book.update(_est(t, tuple(p)), None)
        assert book.continued
        t = _lock_for(book, t + T, hold, tuple(p))
    assert book.fix is not None
    assert book.fix.t == t - T
    book.update(_est(t, tuple(p), tracked=False), None)
    bird = _cands(((p[0] - 60.0, p[1], 30.0), False))
    assert len(book.reachable(t + 1.0, bird)) == 0
    # With the established lock's 1 s as the window the first 1.2 s gap breaks the
    # chain: the fix stays at the first lock, and the bird is within its reach.
    stale = LockBook(S, continue_s=1.0)
    t0 = _lock_for(stale, 0.0, 1.5, (135.0, -40.0, 20.0))
    stale.update(_est(t0, (135.0, -40.0, 20.0), tracked=False), None)
    stale.update(_est(t0 + 1.2, (135.0, -30.0, 20.0)), None)
    assert not stale.continued
    assert stale.fix is not None
    assert len(stale.reachable(stale.fix.t + 6.0, bird)) == 1


def test_a_relock_out_of_reach_is_a_new_lock() -> None:
    book = LockBook(S)
    t = _lock_for(book, 0.0, 1.5, (100.0, 0.0, 20.0))
    old = book.fix
    book.update(_est(t, (100.0, 0.0, 20.0), tracked=False), None)
    book.update(_est(t + 0.1, (50.0, 0.0, 20.0)), None)  # 50 m in 0.2 s
    assert not book.continued
    assert book.fix is old


def test_a_lock_that_never_hovered_gives_way_to_a_hoverer() -> None:
    book = LockBook(S)
    bird, drone = (60.0, 20.0, 30.0), (15.0, 0.0, 3.0)
    both = _cands((bird, False), (drone, True))
    _lock_for(book, 0.0, 2.0, bird)
    book.update(_est(2.0, bird), _cands((bird, False)))
    other = book.switch(both)
    assert other is not None
    assert len(other) == 1
    np.testing.assert_allclose(other.positions[0], drone)


def test_a_lock_on_a_hoverer_is_never_switched() -> None:
    book = LockBook(S)
    drone, other = (15.0, 0.0, 3.0), (40.0, 5.0, 10.0)
    book.update(_est(0.0, drone), _cands((drone, True)))
    book.update(_est(0.1, (16.0, 0.0, 3.0)), _cands(((16.0, 0.0, 3.0), False)))
    assert book.hovered  # the flag stays with the lock, not with one frame's candidate
    assert book.switch(_cands((other, True))) is None


def test_the_hover_flag_survives_a_continued_lock_but_not_a_new_one() -> None:
    book = LockBook(S)
    p = (30.0, 0.0, 5.0)
    t = _lock_for(book, 0.0, 1.2, p)
    book.update(_est(t, p), _cands((p, True)))
    book.update(_est(t + T, p, tracked=False), None)
    book.update(_est(t + 2 * T, p), None)  # continued
    assert book.hovered
    book.update(_est(t + 3 * T, p, tracked=False), None)
    book.update(_est(t + 4 * T, (120.0, 0.0, 5.0)), None)  # out of reach: another target
    assert not book.hovered


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    hovered_lock=st.booleans(),
    n=st.integers(0, 6),
)
def test_switch_offers_only_hoverers_away_from_a_lock_that_never_hovered(
    seed: int, hovered_lock: bool, n: int
) -> None:
    rng = np.random.default_rng(seed)
    book = LockBook(S)
    p = tuple(rng.uniform(-50, 50, 3))
    book.update(_est(0.0, p), _cands((p, hovered_lock)))
    rows = [
        (tuple(np.asarray(p) + rng.normal(0, 3, 3)), bool(rng.random() < 0.5)) for _ in range(n)
    ]
    cands = _cands(*rows) if rows else Candidates.empty()
    out = book.switch(cands)
    if hovered_lock:
        assert out is None
        return
    away = [r for r in rows if r[1] and np.linalg.norm(np.subtract(r[0], p)) > book.same_m]
    if not away:
        assert out is None
    else:
        assert out is not None
        assert len(out) == len(away)
        assert out.hovered.all()
        assert (np.linalg.norm(out.positions - np.asarray(p), axis=1) > book.same_m).all()


def test_a_relock_after_a_long_loss_is_a_new_lock_even_within_reach() -> None:
    """Lost for 2 s (> continue_s), the reach is 31 m: a lock 10 m away is within
    it, but could be anything that flew there; it does not inherit the hover."""
    book = LockBook(S)
    p = (100.0, 0.0, 20.0)
    t = _lock_for(book, 0.0, 1.5, p)
    book.update(_est(t, p), _cands((p, True)))
    book.update(_est(t + T, p, tracked=False), None)
    book.update(_est(t + 2.0, (110.0, 0.0, 20.0)), None)
    assert not book.continued
    assert not book.hovered


def test_the_likeliest_drone_comes_first_before_and_after_a_fix() -> None:
    """A person walking (p_drone 0.02) listed first by the detect stage, and pausing (it
    hovered), is put after a drone (p_drone 0.98) that has not hovered yet; candidates of
    equal rank keep the order of the rules above."""
    walker, drone, other = (26.0, 10.0, 1.0), (35.0, 0.0, 12.0), (40.0, 5.0, 12.0)
    cands = _cands((walker, True), (drone, False), (other, False))
    rank = np.array([0.02, 0.98, 0.5])
    fresh = LockBook(S)
    out = fresh.reachable(0.0, cands, rank)
    assert out is not None
    np.testing.assert_allclose(out.positions, [drone, other, walker])
    book = LockBook(S)
    t = _lock_for(book, 0.0, 1.5, (30.0, 0.0, 5.0))
    book.update(_est(t, (30.0, 0.0, 5.0), tracked=False), None)
    out = book.reachable(t + 3.0, cands, rank)
    assert out is not None
    np.testing.assert_allclose(out.positions, [drone, other, walker])
    out = book.reachable(t + 3.0, cands)  # without ranks: the hovered first
    assert out is not None
    np.testing.assert_allclose(out.positions[0], walker)
