"""Every object a track (``track.multi``): the constant-velocity filter bank, its gates
and assignment, births on confirmed candidates, deaths after coasting."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from dronetrack.detect.tentative import ConfirmationSettings, TentativeTracks
from dronetrack.errors import ConfigError, InputError
from dronetrack.track.cv_bank import (
    associate,
    cv_predict,
    cv_process_noise,
    cv_update,
    gate_costs,
    on_or_above,
)
from dronetrack.track.kalman import cv_transition, kf_predict, kf_update, position_selector
from dronetrack.track.multi import Floor, InView, MultiTargetTracker, TrackSettings
from dronetrack.track.same_object import close_pairs, one_object, within_smear
from dronetrack.types import Candidates, Detections, TrackEstimate

T = 0.1  # frame period [s]


def _found(centroids: np.ndarray, sigma: float = 0.1) -> Detections:
    """Clusters at ``centroids`` (D, 3), each with an isotropic point spread σ."""
    k = len(centroids)
    cov = np.tile(sigma**2 * np.eye(3), (k, 1, 1))
    return Detections(
        np.asarray(centroids, dtype=np.float64).reshape(k, 3),
        np.full(k, 5),
        np.tile([0.4, 0.3, 0.2], (k, 1)),
        cov,
        np.zeros(k),
    )


class _Layer:
    """The detect stage's tentative tracks feeding the track layer, as the pipeline runs
    them (clusters at the frame's middle, the state at its end)."""

    def __init__(self, **track_settings: float) -> None:
        self.tentative = TentativeTracks(ConfirmationSettings(v_max=15.0, hits=2, frames=4))
        self.tracks = MultiTargetTracker(TrackSettings(**track_settings))  # type: ignore[arg-type]

    def step(
        self,
        t: float,
        centroids: np.ndarray,
        in_view: InView | None = None,
        floor: Floor | None = None,
    ) -> None:
        found = _found(centroids)
        confirmed = self.tentative.update(t, found)
        self.tracks.step(t, found, confirmed, t_meas=t - 0.5 * T, in_view=in_view, floor=floor)


def test_process_noise_is_the_white_acceleration_model() -> None:
    dt, sa = 0.2, 3.0
    Q = cv_process_noise(np.array([dt]), sa)[0]
    q = sa**2
    for i in range(3):
        assert Q[i, i] == pytest.approx(q * dt**4 / 4)
        assert Q[i, i + 3] == Q[i + 3, i] == pytest.approx(q * dt**3 / 2)
        assert Q[i + 3, i + 3] == pytest.approx(q * dt**2)
    assert Q[0, 1] == Q[0, 4] == 0.0


def test_the_bank_predicts_each_track_as_one_kalman_filter_would() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(size=(4, 6))
    A = rng.normal(size=(4, 6, 6))
    P = A @ np.transpose(A, (0, 2, 1)) + np.eye(6)
    dt = np.array([0.0, 0.1, 0.35, 2.0])
    xb, Pb = cv_predict(x, P, dt, 4.0)
    for k in range(4):
        xk, Pk = kf_predict(
            x[k], P[k], cv_transition(dt[k]), cv_process_noise(dt[k : k + 1], 4.0)[0]
        )
        np.testing.assert_allclose(xb[k], xk, atol=1e-12)
        np.testing.assert_allclose(Pb[k], Pk, atol=1e-9)


def test_the_bank_updates_each_track_as_one_kalman_filter_would() -> None:
    rng = np.random.default_rng(4)
    x = rng.normal(size=(5, 6))
    A = rng.normal(size=(5, 6, 6))
    P = A @ np.transpose(A, (0, 2, 1)) + np.eye(6)
    z = rng.normal(size=(5, 3))
    B = rng.normal(size=(5, 3, 3))
    R = B @ np.transpose(B, (0, 2, 1)) + 0.1 * np.eye(3)
    xb, Pb = cv_update(x, P, z, R)
    for k in range(5):
        up = kf_update(x[k], P[k], z[k], position_selector(6), R[k])
        np.testing.assert_allclose(xb[k], up.x, atol=1e-10)
        np.testing.assert_allclose(Pb[k], up.P, atol=1e-9)


@settings(max_examples=30, deadline=None)
@given(
    st.lists(st.floats(0.0, 5.0), min_size=1, max_size=5),
    st.floats(0.1, 30.0),
    st.integers(0, 2**32 - 1),
)
def test_predicted_covariances_stay_symmetric_and_positive(
    dts: list[float], sa: float, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    k = len(dts)
    A = rng.normal(size=(k, 6, 6))
    P = A @ np.transpose(A, (0, 2, 1)) + 1e-3 * np.eye(6)
    _, Pb = cv_predict(rng.normal(size=(k, 6)), P, np.array(dts), sa)
    np.testing.assert_allclose(Pb, np.transpose(Pb, (0, 2, 1)), atol=1e-9)
    assert np.all(np.linalg.eigvalsh(Pb) > 0)


def test_gate_costs_are_the_pairs_log_likelihood_inside_both_gates() -> None:
    x = np.array([[0.0, 0, 0, 10, 0, 0]])
    P = np.eye(6)[None] * 0.25  # σ 0.5 m per axis
    R = np.tile(0.25 * np.eye(3), (3, 1, 1))
    gate = chi2.ppf(0.99, 3)
    z = np.array([[0.0, 0, 0], [1.0, 0, 0], [5.0, 0, 0]])
    cost = gate_costs(x, P, np.zeros((1, 3)), np.array([10.0]), z, R, gate)
    S = 0.5 * np.eye(3)
    # J = d² + ln|S|: at the prediction d² = 0; one metre off d² = 1 / 0.5 = 2
    assert cost[0, 0] == pytest.approx(np.log(np.linalg.det(S)))
    assert cost[0, 1] == pytest.approx(2.0 + np.log(np.linalg.det(S)))
    assert cost[0, 2] >= 1e12  # d² = 50 > χ²₃(0.99)
    # the speed gate: a cluster 1 m off is out of a 0.5 m reach, whatever d²
    tight = gate_costs(x, P, np.zeros((1, 3)), np.array([0.5]), z, R, gate)
    assert tight[0, 0] < 1e12 <= tight[0, 1]


def test_the_assignment_keeps_feasible_pairs_only() -> None:
    cost = np.array([[1.0, 1e12], [1e12, 1e12]])
    rows, cols = associate(cost)
    assert rows.tolist() == [0]
    assert cols.tolist() == [0]
    assert [len(a) for a in associate(np.empty((0, 3)))] == [0, 0]


def test_a_track_is_born_on_a_confirmed_candidate_and_dies_after_coasting() -> None:
    layer = _Layer(coast_s=1.0)
    p = np.array([[30.0, 5.0, 10.0]])
    for k in range(3):
        layer.step(k * T, p)
    assert layer.tracks.ids.tolist() == [1]  # born on the second frame (2 of 4)
    assert layer.tracks.born[0] == pytest.approx(T - 0.5 * T)
    for k in range(3, 3 + 10):  # the object is gone: it coasts 1 s, then ends
        layer.step(k * T, np.empty((0, 3)))
    assert len(layer.tracks) == 1
    layer.step(13 * T, np.empty((0, 3)))
    assert len(layer.tracks) == 0
    for k in range(14, 17):  # it comes back: a new identity, never a reused one
        layer.step(k * T, p)
    assert layer.tracks.ids.tolist() == [2]


def _lives(layer: _Layer, frames: int) -> int:
    """How many empty frames after ``frames`` frames of an object its track lives."""
    p = np.array([[12.0, -3.0, 2.0]])
    for k in range(frames):
        layer.step(k * T, p)
    assert layer.tracks.ids.tolist() == [1]
    alive = 0
    for k in range(frames, frames + 100):
        layer.step(k * T, np.empty((0, 3)))
        if len(layer.tracks) == 0:
            break
        alive += 1
    return alive


def test_a_track_never_updated_after_its_birth_lives_its_probation_only() -> None:
    """Two returns in two frames confirm a candidate (2 of 4) and give a track with its
    birth as its only update: it lives probation_s (1 s) missed, to a frame.  One
    return more, an update after its birth, and it lives coast_s (3 s)."""
    assert 1.0 - T - 1e-9 <= _lives(_Layer(coast_s=3.0, probation_s=1.0), 2) * T <= 1.0 + 1e-9
    assert 3.0 - T - 1e-9 <= _lives(_Layer(coast_s=3.0, probation_s=1.0), 3) * T <= 3.0 + 1e-9
    # without a probation, or a longer one than coast_s, coast_s bounds both
    assert 3.0 - T - 1e-9 <= _lives(_Layer(coast_s=3.0), 2) * T <= 3.0 + 1e-9
    assert 3.0 - T - 1e-9 <= _lives(_Layer(coast_s=3.0, probation_s=9.0), 2) * T <= 3.0 + 1e-9


def test_a_track_on_probation_out_of_view_is_not_missed() -> None:
    """The probation counts only the frames that saw where the track is, as coast_s."""
    layer = _Layer(coast_s=3.0, probation_s=0.5, unseen_s=30.0)
    p = np.array([[12.0, -3.0, 2.0]])
    for k in range(2):
        layer.step(k * T, p)
    for k in range(2, 40):  # 3.8 s out of view
        layer.step(k * T, np.empty((0, 3)), _nowhere)
    assert layer.tracks.ids.tolist() == [1]
    alive = 0
    for k in range(40, 60):
        layer.step(k * T, np.empty((0, 3)))
        if len(layer.tracks) == 0:
            break
        alive += 1
    assert 0.5 - T - 1e-9 <= alive * T <= 0.5 + 1e-9


def _nowhere(p: np.ndarray) -> np.ndarray:
    return np.zeros(len(p), dtype=bool)


def test_a_track_out_of_view_is_not_missed_and_lives_until_unseen_s() -> None:
    """coast_s 1 s counts only the frames that saw where the track is; unseen_s 3 s
    bounds its life wherever it is.  Its object is gone at 0.25 s (its last update)."""
    layer = _Layer(coast_s=1.0, unseen_s=3.0)
    p = np.array([[30.0, 5.0, 10.0]])
    for k in range(3):
        layer.step(k * T, p)
    last = layer.tracks.t_update[0]
    k = 3
    while (k * T - 0.5 * T) - last <= 3.0 - 1e-9:  # out of view: alive 3 s after it
        layer.step(k * T, np.empty((0, 3)), _nowhere)
        assert layer.tracks.ids.tolist() == [1], k
        snap = layer.tracks.snapshot()
        assert snap.missed_s[0] == pytest.approx(0.0, abs=1e-9)
        assert not snap.in_view[0]
        k += 1
    layer.step(k * T, np.empty((0, 3)), _nowhere)
    assert len(layer.tracks) == 0
    # in view again after 2 s away: missed from then on, it ends 1 s later
    layer = _Layer(coast_s=1.0, unseen_s=30.0)
    for k in range(3):
        layer.step(k * T, p)
    for k in range(3, 23):
        layer.step(k * T, np.empty((0, 3)), _nowhere)
    alive = 0
    for k in range(23, 60):
        layer.step(k * T, np.empty((0, 3)), lambda q: np.ones(len(q), dtype=bool))
        if len(layer.tracks) == 0:
            break
        alive += 1
        assert layer.tracks.snapshot().missed_s[0] == pytest.approx(alive * T)
    assert 1.0 - T - 1e-9 <= alive * T <= 1.0 + 1e-9  # coast_s, to a frame


def test_a_track_a_cluster_of_the_frame_updated_is_in_view() -> None:
    """The field of view is the one at the frame's end; a turret slewing through the
    frame may have left behind a track whose returns came in earlier.  A cluster of the
    frame updated it, so the sensor saw it: in view, whatever the end's field says."""
    layer = _Layer()
    p = np.array([[30.0, 5.0, 10.0]])
    for k in range(3):
        layer.step(k * T, p)
    layer.step(3 * T, p, _nowhere)  # seen, the end's field holds nothing
    snap = layer.tracks.snapshot()
    assert snap.ids.tolist() == [1]
    assert layer.tracks.updated[0]
    assert snap.in_view[0]
    layer.step(4 * T, np.empty((0, 3)), _nowhere)  # not seen, not in the field
    assert not layer.tracks.snapshot().in_view[0]


def test_a_track_that_lived_on_out_of_view_takes_no_cluster_far_from_its_prediction() -> None:
    """Unseen for 3 s (out of view), a track at rest takes a confirmed candidate's
    cluster within stale_gate_m + birth_sigma_v × 3 s = 5 + 5 × 3 = 20 m of its
    prediction, never one farther, which its grown gates would let it take (σ_a 15 m/s²,
    a run's: σ ≈ 13 m per axis after 3 s, so 40 m is within the 4.5 σ gate)."""
    for offset, same in ((12.0, True), (40.0, False)):
        layer = _Layer(coast_s=1.0, unseen_s=30.0, sigma_acc=15.0)
        p = np.array([[60.0, 0.0, 20.0]])
        for k in range(6):
            layer.step(k * T, p)
        for k in range(6, 36):
            layer.step(k * T, np.empty((0, 3)), _nowhere)
        q = p + np.array([[0.0, offset, 0.0]])
        for k in range(36, 40):
            layer.step(k * T, q)
        assert (layer.tracks.ids.tolist() == [1]) is same, offset
        if not same:
            assert layer.tracks.ids.tolist() == [1, 2]  # a new object, the old one unseen


def test_a_lone_return_never_makes_a_track() -> None:
    layer = _Layer()
    rng = np.random.default_rng(0)
    for k in range(30):  # one false return a frame, anywhere within 100 m
        layer.step(k * T, rng.uniform(-100, 100, size=(1, 3)))
    assert len(layer.tracks) == 0


def _crossing(t: float) -> np.ndarray:
    """Two drones at 10 m/s on paths crossing at 60° at (40, 0, 20) at t = 2 s."""
    c = np.array([40.0, 0.0, 20.0])
    a = np.radians(30.0)
    u = np.array([np.cos(a), np.sin(a), 0.0])
    w = np.array([np.cos(a), -np.sin(a), 0.0])
    return np.stack([c + 10.0 * (t - 2.0) * u, c + 10.0 * (t - 2.0) * w])


def test_two_crossing_drones_keep_their_identities() -> None:
    rng = np.random.default_rng(7)
    layer = _Layer(sigma_acc=15.0)
    owners: set[tuple[int, int]] = set()
    for k in range(41):
        t = k * T
        truth = _crossing(t - 0.5 * T)
        if np.linalg.norm(truth[0] - truth[1]) < 1.0:  # one cluster (DBSCAN ε = 1 m)
            truth = truth.mean(axis=0, keepdims=True)
        layer.step(t, truth + rng.normal(scale=0.1, size=truth.shape))
        gt = _crossing(t)
        if k >= 3 and np.linalg.norm(gt[0] - gt[1]) > 2.0:
            d = np.linalg.norm(layer.tracks.x[:, None, :3] - gt[None, :, :], axis=2)
            assert d.min(axis=0).max() < 1.0  # each drone has a track within 1 m
            owners.add(
                (
                    int(layer.tracks.ids[np.argmin(d[:, 0])]),
                    int(layer.tracks.ids[np.argmin(d[:, 1])]),
                )
            )
    assert len(layer.tracks) == 2
    assert owners == {(1, 2)}  # the same identities before and after the crossing


def test_twenty_objects_among_fifty_clusters_a_frame_keep_twenty_tracks() -> None:
    rng = np.random.default_rng(11)
    start = rng.uniform([-80, -80, 5], [80, 80, 60], size=(20, 3))
    v = rng.uniform(-12, 12, size=(20, 3)) * np.array([1, 1, 0.2])
    layer = _Layer(sigma_acc=15.0)
    for k in range(40):
        t = k * T
        objects = start + v * (t - 0.5 * T) + rng.normal(scale=0.1, size=(20, 3))
        clutter = rng.uniform([-100, -100, 0], [100, 100, 80], size=(30, 3))
        layer.step(t, np.concatenate([objects, clutter]))
    truth = start + v * (39 * T)
    d = np.linalg.norm(layer.tracks.x[:, None, :3] - truth[None], axis=2)
    near = d.min(axis=0)
    assert np.all(near < 1.0)  # every object has its track
    # each object's track is the one born on it: 20 identities, none of them clutter's
    owners = layer.tracks.ids[np.argmin(d, axis=0)]
    assert len(set(owners.tolist())) == 20
    # clutter's chance pairs make short-lived tracks only: over seeds 0-29 none got more
    # than 4 updates, where every object's got one a frame since its birth
    objects = np.isin(layer.tracks.ids, owners)
    assert layer.tracks.updates[objects].min() >= 35
    assert layer.tracks.updates[~objects].max(initial=0) <= 5


def test_a_full_layer_keeps_its_established_tracks_over_a_frame_of_births() -> None:
    # One object tracked for a second, then a frame floods the layer with as many new
    # objects as it holds: of the tracks all updated this frame, the newest go first.
    layer = _Layer(max_tracks=4)
    drone = np.array([[30.0, 5.0, 10.0]])
    for k in range(10):
        layer.step(k * T, drone)
    (first,) = layer.tracks.ids.tolist()
    crowd = np.array([[60.0 + 5 * i, -20.0, 8.0] for i in range(4)])
    for k in range(10, 14):
        layer.step(k * T, np.concatenate([drone, crowd]))
        assert first in layer.tracks.ids.tolist()
        assert len(layer.tracks) <= 4
    assert len(layer.tracks) == 4  # the crowd's births fill the rest


def test_at_the_cap_the_tracks_the_classes_hold_no_drone_die_first() -> None:
    # A full layer of established tracks on fragments of a far structure, then a drone
    # comes into view: without the classes' word the fragments, updated longer, outlive
    # the drone's new track; once they are noted unlikely, the drone's track is kept.
    fragments = np.array([[150.0, 10.0 * i, 5.0] for i in range(4)])
    drone = np.array([[40.0, -20.0, 15.0]])
    for unlikely, kept in ((False, False), (True, True)):
        layer = _Layer(max_tracks=4)
        for k in range(10):
            layer.step(k * T, fragments)
        if unlikely:
            layer.tracks.note_unlikely(layer.tracks.ids.copy())
        for k in range(10, 14):
            layer.step(k * T, np.concatenate([fragments, drone]))
        near = np.linalg.norm(layer.tracks.snapshot().positions - drone, axis=1) < 1.0
        assert bool(near.any()) is kept
        assert len(layer.tracks) == 4


def test_at_the_cap_the_track_the_turret_holds_lives_though_held_no_drone() -> None:
    # The turret locked on a fragment the classes then hold no drone: at the cap it
    # must outlive the others, else the tracker stays locked on what no track follows
    # and the lock on what the classes are about to call static is never given up.
    fragments = np.array([[150.0, 10.0 * i, 5.0] for i in range(4)])
    births = np.array([[60.0 + 5 * i, -20.0, 8.0] for i in range(4)])
    for lock in (False, True):
        layer = _Layer(max_tracks=4)
        for k in range(10):
            layer.step(k * T, fragments)
        target = int(layer.tracks.ids[np.argmin(layer.tracks.x[:, 1])])  # at y = 0
        layer.tracks.note_unlikely(layer.tracks.ids.copy())
        if lock:
            estimate = TrackEstimate(1.0, fragments[0], np.zeros(3), True, 0.2)
            snap = layer.tracks.snapshot(estimate)
            assert snap.ids[snap.locked].tolist() == [target]
            layer.tracks.note_lock(snap, estimate)
        for k in range(10, 14):
            layer.step(k * T, births)  # the fragments missed, the births confirmed
        assert len(layer.tracks) == 4
        assert (target in layer.tracks.ids.tolist()) is lock


def test_the_locked_track_is_the_one_at_a_locked_estimate() -> None:
    layer = _Layer()
    for k in range(3):
        layer.step(k * T, np.array([[0.0, 0, 5], [10.0, 0, 5]]))

    def estimate(p: list[float], tracked: bool) -> TrackEstimate:
        return TrackEstimate(1.0, np.array(p), np.zeros(3), tracked, 0.2)

    order = np.argsort(layer.tracks.x[:, 0])
    locked = layer.tracks.snapshot(estimate([9.5, 0, 5], True)).locked[order]
    assert locked.tolist() == [False, True]
    assert not layer.tracks.snapshot(estimate([9.5, 0, 5], False)).locked.any()
    assert not layer.tracks.snapshot(estimate([5.0, 0, 5], True)).locked.any()  # 5 m off


def test_the_snapshot_reports_states_covariances_and_defaults() -> None:
    layer = _Layer()
    for k in range(3):
        layer.step(k * T, np.array([[20.0, 0.0, 5.0]]))
    snap = layer.tracks.snapshot()
    assert len(snap) == 1
    assert snap.class_names == ["unknown"]
    assert snap.p_drone.tolist() == [0.5]
    assert snap.position_sigma[0] == pytest.approx(
        np.sqrt(np.max(np.diag(snap.covariances[0])[:3]))
    )
    with pytest.raises(ValueError, match="read-only"):
        snap.positions[0, 0] = 1.0


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ConfigError, match="sigma_acc"):
        TrackSettings(sigma_acc=0.0)
    with pytest.raises(ConfigError, match="gate_probability"):
        TrackSettings(gate_probability=1.0)
    with pytest.raises(ConfigError, match="max_tracks"):
        TrackSettings(max_tracks=0)
    with pytest.raises(ConfigError, match="merge_m"):
        TrackSettings(merge_s=-1.0)
    with pytest.raises(ConfigError, match="unseen_s"):
        TrackSettings(coast_s=5.0, unseen_s=4.0)
    with pytest.raises(ConfigError, match="probation_s"):
        TrackSettings(probation_s=0.0)


def test_empty_inputs_leave_no_track() -> None:
    tracks = MultiTargetTracker()
    snap = tracks.step(0.1, Detections.empty(), Candidates.empty())
    assert len(snap) == 0
    assert snap.covariances.shape == (0, 6, 6)


def test_tracks_within_the_clustering_radius_for_a_second_are_one_object() -> None:
    """Two tracks that close follow one object (two objects within ε give one cluster):
    after ``merge_s`` the one with fewer updates ends and the older identity stays; a
    cluster that close to a track starts none."""
    layer = _Layer(merge_m=1.0, merge_s=1.0)
    v = np.array([5.0, 0.0, 0.0])

    def at(t: float) -> np.ndarray:
        return np.array([40.0, 0.0, 20.0]) + v * t

    for k in range(10):  # one object, one cluster: track 1
        layer.step(k * T, at(k * T - 0.5 * T)[None, :])
    assert layer.tracks.ids.tolist() == [1]
    for k in range(10, 40):  # its cluster splits in two pieces 0.6 m apart
        c = at(k * T - 0.5 * T)
        half = np.array([0.0, 0.3, 0.0])
        layer.step(k * T, np.stack([c + half, c - half]))
        assert layer.tracks.ids.tolist() == [1]  # no track is born on a piece
    # a second object flies in beside it (2.5 m away), then closes to 0.5 m: its own
    # track until the two have been within 1 m for a second
    ids_seen = []
    for k in range(40, 80):
        c = at(k * T - 0.5 * T)
        off = 2.5 if k < 50 else 0.5
        layer.step(k * T, np.stack([c, c + np.array([0.0, off, 0.0])]))
        ids_seen.append(layer.tracks.ids.tolist())
    assert ids_seen[8] == [1, 2]  # confirmed beside it
    closed_at = 50  # within 1 m from the frame k = 50 on
    together = [ids for k, ids in zip(range(40, 80), ids_seen, strict=True) if k > closed_at]
    assert together[int(1.0 / T) - 2] == [1, 2]  # not yet a second together
    assert together[-1] == [1]  # then one object, the older identity


def test_within_smear_is_the_capsule_around_the_path_over_the_period() -> None:
    # p = 0, v = 10 m/s along x, ±0.1 s: the segment x ∈ [−1, 1] m, radius 0.5 m
    x = np.array([0.0, 0, 0, 10.0, 0, 0])
    points = np.array(
        [
            [1.4, 0, 0],  # 0.4 m past the segment's end: in
            [-1.6, 0, 0],  # 0.6 m past the other end: out
            [0.3, 0.49, 0],  # 0.49 m beside it: in
            [0.3, 0, 0.51],  # 0.51 m beside it: out
            [1.3, 0.39, 0],  # 0.49 m from the end (√(0.3² + 0.39²)): in
            [1.3, 0.41, 0],  # 0.51 m from it: out
        ]
    )
    assert within_smear(points, x, 0.1, 0.5).tolist() == [True, False, True, False, True, False]
    # at rest, or over no time, the ball of that radius
    still = np.array([0.0, 0, 0, 0, 0, 0])
    assert within_smear(points, still, 0.1, 0.5).tolist() == [False] * 6
    assert within_smear(np.array([[0.3, 0.3, 0.3]]), still, 0.1, 0.6).tolist() == [True]
    assert within_smear(points[:1], x, 0.0, 0.5).tolist() == [False]


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.floats(-5, 5), min_size=3, max_size=3),
    st.lists(st.floats(-20, 20), min_size=3, max_size=3),
    st.floats(0.0, 0.2),
    st.floats(0.1, 3.0),
)
def test_within_smear_agrees_with_the_distance_to_the_sampled_path(
    c: list[float], v: list[float], period: float, radius: float
) -> None:
    x = np.concatenate([[1.0, -2.0, 3.0], v])
    # the path p + v τ, τ ∈ [−T, T], sampled densely: the distance to it
    tau = np.linspace(-period, period, 4001)
    path = x[:3] + tau[:, None] * np.asarray(v)[None, :]
    d = float(np.min(np.linalg.norm(path - np.asarray(c), axis=1)))
    step = 2 * period * float(np.linalg.norm(v)) / 4000  # the samples' spacing [m]
    if abs(d - radius) > step + 1e-9:
        assert within_smear(np.array([c]), x, period, radius)[0] == (d <= radius)


