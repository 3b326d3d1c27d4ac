"""Tentative tracks: M-of-N confirmation inside a speed gate."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.detect.tentative import (
    ConfirmationSettings,
    TentativeTracks,
    gated_assignment,
    kept,
    within_reach,
)
from dronetrack.errors import ConfigError
from dronetrack.types import Candidates, Detections

T = 0.1  # frame period [s]


def _found(*centroids: tuple[float, float, float], size: float = 0.5, count: int = 3) -> Detections:
    k = len(centroids)
    c = np.array(centroids, dtype=np.float64).reshape(k, 3)
    return Detections(
        c, np.full(k, count), np.tile([size, 0.1, 0.1], (k, 1)), np.zeros((k, 3, 3)), np.zeros(k)
    )


def test_a_moving_target_is_confirmed_on_its_third_frame_with_its_velocity() -> None:
    tracks = TentativeTracks(ConfirmationSettings(v_max=15.0, hits=3, frames=4))
    v = np.array([10.0, -4.0, 1.0])
    out = []
    for k in range(5):
        p = np.array([50.0, 10.0, 20.0]) + v * (k * T)
        out.append(tracks.update(k * T, _found(tuple(p))))
    assert [len(c) for c in out] == [0, 0, 1, 1, 1]
    # Exact centroids: (c − p)/Δt is v exactly, and so is its smoothed value.
    np.testing.assert_allclose(out[-1].velocities[0], v, atol=1e-9)
    np.testing.assert_allclose(out[-1].positions[0], [54.0, 8.4, 20.4], atol=1e-9)
    assert out[-1].hits[0] == 4
    assert out[-1].ids[0] == out[2].ids[0] == 0
    assert out[-1].sizes[0] == pytest.approx(0.5)


def test_m_of_n_tolerates_one_miss_and_drops_after_n_minus_m_plus_one() -> None:
    tracks = TentativeTracks(ConfirmationSettings(hits=3, frames=4))
    here = _found((30.0, 0.0, 5.0))
    none = Detections.empty()
    seen = [tracks.update(k * T, f) for k, f in enumerate([here, here, none, here])]
    # hits 1, 2, (miss), 3 of the last 4 frames: confirmed on the fourth
    assert [len(c) for c in seen] == [0, 0, 0, 1]
    # two misses in a row: 3 of 4 is out of reach, the track is gone
    tracks.update(4 * T, none)
    assert len(tracks) == 1
    tracks.update(5 * T, none)
    assert len(tracks) == 0


def test_a_jump_faster_than_v_max_starts_another_track() -> None:
    s = ConfirmationSettings(v_max=15.0, gate_m=1.0, hits=2, frames=2)
    tracks = TentativeTracks(s)
    tracks.update(0.0, _found((30.0, 0.0, 5.0)))
    # v_max Δt + g = 2.5 m: 2.4 m continues the track, 2.6 m cannot
    assert len(tracks.update(T, _found((32.4, 0.0, 5.0)))) == 1
    far = TentativeTracks(s)
    far.update(0.0, _found((30.0, 0.0, 5.0)))
    assert len(far.update(T, _found((32.6, 0.0, 5.0)))) == 0
    # the old track missed (and, as 2 of 2 is out of reach, is gone); a new one began
    assert far.ids.tolist() == [1]


def test_global_nearest_neighbour_minimises_the_total_distance() -> None:
    # Greedy nearest-first would give track 0 cluster 0 (distance 0.1) and leave track 1
    # cluster 1 at 1.9; the global optimum crosses them: 0.9 + 0.3.
    predicted = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    centroids = np.array([[0.9, 0.0, 0.0], [-0.9, 0.0, 0.0]])
    rows, cols = gated_assignment(predicted, predicted, np.array([5.0, 5.0]), centroids)
    assert sorted(zip(rows.tolist(), cols.tolist(), strict=True)) == [(0, 1), (1, 0)]
    # Outside every gate: no pair.
    rows, _ = gated_assignment(predicted, predicted, np.array([0.5, 0.5]), centroids + 5.0)
    assert len(rows) == 0


def _false_returns(settings: ConfirmationSettings, frames: int = 300) -> int:
    """Confirmations among ten single false returns a frame, uniform in a 200 m × 200 m
    × 50 m box (V = 2·10⁶ m³), for ``frames`` frames."""
    rng = np.random.default_rng(3)
    tracks = TentativeTracks(settings)
    confirmed = 0
    for k in range(frames):
        pts = rng.uniform([0, -100, 0], [200, 100, 50], (10, 3))
        confirmed += len(tracks.update(k * T, _found(*map(tuple, pts))))
        assert len(tracks) <= settings.max_tracks
    return confirmed


def test_random_false_returns_do_not_confirm_three_of_four() -> None:
    """A return lands in a given track's 2.5 m gate with probability about
    10 · (4/3 π 2.5³) / 2·10⁶ ≈ 3·10⁻⁴ a frame, so three in four frames do not happen."""
    assert _false_returns(ConfirmationSettings(hits=3, frames=4)) == 0


def test_random_false_returns_rarely_confirm_two_of_four() -> None:
    """The default, 2 of 4: a pair of false returns within a gate of each other does
    confirm.  A single-return track is kept for the 3 frames after its birth, with a
    gate growing as v_max Δt + g: 2.5, 4 and 5.5 m, 1,030 m³ in all, so each meets a
    second return with probability about 10 · 1,030 / 2·10⁶ ≈ 5·10⁻³; ten are born a
    frame: about 0.05 confirmations a frame, a Poisson mean of about 15 in 300 frames,
    below 5 or above 26 with probability under 1 %.  This is ten times the false-return
    density of any simulated scene (about one a frame), and the pairs' rate grows with
    its square."""
    n = _false_returns(ConfirmationSettings())
    assert 5 <= n <= 26


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n=st.integers(0, 12))
def test_confirmed_candidates_move_within_the_speed_gate(seed: int, n: int) -> None:
    """Each step is at most v_max Δt + g, so |v| ≤ v_max + g / Δt (Δt ≥ T here)."""
    rng = np.random.default_rng(seed)
    s = ConfirmationSettings(v_max=5.0, gate_m=0.5, hits=2, frames=3, max_tracks=8)
    tracks = TentativeTracks(s)
    p = rng.uniform(-20, 20, (n, 3))
    for k in range(15):
        p = p + rng.normal(0.0, 1.0, p.shape)  # some steps are faster than v_max
        out = tracks.update(k * T, _found(*map(tuple, p)))
        assert np.all(np.linalg.norm(out.velocities, axis=1) <= s.v_max + s.gate_m / T + 1e-9)
        assert np.all(out.hits >= s.hits)
        assert len(tracks) <= s.max_tracks
        assert len(np.unique(out.ids)) == len(out)


def test_bad_settings() -> None:
    with pytest.raises(ConfigError, match="cue_hits"):
        ConfirmationSettings(hits=3, frames=4, cue_hits=4)
    with pytest.raises(ConfigError, match="cue_points"):
        ConfirmationSettings(cue_points=-1)
    with pytest.raises(ConfigError, match="hits ≤ frames"):
        ConfirmationSettings(hits=5, frames=4)
    with pytest.raises(ConfigError, match="v_max > 0"):
        ConfirmationSettings(v_max=0.0)


def test_a_track_seen_twice_is_a_cue_until_it_confirms_or_drops() -> None:
    tracks = TentativeTracks(ConfirmationSettings(v_max=15.0, hits=3, frames=4, cue_hits=2))
    none = Detections.empty()
    tracks.update(0.0, _found((100.0, 0.0, 10.0)))
    assert len(tracks.cues(0.0)) == 0  # one hit: a single return is no cue
    tracks.update(T, _found((101.0, 0.0, 10.0)))
    cues = tracks.cues(T)
    assert len(cues) == 1
    assert cues.hits[0] == 2
    np.testing.assert_allclose(cues.velocities[0], [10.0, 0.0, 0.0], atol=1e-9)
    # Missed in the next frame: still a cue (2 of the last 4), at p + v Δt.
    tracks.update(2 * T, none)
    np.testing.assert_allclose(tracks.cues(2 * T).positions[0], [102.0, 0.0, 10.0], atol=1e-9)
    # Seen again: 3 of 4, confirmed, so no longer a cue.
    assert len(tracks.update(3 * T, _found((103.0, 0.0, 10.0)))) == 1
    assert len(tracks.cues(3 * T)) == 0


@pytest.mark.parametrize(
    ("cue_points", "count", "cue"), [(2, 2, True), (2, 1, False), (0, 5, False)]
)
def test_one_detection_of_cue_points_returns_is_a_cue(
    cue_points: int, count: int, cue: bool
) -> None:
    s = ConfirmationSettings(hits=2, frames=4, cue_hits=2, cue_points=cue_points)
    tracks = TentativeTracks(s)
    tracks.update(0.0, _found((140.0, 60.0, 25.0), count=count))
    assert len(tracks.cues(0.0)) == int(cue)
    # Missed twice more it is still a cue; dropped with its track on the third miss.
    for k in (1, 2):
        tracks.update(k * T, Detections.empty())
    assert len(tracks.cues(2 * T)) == int(cue)
    tracks.update(3 * T, Detections.empty())
    assert len(tracks) == 0
    assert len(tracks.cues(3 * T)) == 0


def test_a_cue_drops_with_its_track() -> None:
    tracks = TentativeTracks(ConfirmationSettings(hits=3, frames=4, cue_hits=2))
    here, none = _found((40.0, 5.0, 8.0)), Detections.empty()
    for k, f in enumerate([here, here, none, none]):
        tracks.update(k * T, f)
    assert len(tracks) == 0
    assert len(tracks.cues(3 * T)) == 0


def test_kept_spends_the_room_on_tracks_standing_alone_first() -> None:
    detections = np.array([9, 8, 7, 1, 1, 5])
    ids = np.arange(6)
    crowd = np.array([True, True, True, False, False, False])
    # room for 4, of it at most 2 crowded: the three alone, then the most detected crowded
    assert kept(detections, ids, crowd, 4, 2).tolist() == [True, False, False, True, True, True]
    # room for 3: the alone fill it, whatever the crowded were detected
    assert kept(detections, ids, crowd, 3, 2).tolist() == [False] * 3 + [True] * 3
    # of equals the older: ids 3 and 4 were both detected once
    assert kept(detections, ids, crowd, 2, 2).tolist() == [False] * 3 + [True, False, True]


@settings(max_examples=60, deadline=None)
@given(
    detections=st.lists(st.integers(1, 30), min_size=0, max_size=40),
    data=st.data(),
    max_tracks=st.integers(1, 20),
    share=st.floats(0.0, 1.0),
)
def test_kept_bounds_the_crowded_and_drops_none_alone_while_room_is_left(
    detections: list[int], data: st.DataObject, max_tracks: int, share: float
) -> None:
    n = len(detections)
    crowd = np.array(data.draw(st.lists(st.booleans(), min_size=n, max_size=n)), dtype=bool)
    d, ids = np.array(detections, dtype=np.int64), np.arange(n, dtype=np.int64)
    max_crowded = int(share * max_tracks)
    keep = kept(d, ids, crowd, max_tracks, max_crowded)
    assert keep.sum() <= max_tracks
    assert (keep & crowd).sum() <= max_crowded
    alone = ~crowd
    if (alone & ~keep).any():  # a track alone was dropped: the room was full of them
        assert (keep & alone).sum() == max_tracks
        assert d[keep & alone].min() >= d[alone & ~keep].max()
    if (crowd & ~keep).any() and (crowd & keep).any():
        assert d[keep & crowd].min() >= d[crowd & ~keep].max()
    assert keep.sum() == min(n, max_tracks, alone.sum() + max_crowded)


def test_a_lone_cluster_among_a_flood_of_fragments_is_confirmed() -> None:
    """A far structure the map lacks breaks into fragments 1.5 m apart, each detected
    in every frame, more than the tentative room holds; a drone's lone cluster that
    comes into view among them is confirmed on its second detection as if alone.
    Kept first by their detections, the fragments would fill the room, and the
    drone's new track would be dropped as soon as it was added, frame after frame."""
    s = ConfirmationSettings(hits=2, frames=4, max_tracks=16, crowd_gap_m=2.0)
    sensor = np.zeros(3)
    # 40 fragments along a tree line 120 m out: gaps 1.0 m ≤ min(2 m, 1° × 120 m)
    line = [(120.0, 1.5 * i, 8.0) for i in range(40)]
    tracks = TentativeTracks(s)
    for k in range(5):
        tracks.update(k * T, _found(*line), sensor)
    assert len(tracks) == s.max_crowded == 8  # half the room: the rest is kept free
    drone = (70.0, -40.0, 20.0)
    tracks.update(5 * T, _found(*line, drone), sensor)
    out = tracks.update(6 * T, _found(*line, (70.2, -40.0, 20.0)), sensor)
    assert len(tracks) <= s.max_tracks
    assert any(np.linalg.norm(p - [70.2, -40.0, 20.0]) < 0.1 for p in out.positions)
    # without the crowded test the fragments, detected more often, keep all the room
    plain = TentativeTracks(ConfirmationSettings(hits=2, frames=4, max_tracks=16))
    for k in range(5):
        plain.update(k * T, _found(*line), sensor)
    plain.update(5 * T, _found(*line, drone), sensor)
    out = plain.update(6 * T, _found(*line, (70.2, -40.0, 20.0)), sensor)
    assert not any(np.linalg.norm(p - [70.2, -40.0, 20.0]) < 0.1 for p in out.positions)


