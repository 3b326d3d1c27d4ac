"""The height spread of a track's clusters and its test against a drone
(``classify.spread``): known answers, the statistic's moments, and the classes of a
pole sampled at random heights and of a drone."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.stats import chi2

from dronetrack.classify.features import LifeFeatures, TrackLives
from dronetrack.classify.observe import BEAM_RAD, observe
from dronetrack.classify.rules import DRONE, STATIC, classify
from dronetrack.classify.spread import (
    SPREAD_ALPHA,
    SPREAD_GAP_S,
    SPREAD_KAPPA,
    spread_deviation,
    spread_height,
    spread_scale,
    taller_than_drone,
)
from dronetrack.types import Detections, Tracks

T = 0.1


@settings(max_examples=80, deadline=None)
@given(
    z0=st.floats(-50, 50),
    vz=st.floats(-8, 8),
    g1=st.floats(0.01, 0.15),
    g0=st.floats(0.01, 0.15),
)
def test_a_climb_at_constant_speed_deviates_nothing(
    z0: float, vz: float, g1: float, g0: float
) -> None:
    """d = z₀ − (1 + ρ) z₁ + ρ z₂ is 0 on any line z(t), whatever the gaps."""
    z2, z1, z = z0, z0 + vz * g1, z0 + vz * (g1 + g0)
    d, c = spread_deviation(np.array([z]), np.array([z1]), np.array([z2]), np.array([g0 / g1]))
    assert d[0] == pytest.approx(0.0, abs=1e-9)
    assert c[0] == pytest.approx(1 + (1 + g0 / g1) ** 2 + (g0 / g1) ** 2)


def test_the_deviations_variance_is_c_sigma_squared_and_their_sum_is_satterthwaites() -> None:
    """Heights of variance σ², equal gaps: Var d = 6 σ², and the sum over n overlapping
    triples, Q = Σ d² / (6 σ²), has mean n and variance 2 n / κ, κ = 18/35 (the
    correlations −2/3 and 1/6 of neighbouring deviations): 4000 runs of n = 50."""
    rng = np.random.default_rng(1)
    sigma, n, runs = 0.3, 50, 4000
    z = rng.normal(0.0, sigma, (runs, n + 2))
    d, c = spread_deviation(z[:, 2:], z[:, 1:-1], z[:, :-2], np.ones((runs, n)))
    assert np.var(d) == pytest.approx(6 * sigma**2, rel=0.03)
    q = (d**2 / (c * sigma**2)).sum(axis=1)
    assert q.mean() == pytest.approx(n, rel=0.02)
    assert q.var() == pytest.approx(2 * n / SPREAD_KAPPA, rel=0.1)
    assert q.var() > 1.5 * 2 * n  # well over χ²(n)'s: the deviations overlap


def test_the_spread_height_of_returns_landing_anywhere_on_an_object_is_its_height() -> None:
    """Heights uniform over h: Σ 12 d²/c / n → h² (a uniform's variance is h²/12)."""
    rng = np.random.default_rng(2)
    for h in (0.3, 1.0, 3.0):
        z = rng.uniform(0.0, h, 20002)
        d, c = spread_deviation(z[2:], z[1:-1], z[:-2], np.ones(20000))
        got = spread_height(np.array([(12 * d**2 / c).sum()]), np.array([20000]))
        assert got[0] == pytest.approx(h, rel=0.03)
    assert np.isnan(spread_height(np.zeros(1), np.zeros(1, dtype=np.int64))[0])


def test_a_drones_scale_is_its_size_and_the_beams_footprint() -> None:
    """σ_d = (s + θ_b r)/√12: 0.4 m and 5 mrad give 0.24 m at 85 m."""
    got = spread_scale(0.4, np.array([0.0, 85.0]))
    np.testing.assert_allclose(got, [0.4 / math.sqrt(12), (0.4 + BEAM_RAD * 85) / math.sqrt(12)])
    assert got[1] == pytest.approx(0.238, abs=1e-3)


def test_the_test_rejects_at_its_level_on_heights_a_drone_would_give() -> None:
    """On heights spread exactly as σ_d (Gaussian, the worst case), over n = 10 to 200
    triples, the test rejects about α of 4000 runs (within 3α: the approximation's
    slack); over n = 0 it never does."""
    rng = np.random.default_rng(3)
    for n in (10, 50, 200):
        z = rng.normal(0.0, 1.0, (4000, n + 2))
        d, c = spread_deviation(z[:, 2:], z[:, 1:-1], z[:, :-2], np.ones((4000, n)))
        q = (d**2 / c).sum(axis=1)
        rate = taller_than_drone(q, np.full(4000, n)).mean()
        assert rate < 3 * SPREAD_ALPHA
    assert not taller_than_drone(np.array([1e9]), np.array([0]))[0]
    # the bound: κ Q > χ²₁₋α(κ n)
    n = np.array([20])
    edge = chi2.ppf(1 - SPREAD_ALPHA, SPREAD_KAPPA * 20) / SPREAD_KAPPA
    assert not taller_than_drone(np.array([edge * 0.999]), n)[0]
    assert taller_than_drone(np.array([edge * 1.001]), n)[0]


def _frame(lives: TrackLives, t: float, ident: int, p: list[float], **kw: object) -> LifeFeatures:
    """One frame of a still track ``ident`` whose cluster is a point at ``p``, over flat
    ground (z = 0) and 195 m of the drone's reach."""
    tracks = Tracks(
        ids=np.array([ident]),
        positions=np.array([p]),
        velocities=np.zeros((1, 3)),
        covariances=np.tile(0.01 * np.eye(6), (1, 1, 1)),
        born=np.zeros(1),
        updated=np.ones(1, dtype=bool),
        hovered=np.zeros(1, dtype=bool),
        locked=np.zeros(1, dtype=bool),
        clusters=np.zeros(1, dtype=np.int64),
    )
    found = Detections(
        np.array([p]),
        np.ones(1, dtype=np.int64),
        np.zeros((1, 3)),
        np.zeros((1, 3, 3)),
        np.zeros(1),
        np.array([p[2]]),
    )
    obs = observe(tracks, found, np.zeros(3), np.zeros(1), floor_z=0.0, limit_m=195.0)
    return lives.update(t, tracks, obs, **kw)  # type: ignore[arg-type]


def _life(
    heights: np.ndarray, xy: tuple[float, float], gaps: np.ndarray | None = None
) -> LifeFeatures:
    """A still track 1 m up or more, one cluster a frame at ``heights``."""
    lives = TrackLives(hover_speed=4.0, hover_frames=3, drone_size_m=0.4)
    t, life = 0.0, None
    for k, z in enumerate(heights):
        t += 0.0 if k == 0 else (T if gaps is None else float(gaps[k - 1]))
        life = _frame(lives, t, 9, [xy[0], xy[1], float(z)])
    assert life is not None
    return life


def test_a_pole_sampled_at_random_heights_is_taller_than_a_drone() -> None:
    """A 5 m pole 85 m out, one return a frame anywhere on 1.5-4.5 m, hovers in free
    space by every other test; its heights spread over 3 m where a drone's spread over
    0.8 m: after 2 s it is larger than a drone, and static, its clusters within the
    height they land over.  A drone hovering there, its returns over 0.3 m, and one
    climbing at 2 m/s are drones; a minute of the hover is not rejected either."""
    rng = np.random.default_rng(4)
    pole = _life(rng.uniform(1.5, 4.5, 21), (26.0, -81.0))
    assert taller_than_drone(pole.spread_q, pole.spread_n)[0]
    assert pole.spread_m[0] == pytest.approx(3.0, rel=0.5)
    assert classify(pole)[0][0] == STATIC
    hover = _life(10.0 + rng.uniform(0.0, 0.3, 600), (26.0, -81.0))
    climb = _life(10.0 + 0.2 * np.arange(21) + rng.uniform(0.0, 0.3, 21), (26.0, -81.0))
    for drone in (hover, climb):
        assert not taller_than_drone(drone.spread_q, drone.spread_n)[0]
        assert classify(drone)[0][0] == DRONE
    assert int(hover.spread_n[0]) == 598


def test_taller_than_a_drone_its_height_is_no_motion_but_its_way_across_is() -> None:
    """The pole's first cluster at its top and the later ones lower: its clusters
    moved 0.8 m more than the height they spread over (``outdoor-unscanned`` seed 12:
    3.0 m against 2.2 m, 85 m out), but 0.3 m across: still, and static.  Had it
    moved as far across, it would not be; nor is a drone that came down 3 m where it
    hovers (its height spread a drone's)."""
    rng = np.random.default_rng(4)
    pole = _life(rng.uniform(1.5, 4.5, 21), (26.0, -81.0))
    down = float(pole.spread_m[0]) + 0.8
    assert down > 1.0  # past the 1 m any still object may wander
    top_first = replace(pole, moved=np.array([down]), moved_xy=np.array([0.3]))
    assert classify(top_first)[0][0] == STATIC
    across = replace(top_first, moved_xy=np.array([down]))
    assert classify(across)[0][0] != STATIC
    hover = _life(10.0 + rng.uniform(0.0, 0.3, 21), (26.0, -81.0))
    came_down = replace(hover, moved=np.array([3.0]), moved_xy=np.array([0.3]))
    assert classify(came_down)[0][0] != STATIC


def test_only_close_triples_count() -> None:
    """A gap over ``SPREAD_GAP_S`` breaks the triples: with every other gap 0.3 s, none."""
    gaps = np.where(np.arange(20) % 2 == 0, T, 2 * SPREAD_GAP_S)
    life = _life(np.random.default_rng(5).uniform(0, 3, 21), (26.0, -81.0), gaps)
    assert int(life.spread_n[0]) == 0
    assert not taller_than_drone(life.spread_q, life.spread_n)[0]


def test_an_heir_keeps_the_spread_but_starts_its_triples_from_its_own_clusters() -> None:
    """An heir takes its resting track's Q and n, but no triple joins the old track's
    clusters to its own (an heir is its object by place, not by path)."""

    def frame(lives: TrackLives, t: float, ident: int, z: float, **kw: object) -> LifeFeatures:
        return _frame(lives, t, ident, [40.0, 5.0, z], **kw)

    lives = TrackLives()
    for k, z in enumerate((5.0, 5.2, 5.1)):
        life = frame(lives, k * T, 7, z)
    assert int(life.spread_n[0]) == 1
    rest = np.array([7])
    heir = frame(lives, 3 * T, 12, 9.0, resting=rest, heirs=(np.array([12]), rest))
    assert int(heir.spread_n[0]) == 1
    assert heir.spread_q[0] == pytest.approx(float(life.spread_q[0]))
    frame(lives, 4 * T, 12, 9.1, resting=rest)
    last = frame(lives, 5 * T, 12, 9.0, resting=rest)
    assert int(last.spread_n[0]) == 2  # its own first triple