def test_one_object_needs_each_within_the_others_smear() -> None:
    track = np.array([0.0, 0, 0, 20.0, 0, 0])  # ±0.1 s: along x ∈ [−2, 2] m
    pieces = np.array(
        [
            [1.9, 0, 0, 20.0, 0, 0],  # along it, moving with it: one object
            [1.9, 0, 0, 0.0, 0, 0],  # along it, but still: the track is 1.9 m off its ball
            [0.0, 1.4, 0, 20.0, 0, 0],  # beside it: another object
        ]
    )
    assert one_object(pieces, track, 0.1, 1.0).tolist() == [True, False, False]
    assert one_object(np.empty((0, 6)), track, 0.1, 1.0).shape == (0,)
    # (pieces, tracks) at once, as births test them: column k is track k's answer
    still = np.array([0.0, 1.4, 0, 0, 0, 0])  # the third piece's ball holds it
    both = one_object(pieces[:, None, :], np.stack([track, still])[None, :, :], 0.1, 1.0)
    assert both.tolist() == [[True, False], [False, False], [False, True]]


def _split(offset: np.ndarray) -> list[int]:
    """A drone at 12 m/s along x; from 1 s on, its returns of each frame fall in two
    clusters ``offset`` apart (its smear over the 0.1 s frame cut in two); the
    identities at the end."""
    layer = _Layer()
    v = np.array([12.0, 0.0, 0.0])
    for k in range(40):
        c = np.array([60.0, 0.0, 20.0]) + v * (k * T - 0.5 * T)
        layer.step(k * T, c[None, :] if k < 10 else np.stack([c - offset / 2, c + offset / 2]))
    return layer.tracks.ids.tolist()