def _cands(positions: np.ndarray) -> Candidates:
    k = len(positions)
    ids = np.arange(k, dtype=np.int64)
    return Candidates(positions, np.zeros((k, 3)), np.full(k, 3), np.full(k, 0.4), ids)


def test_within_reach_keeps_what_the_target_could_reach_in_order() -> None:
    c = _cands(np.array([[40.0, 0.0, 10.0], [12.0, 0.0, 10.0], [18.0, 0.0, 10.0], [9.0, 0, 10]]))
    # Last fixed at (10, 0, 10) 1 s ago: reach 15 · 1 + 1 = 16 m; 40 m away is out.
    out = within_reach(c, 1.0, np.array([10.0, 0, 10]), 15.0, 1.0)
    assert out.ids.tolist() == [1, 2, 3]
    # 2 s on: reach 31 m takes in the far one too.
    assert within_reach(c, 2.0, np.array([10.0, 0, 10]), 15.0, 1.0).ids.tolist() == [0, 1, 2, 3]


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 2**31 - 1), st.floats(0.0, 5.0))
def test_within_reach_is_the_reachable_subset_in_order(seed: int, dt: float) -> None:
    rng = np.random.default_rng(seed)
    c = _cands(rng.uniform(-80.0, 80.0, (12, 3)))
    p = rng.uniform(-20.0, 20.0, 3)
    out = within_reach(c, dt, p, 15.0, 1.0)
    near = np.linalg.norm(c.positions - p, axis=1) <= 15.0 * dt + 1.0
    assert out.ids.tolist() == c.ids[near].tolist()


