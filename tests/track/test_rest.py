"""Identities at rest (``track.rest``): the matcher of births to the last fixes of the
tracks ended for room, and the layer's heirs."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.detect.tentative import ConfirmationSettings, TentativeTracks
from dronetrack.track.multi import MultiTargetTracker, TrackSettings
from dronetrack.track.rest import Resting, keep_at_cap, match_rested
from dronetrack.types import Detections

T = 0.1  # frame period [s]


def test_each_birth_takes_the_nearest_rested_track_within_the_radius_once() -> None:
    births = np.array([[0.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.5, 0.0, 0.0], [np.nan, 0, 0]])
    rested = np.array([[0.2, 0.0, 0.0], [10.9, 0.0, 0.0], [50.0, 0.0, 0.0]])
    rows, cols = match_rested(births, rested, 1.0)
    # birth 0 (0.2 m) and birth 2 (0.3 m) both near rested 0: the nearer takes it
    assert sorted(zip(rows.tolist(), cols.tolist(), strict=True)) == [(0, 0), (1, 1)]
    assert match_rested(births, rested, 0.1)[0].tolist() == []
    assert match_rested(births[:0], rested, 1.0)[0].tolist() == []


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**32 - 1), st.floats(0.1, 5.0))
def test_matches_are_within_the_radius_and_one_to_one(seed: int, radius: float) -> None:
    rng = np.random.default_rng(seed)
    births, rested = rng.uniform(-5, 5, (6, 3)), rng.uniform(-5, 5, (5, 3))
    rows, cols = match_rested(births, rested, radius)
    assert len(set(rows.tolist())) == len(rows)
    assert len(set(cols.tolist())) == len(cols)
    d = np.linalg.norm(births[:, None] - rested[None], axis=2)
    assert np.all(d[rows, cols] <= radius)
    # no pair left out that both sides could still take
    free_b = np.setdiff1d(np.arange(6), rows)
    free_r = np.setdiff1d(np.arange(5), cols)
    assert not np.any(d[np.ix_(free_b, free_r)] <= radius)


def test_at_the_cap_the_held_lives_and_the_unlikely_then_the_longest_unseen_die() -> None:
    """Five tracks, room for three: the held one lives although it is unlikely and
    the longest unseen; the other unlikely one dies before any; of the rest, the one
    last updated longest ago dies, and of two updated at once the fewer updates."""
    ids = np.array([1, 2, 3, 4, 5])
    updates = np.array([9, 9, 3, 8, 9])
    t_update = np.array([0.0, 5.0, 5.0, 5.0, 1.0])
    unlikely = np.array([True, True, False, False, False])
    held = np.array([True, False, False, False, False])
    kept = [keep_at_cap(ids, updates, t_update, unlikely, held, cap).tolist() for cap in (4, 3, 2)]
    assert kept[0] == [True, False, True, True, True]
    assert kept[1] == [True, False, True, True, False]
    assert kept[2] == [True, False, False, True, False]


def test_a_rested_track_is_forgotten_keep_s_after_it_ended() -> None:
    rest = Resting()
    rest.add(1.0, np.array([3, 4]), np.zeros((2, 3)))
    rest.add(2.0, np.array([9]), np.ones((1, 3)))
    rest.expire(6.0, 4.5)
    assert rest.ids.tolist() == [9]


def _found(centroids: np.ndarray) -> Detections:
    k = len(centroids)
    return Detections(
        np.asarray(centroids, dtype=np.float64).reshape(k, 3),
        np.full(k, 5),
        np.tile([0.4, 0.3, 0.2], (k, 1)),
        np.tile(0.01 * np.eye(3), (k, 1, 1)),
        np.zeros(k),
    )


def _heirs_after_a_full_frame(offset: float, rest_s: float = 1.0) -> list[tuple[int, int]]:
    """Four fragments tracked and held no drone; four new objects fill a layer of four,
    ending the fragments; once those leave, the fragments' clusters come back
    ``offset`` [m] from where they were, ``rest_s`` [s] after they ended: the heirs."""
    tentative = TentativeTracks(ConfirmationSettings(v_max=15.0, hits=2, frames=4))
    layer = MultiTargetTracker(TrackSettings(max_tracks=4, coast_s=2.0))
    fragments = np.array([[150.0, 10.0 * i, 5.0] for i in range(4)])
    crowd = np.array([[60.0 + 5 * i, -20.0, 8.0] for i in range(4)])
    heirs: list[tuple[int, int]] = []
    t = 0.0

    def step(centroids: np.ndarray) -> None:
        nonlocal t
        found = _found(centroids)
        layer.step(t, found, tentative.update(t, found), t_meas=t - 0.5 * T)
        new, old = layer.heirs
        heirs.extend(zip(new.tolist(), old.tolist(), strict=True))
        t += T

    for _ in range(10):
        step(fragments)
    first = layer.ids.copy()
    layer.note_unlikely(first)
    for _ in range(4):
        step(crowd)  # the fragments are missed, the crowd is born and takes the room
    assert not np.isin(first, layer.ids).any()
    assert sorted(layer.resting.tolist()) == sorted(first.tolist())
    t += rest_s
    for _ in range(4):
        step(fragments + np.array([offset, 0.0, 0.0]))
    assert not set(first.tolist()) & set(layer.ids.tolist())  # new identities
    return heirs


def test_births_where_tracks_held_no_drone_ended_for_room_are_their_heirs() -> None:
    heirs = _heirs_after_a_full_frame(0.5)
    assert len(heirs) == 4
    assert len({old for _, old in heirs}) == 4
    assert _heirs_after_a_full_frame(1.5) == []  # beyond merge_m (1 m): other objects
    assert _heirs_after_a_full_frame(0.5, rest_s=3.0) == []  # rested beyond coast_s
