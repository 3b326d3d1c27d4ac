"""Which target the single-target tracker follows among the tracks
(``pipeline.selection``): the rules' known answers on hand-built frames."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from numpy.typing import ArrayLike

from dronetrack.control.choose import ChooseSettings, TargetChooser, not_static
from dronetrack.detect.lock import LockBook
from dronetrack.detect.tentative import ConfirmationSettings
from dronetrack.pipeline.selection import STATIC_HOLD_S, TargetSelection, rank
from dronetrack.types import TRACK_CLASSES, Candidates, Detections, TrackEstimate, Tracks
from track_helpers import hand_tracks

DRONE, STATIC = TRACK_CLASSES.index("drone"), TRACK_CLASSES.index("static")
UNKNOWN = TRACK_CLASSES.index("unknown")


class _Tracker:
    """Records what the selection asks of the tracker."""

    def __init__(self) -> None:
        self.resets = 0
        self.starts: list[Candidates] = []

    def reset(self) -> None:
        self.resets += 1

    def acquire(self, candidates: Candidates) -> None:
        self.starts.append(candidates)


def _frame(
    positions: ArrayLike, classes: list[int], p: list[float], hovered: list[bool] | None = None
) -> tuple[Detections, Candidates, Tracks]:
    """One cluster, one confirmed candidate and one track per position, in that order,
    each track updated by its own cluster; ``hovered``: which candidates hovered."""
    c = np.array(positions, dtype=float)
    k = len(c)
    found = Detections(
        c, np.full(k, 10), np.ones((k, 3)), np.tile(np.eye(3), (k, 1, 1)), np.zeros(k)
    )
    ids = np.arange(1, k + 1)
    flags = np.zeros(k, dtype=bool) if hovered is None else np.array(hovered)
    offered = Candidates(
        c, np.zeros((k, 3)), np.full(k, 3), np.ones(k), ids, hovered=flags, clusters=ids - 1
    )
    tracks = replace(
        hand_tracks(ids.tolist(), c, classes), p_drone=np.array(p, dtype=float), clusters=ids - 1
    )
    return found, offered, tracks


def _locked_on(position: list[float], t: float, since: float = 0.0) -> LockBook:
    """A lock book whose tracker has held ``position`` from ``since`` to ``t``."""
    lock = LockBook(ConfirmationSettings())
    for time in (since, t):
        p = np.array(position, dtype=float)
        lock.update(TrackEstimate(time, p, np.zeros(3), True, 0.3), None)
    return lock


def test_rank_is_each_candidates_track_p_drone_and_even_without_one() -> None:
    found, offered, tracks = _frame([[50, 0, 10], [80, 5, 20]], [DRONE, UNKNOWN], [0.98, 0.3])
    assert rank(offered, found, tracks) == pytest.approx([0.98, 0.3])
    lone = replace(tracks, clusters=np.array([0, -1]))  # the second cluster has no track
    assert rank(offered, found, lone) == pytest.approx([0.98, 0.5])
    assert rank(offered, found, None) is None


def test_a_lock_on_no_drone_restarts_on_the_drone_track() -> None:
    # threats (d_ref 100 m): the drone 0.98 · 100 / 164 = 0.60, the held 0.5 · 100 / 151
    # = 0.33, so the drone is well over the 1.5 × hysteresis
    found, offered, tracks = _frame([[50, 0, 10], [60, 20, 15]], [UNKNOWN, DRONE], [0.5, 0.98])
    lock, tracker = _locked_on([50, 0, 10], t=3.0), _Tracker()
    TargetSelection().step(3.0, found, tracks, offered, lock, tracker)
    assert tracker.resets == 1
    assert not lock.locked
    assert len(tracker.starts) == 1
    np.testing.assert_allclose(tracker.starts[0].positions, [[60, 20, 15]])


def test_a_drone_track_within_apart_m_of_the_lock_is_the_held_object() -> None:
    # the lock's estimate lags: the drone's track 3 m from it, an unknown track on it
    found, offered, tracks = _frame([[50, 0, 10], [53, 0, 10]], [UNKNOWN, DRONE], [0.5, 0.98])
    lock, tracker = _locked_on([50, 0, 10], t=3.0), _Tracker()
    TargetSelection().step(3.0, found, tracks, offered, lock, tracker)
    assert tracker.resets == 0
    assert tracker.starts == []


def test_a_lock_on_what_never_hovered_restarts_on_a_candidate_that_did() -> None:
    # two tracks of no class; the one away from the lock has hovered (no bird can)
    positions = [[50, 0, 10], [70, -30, 20]]
    found, offered, tracks = _frame(positions, [UNKNOWN, UNKNOWN], [0.5, 0.5], [False, True])
    lock, tracker = _locked_on([50, 0, 10], t=3.0), _Tracker()
    TargetSelection().step(3.0, found, tracks, offered, lock, tracker)
    assert tracker.resets == 1
    assert not lock.locked
    np.testing.assert_allclose(tracker.starts[0].positions, [[70, -30, 20]])


def test_the_chooser_turns_the_turret_to_a_drone_never_served() -> None:
    # two drone-class tracks 60° apart; the held one keeps the turret for hold_s, then
    # the other gets its first look: the tracker lets go and starts on its candidate,
    # or, without one this frame, the turret looks where its track is
    positions = [[50, 0, 10], [25, 43, 10]]
    found, offered, tracks = _frame(positions, [DRONE, DRONE], [0.98, 0.98])
    selection = TargetSelection(TargetChooser(ChooseSettings()))
    lock, tracker = _locked_on([50, 0, 10], t=0.0), _Tracker()
    selection.step(0.0, found, tracks, offered, lock, tracker)
    assert tracker.resets == 0  # the held one is served first
    lock.update(TrackEstimate(1.5, np.array([50.0, 0, 10]), np.zeros(3), True, 0.3), None)
    mine = selection.step(1.5, found, tracks, offered, lock, tracker)
    assert tracker.resets == 1
    assert not lock.locked
    np.testing.assert_allclose(mine.positions, [[25, 43, 10]])  # the served track's only
    np.testing.assert_allclose(tracker.starts[-1].positions, [[25, 43, 10]])
    assert selection.look is None
    coasting = replace(tracks, clusters=np.array([0, -1]))  # no cluster of it this frame
    selection.step(1.6, found, coasting, offered.take(np.array([0])), lock, tracker)
    assert selection.look is not None
    np.testing.assert_allclose(selection.look.positions, [[25, 43, 10]])


def test_a_lock_on_a_drone_track_stays() -> None:
    found, offered, tracks = _frame([[50, 0, 10], [80, 40, 20]], [DRONE, DRONE], [0.98, 0.98])
    lock, tracker = _locked_on([50, 0, 10], t=3.0), _Tracker()
    TargetSelection().step(3.0, found, tracks, offered, lock, tracker)
    assert tracker.resets == 0
    assert tracker.starts == []
    assert lock.locked


def test_a_lock_on_a_static_track_is_given_up_after_the_hold() -> None:
    found, offered, tracks = _frame([[50, 0, 0.5]], [STATIC], [0.01])
    offered = not_static(offered, found, tracks)  # as the pipeline offers them: none
    selection, tracker = TargetSelection(), _Tracker()
    lock = _locked_on([50, 0, 0.5], t=2.0)
    selection.step(2.0, found, tracks, offered, lock, tracker)
    assert tracker.resets == 0
    assert lock.locked
    lock.update(
        TrackEstimate(2.0 + STATIC_HOLD_S, np.array([50, 0, 0.5]), np.zeros(3), True, 0.3), None
    )
    selection.step(2.0 + STATIC_HOLD_S, found, tracks, offered, lock, tracker)
    assert tracker.resets == 1
    assert not lock.locked
    assert tracker.starts == []  # nothing else to start on


def test_unlocked_it_starts_within_the_lost_targets_reach_the_likeliest_drone_first() -> None:
    # the lock's fix at (50, 0, 10) at t = 2; lost; at t = 3 the reach is 15 + 1 m
    lock = _locked_on([50, 0, 10], t=2.0)
    lock.update(TrackEstimate(2.5, np.array([50.0, 0, 10]), np.zeros(3), False, 5.0), None)
    positions = [[55, 0, 10], [58, 3, 10], [150, 60, 20]]
    found, offered, tracks = _frame(positions, [UNKNOWN, UNKNOWN, DRONE], [0.3, 0.6, 0.98])
    tracker = _Tracker()
    TargetSelection().step(3.0, found, tracks, offered, lock, tracker)
    assert tracker.resets == 0
    assert len(tracker.starts) == 1
    # the drone-class track 117 m away waits; of the two within reach, p_drone first
    np.testing.assert_allclose(tracker.starts[0].positions, [[58, 3, 10], [55, 0, 10]])