def _fly(tracks: TentativeTracks, v: np.ndarray, frames: int, t0: float = 0.0) -> Candidates:
    """A target at constant velocity ``v`` seen in every frame; the last confirmed set."""
    out = Candidates.empty()
    for k in range(frames):
        p = np.array([40.0, 5.0, 10.0]) + v * (k * T)
        out = tracks.update(t0 + k * T, _found(tuple(p)))
    return out


def test_a_hover_shows_on_the_fourth_detection_not_before() -> None:
    # v is measured from the 2nd detection on; K = 3 slow ones in a row: the 4th.
    s = ConfirmationSettings(hover_speed=4.0, hover_frames=3)
    flags = [
        bool(_fly(TentativeTracks(s), np.array([0.0, 0.0, 2.5]), n).hovered[0]) for n in (2, 3, 4)
    ]
    assert flags == [False, False, True]


def test_a_bird_at_its_slowest_never_hovers() -> None:
    # 5 m/s, the slowest bird of the clutter model, for 50 frames
    out = _fly(TentativeTracks(ConfirmationSettings()), np.array([3.0, 4.0, 0.0]), 50)
    assert len(out) == 1
    assert not out.hovered[0]


def test_a_track_that_hovered_keeps_the_flag_at_speed_and_comes_first() -> None:
    tracks = TentativeTracks(ConfirmationSettings())
    v_hover, v_fast = np.array([1.0, 0.0, 0.0]), np.array([12.0, 0.0, 0.0])
    p_bird = np.array([80.0, -30.0, 40.0])
    p = np.array([20.0, 0.0, 5.0])
    out = Candidates.empty()
    for k in range(12):
        v = v_hover if k < 5 else v_fast
        p = p + v * T
        # equal hits and detections; the bird's track is the older (listed first): it
        # would come first without the flag
        out = tracks.update(
            k * T, _found(tuple(p_bird + np.array([9.0, 0.0, 0.0]) * k * T), tuple(p))
        )
    assert len(out) == 2
    assert out.hovered.tolist() == [True, False]
    np.testing.assert_allclose(out.positions[0], p)


def test_a_confirmed_candidate_names_its_cluster_of_the_frame() -> None:
    tracks = TentativeTracks(ConfirmationSettings(v_max=15.0, hits=2, frames=4))
    g = np.random.default_rng(2)
    for k in range(6):
        drones = np.array([[30.0 + k, 0.0, 10.0], [60.0, 20.0 - k, 15.0]])
        clutter = g.uniform([0, -100, 0], [200, 100, 50], size=(3, 3))
        order = g.permutation(5)
        found = _found(*map(tuple, np.vstack([drones, clutter])[order]))
        confirmed = tracks.update(T * k, found)
    assert len(confirmed) == 2
    assert np.all(confirmed.clusters >= 0)
    np.testing.assert_array_equal(confirmed.positions, found.centroids[confirmed.clusters])