def test_a_fast_drone_split_along_its_motion_keeps_one_track_and_two_abreast_two() -> None:
    """Pieces 1.9 m apart along a 12 m/s drone's motion lie within the 1.2 m each way it
    sweeps in a frame (plus merge_m = 1 m): one object.  1.4 m apart across it they are
    two objects, each with its track."""
    assert _split(np.array([1.9, 0.0, 0.0])) == [1]
    assert len(_split(np.array([0.0, 1.4, 0.0]))) == 2


def test_on_or_above_projects_a_state_below_the_ground_onto_it() -> None:
    x = np.array(
        [
            [10.0, 0, -3.0, 1.0, 0, -2.0],  # below, sinking: onto the ground, v_z 0
            [10.0, 0, -3.0, 1.0, 0, 0.5],  # below, rising: onto it, v_z kept
            [10.0, 0, 4.0, 1.0, 0, -2.0],  # above: as it was
            [10.0, 0, -30.0, 1.0, 0, -2.0],  # ground unknown: as it was
        ]
    )
    out = on_or_above(x, np.array([1.0, 1.0, 1.0, np.nan]))
    expected = x.copy()
    expected[0, [2, 5]] = [1.0, 0.0]
    expected[1, 2] = 1.0
    np.testing.assert_array_equal(out, expected)
    assert x[0, 2] == -3.0  # the input is left alone


