"""The share of frames the drone returns a point at a range, and the test of a track
that returns more often than it could (``classify.return_share``)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.stats import binom

from dronetrack.classify.features import LifeFeatures, TrackLives
from dronetrack.classify.observe import observe
from dronetrack.classify.return_share import ALPHA, more_often_than_drone, return_share
from dronetrack.classify.rules import ClassRules, classify
from dronetrack.config.reach import RETURN_SHARE
from dronetrack.types import TRACK_CLASSES, Detections, Tracks

R50, S = RETURN_SHARE[("avia", "phantom4")]
DRONE, STATIC = TRACK_CLASSES.index("drone"), TRACK_CLASSES.index("static")


def test_the_share_is_a_half_at_r50_and_falls_by_the_logistic() -> None:
    assert return_share(np.array(R50), R50, S) == pytest.approx(0.5)
    # P(r₅₀ + s ln 3) = 1 / (1 + 3)
    assert return_share(np.array(R50 + S * math.log(3.0)), R50, S) == pytest.approx(0.25)
    assert return_share(np.array(R50 - S * math.log(3.0)), R50, S) == pytest.approx(0.75)
    with np.errstate(all="raise"):  # no overflow far out or near
        far_near = return_share(np.array([1e6, 0.0]), R50, S)
    assert far_near[0] == 0.0
    assert far_near[1] == pytest.approx(1.0, abs=1e-6)


@given(st.floats(0.0, 500.0), st.floats(0.0, 500.0))
def test_the_share_falls_with_range(a: float, b: float) -> None:
    near, far = sorted((a, b))
    assert return_share(np.array(near), R50, S) >= return_share(np.array(far), R50, S)


def test_known_counts_are_or_are_not_too_many_for_the_drone() -> None:
    # e.g. 30 frames where the drone returns in 1.7 %: μ = 0.5
    mu = 0.5
    hits = np.array([20, 5, 3, 0, 1])
    expected = np.array([mu, mu, mu, mu, 0.0])
    # ln P(K ≥ k) ≤ k − μ − k ln(k/μ): −54.3, −7.01 (< ln 10⁻³ = −6.91), −2.9, —, −∞
    assert more_often_than_drone(hits, expected).tolist() == [True, True, False, False, True]
    # as many as expected, or fewer, are never too many
    assert not more_often_than_drone(np.array([7]), np.array([7.8]))[0]


@given(
    st.integers(1, 60),
    st.floats(0.001, 0.999),
    st.integers(0, 60),
)
def test_the_bound_is_above_the_binomial_tail(n: int, p: float, k: int) -> None:
    """Chernoff's bound holds: when a count is called too many, the exact binomial tail
    P(K ≥ k) of n frames at share p is below α too."""
    k = min(k, n)
    if more_often_than_drone(np.array([k]), np.array([n * p]))[0]:
        assert binom.sf(k - 1, n, p) < ALPHA


def test_a_drone_flying_out_to_170m_is_almost_never_called_too_bright() -> None:
    """5,000 simulated drone tracks, each seen on the axis over 30 frames at ranges
    100-170 m with the measured share: the test calls at most α of them too bright."""
    rng = np.random.default_rng(4)
    ranges = rng.uniform(100.0, 170.0, size=(5000, 1)) + np.linspace(0.0, 20.0, 30)
    shares = return_share(ranges, R50, S)
    hits = (rng.random(shares.shape) < shares).sum(axis=1)
    called = more_often_than_drone(hits, shares.sum(axis=1))
    assert called.mean() <= ALPHA


def _tracks(p: list[float], in_view: bool, updated: bool) -> Tracks:
    return Tracks(
        ids=np.array([5]),
        positions=np.array([p]),
        velocities=np.zeros((1, 3)),
        covariances=np.tile(0.01 * np.eye(6), (1, 1, 1)),
        born=np.zeros(1),
        updated=np.array([updated]),
        hovered=np.zeros(1, dtype=bool),
        locked=np.zeros(1, dtype=bool),
        clusters=np.array([0 if updated else -1]),
        in_view=np.array([in_view]),
    )


def _found(p: list[float]) -> Detections:
    return Detections(
        np.array([p]),
        np.full(1, 4),
        np.array([[0.4, 0.2, 0.1]]),
        np.zeros((1, 3, 3)),
        np.zeros(1),
        np.array([p[2] - 0.2]),
    )


def _life_at(p: list[float], frames: list[tuple[bool, bool]], share: bool = True) -> LifeFeatures:
    """A still object at ``p`` over frames of (in view, updated), the first its birth."""
    lives = TrackLives()
    life = None
    for k, (in_view, updated) in enumerate(frames):
        tracks = _tracks(p, in_view, updated)
        obs = observe(tracks, _found(p), np.zeros(3), np.zeros(1), floor_z=1.0, limit_m=195.0)
        r = np.linalg.norm(tracks.positions, axis=1)
        life = lives.update(0.1 * k, tracks, obs, share=return_share(r, R50, S) if share else None)
    assert life is not None
    return life


def test_a_board_in_free_air_that_returns_in_every_frame_at_175m_is_no_drone() -> None:
    """A sign board 175 m out on a thin pole the pattern misses: it holds still in free
    air, a hovering drone by every other test, but it returns in every frame where the
    drone would in 1.9 %; within 2 s it is static (the hover beyond what a drone could
    return is the world's, as beyond reach)."""
    board = [175.0, 0.0, 8.0]
    life = _life_at(board, [(True, True)] * 20)
    assert life.too_often[0]
    assert life.hovered_free[0]
    classes, p = classify(life)
    assert classes[0] == STATIC
    assert p[0] < ClassRules().bird_p  # −6 against the hover's +4
    # unknown where the share is not known (another sensor or drone, or fog): a drone
    unknown = _life_at(board, [(True, True)] * 20, share=False)
    assert not unknown.too_often[0]
    assert classify(unknown)[0][0] == DRONE


def test_only_the_frames_in_view_after_the_birth_count() -> None:
    """The birth's frame is not counted (a track is born because it returned points),
    nor are the frames out of view (the turret looked elsewhere): a drone at 150 m seen
    in its birth frame, then in 2 of the 6 frames in view and none of 20 out of view,
    returned as often as a drone does there (0.29)."""
    frames = [(True, True)] + [(False, False)] * 20 + [(True, k % 3 == 0) for k in range(6)]
    life = _life_at([150.0, 0.0, 20.0], frames)
    assert not life.too_often[0]
    # the same hits in view in every frame at 185 m, where the drone returns in 0.5 %
    far = _life_at([185.0, 0.0, 20.0], [(True, True)] * 4)
    assert far.too_often[0]  # μ = 0.015 over 3 frames after the birth, k = 3


def test_the_pipelines_classifier_takes_the_share_of_its_sensor_and_drone() -> None:
    """The Avia's pipeline with a Phantom 4 in clear air weighs the board of the test
    above as the world; in fog, where neither the share nor the limit is known, as a
    drone hovering."""
    from dronetrack.config.scenarios import SCENARIOS
    from dronetrack.pipeline.factory import build_classifier

    board = [175.0, 0.0, 8.0]
    spread = np.array([[0.0, 0.0, 0.0], [0.0, 0.3, 0.1], [0.0, -0.3, -0.1], [0.0, 0.1, 0.3]])
    world = np.asarray(board) + spread
    out = {}
    for name in ("default", "field-foggy"):
        classifier = build_classifier(SCENARIOS[name].pipeline, floor_z=1.0)
        assert classifier is not None
        for k in range(20):
            tracks = _tracks(board, in_view=True, updated=True)
            tracks = classifier.step(
                0.1 * k, tracks, _found(board), world, np.arange(4), np.zeros(3)
            )
        out[name] = (classifier.share, int(tracks.classes[0]))
    assert out["default"] == (RETURN_SHARE[("avia", "phantom4")], STATIC)
    assert out["field-foggy"] == (None, DRONE)
