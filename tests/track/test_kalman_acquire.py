"""The Kalman trackers started on the detect stage's confirmed candidates
(``track.kalman_base``: ``acquire`` and ``self_start``)."""

from __future__ import annotations

import numpy as np
import pytest

from dronetrack.track.base import CandidateStart, SelfStart
from dronetrack.track.cluster_kalman import AdaptiveEKF, CentroidEKF, ConstantAccelerationKF
from dronetrack.track.kalman_base import _KalmanTracker
from dronetrack.track.sphere_kalman import CatalanoEKF, DogruEKF
from dronetrack.types import Candidates

T = 0.1


def _candidate(p: tuple[float, float, float], v: tuple[float, float, float]) -> Candidates:
    one = np.ones(1, dtype=np.int64)
    return Candidates(np.array([p]), np.array([v]), 3 * one, np.array([0.4]), one)


def _blob(g: np.random.Generator, at: np.ndarray) -> np.ndarray:
    return at + g.normal(0.0, 0.05, (6, 3))


@pytest.mark.parametrize("make", [CentroidEKF, ConstantAccelerationKF, AdaptiveEKF])
def test_a_start_takes_the_candidate_position_and_velocity_unpredicted(make: type) -> None:
    kf = make(period=T)
    assert isinstance(kf, CandidateStart)
    assert isinstance(kf, SelfStart)
    kf.self_start = False
    kf.acquire(_candidate((80.0, 30.0, 20.0), (-12.0, 3.0, 0.0)))
    # The frame's points elsewhere, and 3 periods to predict: the start is the
    # candidate's, at the frame's end, neither updated nor predicted.
    est = kf.step(0.3, np.array([[10.0, 0.0, 5.0]]), 3)
    np.testing.assert_array_equal(est.position, [80.0, 30.0, 20.0])
    np.testing.assert_array_equal(est.velocity, [-12.0, 3.0, 0.0])
    np.testing.assert_array_equal(est.measurement, [80.0, 30.0, 20.0])
    assert est.tracked
    np.testing.assert_array_equal(np.diag(kf.P), np.diag(kf.P0))


@pytest.mark.parametrize("make", [CatalanoEKF, DogruEKF])
def test_the_ctrv_filters_start_at_rest_on_the_candidate(make: type) -> None:
    kf = make(period=T)
    kf.self_start = False
    kf.acquire(_candidate((40.0, -5.0, 12.0), (5.0, 0.0, 0.0)))
    est = kf.step(0.1, np.empty((0, 3)), 1)
    np.testing.assert_array_equal(est.position, [40.0, -5.0, 12.0])
    assert kf.initialised
    assert np.all(kf.x[3:] == 0.0)


@pytest.mark.parametrize(
    "make", [CentroidEKF, ConstantAccelerationKF, AdaptiveEKF, CatalanoEKF, DogruEKF]
)
def test_without_self_start_a_non_empty_frame_starts_nothing(make: type) -> None:
    on_its_own: _KalmanTracker = make(period=T)
    driven: _KalmanTracker = make(period=T)
    driven.self_start = False
    blob = _blob(np.random.default_rng(1), np.array([55.0, 12.0, 9.0]))
    # On its own the filter starts on the frame's centroid, as the seeds do (seed 002's
    # detector takes it after its voxel grid, within a few centimetres) ...
    start = on_its_own.step(0.1, blob, 1).position
    np.testing.assert_allclose(start, blob.mean(axis=0), atol=0.05)
    # ... driven by candidates, it waits for one.
    est = driven.step(0.1, blob, 1)
    assert not driven.initialised
    assert not est.tracked


def test_a_lost_track_restarts_on_a_new_candidate_and_is_tracked_at_once() -> None:
    g = np.random.default_rng(0)
    kf = AdaptiveEKF(period=T, t_occ=1.0)
    kf.self_start = False
    kf.acquire(_candidate((30.0, 0.0, 10.0), (0.0, 0.0, 0.0)))
    t = 0.0
    for _ in range(10):
        t += T
        assert kf.step(t, _blob(g, np.array([30.0, 0.0, 10.0])), 1).tracked
    for _ in range(12):  # 1.2 s without a fix: lost (t_occ = 1 s)
        t += T
        est = kf.step(t, np.empty((0, 3)), 1)
    assert not est.tracked
    kf.acquire(_candidate((70.0, 40.0, 25.0), (0.0, -6.0, 0.0)))
    t += T
    est = kf.step(t, np.empty((0, 3)), 1)
    assert est.tracked
    np.testing.assert_array_equal(est.position, [70.0, 40.0, 25.0])
    # and it goes on from there
    for _ in range(5):
        t += T
        at = np.array([70.0, 40.0 - 6.0 * (t - 2.3), 25.0])
        est = kf.step(t, _blob(g, at), 1)
    assert est.tracked
    assert float(np.linalg.norm(est.position - at)) < 0.5


def test_a_candidate_inside_the_gate_or_a_tracked_filter_changes_nothing() -> None:
    kf = CentroidEKF(period=T)
    kf.self_start = False
    kf.acquire(_candidate((30.0, 0.0, 10.0), (0.0, 0.0, 0.0)))
    kf.step(0.1, np.empty((0, 3)), 1)
    # tracked: ignored
    kf.acquire(_candidate((90.0, 0.0, 10.0), (0.0, 0.0, 0.0)))
    assert kf.step(0.2, np.empty((0, 3)), 1).position[0] == pytest.approx(30.0)
    # not tracked (P above the threshold) but the candidate within 3σ: ignored
    kf.P[0, 0] = kf.P[1, 1] = kf.P[2, 2] = 30.0  # σ = 5.5 m: the gate is 16 m
    kf.lost = True
    kf.acquire(_candidate((40.0, 0.0, 10.0), (0.0, 0.0, 0.0)))
    assert kf._pending is None
    kf.acquire(_candidate((50.0, 0.0, 10.0), (0.0, 0.0, 0.0)))  # 20 m: restart
    assert kf._pending is not None