def _sinking(floor: Floor | None, seen_s: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """An object 40 m out sinking at 4 m/s from 3 m up, seen for ``seen_s``, then missed
    in view: each frame's height and vertical speed of its track over 4 s from birth."""
    layer = _Layer()
    states = []
    for k in range(40):
        c = np.array([40.0, 0.0, 3.0 - 4.0 * (k * T - 0.5 * T)])
        layer.step(k * T, c[None, :] if k * T < seen_s else np.empty((0, 3)), floor=floor)
        if k >= 2:  # born on the second frame
            assert len(layer.tracks) == 1
            states.append(layer.tracks.x[0, [2, 5]])
    z, vz = np.array(states).T
    return z, vz


def test_a_track_coasting_down_stays_on_the_ground() -> None:
    z, vz = _sinking(lambda xy: np.full(len(xy), -5.0))
    assert z.min() == pytest.approx(-5.0)  # it reached the ground and stayed there
    assert z[-1] == pytest.approx(-5.0)
    assert vz[-1] == 0.0
    assert _sinking(None)[0].min() < -10.0  # unbound, it sinks on


def test_a_track_measured_below_the_ground_learnt_is_not_bound_by_it() -> None:
    # a ground learnt 30 m up there (a crown or a wall top seen, not the ground): the
    # track follows its fixes down, and coasts on as without a floor
    def high(xy: np.ndarray) -> np.ndarray:
        return np.full(len(xy), 30.0)

    _, vz = _sinking(high, seen_s=4.0)
    np.testing.assert_allclose(vz[5:], -4.0, atol=0.3)
    np.testing.assert_allclose(_sinking(high)[0], _sinking(None)[0])


def test_a_floor_giving_the_wrong_number_of_heights_is_refused() -> None:
    with pytest.raises(InputError, match="floor"):
        _sinking(lambda xy: np.zeros(len(xy) + 1))


def _alternating(share_m: float, both_after: bool) -> list[list[int]]:
    """Two objects 2 m apart, each its own cluster for 1 s (two tracks); then for 3 s
    one cluster a frame, at one or the other in turn (``both_after``: both, every
    frame)."""
    layer = _Layer(merge_m=1.0, merge_s=1.0, share_m=share_m)
    a, b = np.array([40.0, 0.0, 20.0]), np.array([40.0, 2.0, 20.0])
    for k in range(10):
        layer.step(k * T, np.stack([a, b]))
    ids = []
    for k in range(10, 40):
        layer.step(k * T, np.stack([a, b]) if both_after else (a if k % 2 else b)[None, :])
        ids.append(layer.tracks.ids.tolist())
    return ids


def test_two_tracks_that_take_one_cluster_in_turn_are_one_object() -> None:
    """Within share_m (3 m) for merge_s (1 s) without a frame that updated both, two
    tracks follow one object seen through one cluster (a track lagging a fast drone
    and the one born beside it): the one with fewer updates ends (here a cluster 2 m
    from the one left then starts a track again).  Two objects that give two clusters
    a frame keep their two tracks; without the rule both live on."""
    merged = _alternating(3.0, both_after=False)
    first = next(k for k, ids in enumerate(merged) if len(ids) == 1)
    assert merged[:first] == [[1, 2]] * first
    assert (first + 1) * T == pytest.approx(1.0 + T)  # merge_s after the last frame of two
    assert all(ids == [1, 2] for ids in _alternating(3.0, both_after=True))
    assert all(ids == [1, 2] for ids in _alternating(0.0, both_after=False))


def test_close_pairs_are_the_pairs_within_the_radius() -> None:
    p = np.array([[0.0, 0, 0], [0.9, 0, 0], [3.0, 0, 0], [3.0, 1.0, 0]])
    assert close_pairs(p, 1.0).tolist() == [[0, 1], [2, 3]]
    assert close_pairs(p, 0.5).tolist() == []
    assert close_pairs(np.empty((0, 3)), 1.0).shape == (0, 2)


def _follow(lock: bool) -> list[list[int]]:
    """An object at 5 m/s whose cluster jumps 3 m sideways at 1 s (beyond its track's
    gates) and goes on from there; with ``lock`` the turret's tracker holds it throughout
    and says so after each frame.  The identities after each frame."""
    layer = _Layer()
    seen = []
    for k in range(30):
        t = k * T
        p = np.array([40.0 + 5.0 * t, 0.0, 20.0]) + (np.array([0.0, 3.0, 0.0]) if k >= 10 else 0)
        layer.step(t, (p - [2.5 * T, 0, 0])[None, :])
        seen.append(layer.tracks.ids.tolist())
        if lock:
            estimate = TrackEstimate(t, p, np.array([5.0, 0.0, 0.0]), True, 0.2)
            layer.tracks.note_lock(layer.tracks.snapshot(estimate), estimate)
    return seen


def test_the_lock_carries_its_track_over_a_jump_the_track_missed() -> None:
    alone, held = _follow(lock=False), _follow(lock=True)
    assert alone[9] == held[9] == [1]
    assert 2 in alone[-1]  # without the lock: a new identity where the cluster went
    assert all(ids == [1] for ids in held[1:])  # with it: the same track, restarted there
