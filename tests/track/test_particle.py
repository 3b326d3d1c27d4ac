"""Seed 000's particle filter: eq. (11), the motion models, weights, resampling, re-detection."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.spatial import cKDTree
from scipy.stats import chisquare

from dronetrack.errors import ConfigError
from dronetrack.track.nearest import nearest_distances
from dronetrack.track.particle import (
    MotionModel,
    NoiseParameters,
    ParticleFilter,
    ParticleTracker,
    cylinder_particles,
    eq11_parameters,
    gate_margin,
    likelihood_weights,
    predict,
    spread,
)
from dronetrack.track.resample import multinomial, systematic
from dronetrack.types import Candidates


def test_eq11_gives_the_papers_parameters() -> None:
    # §III-A: 15 m/s, 15 m/s², s_diag 0.4 m, 10 Hz → σ_pos 0.5, σ_vel 0.5, σ_acc 0, σ_m 0.2.
    n = eq11_parameters(15.0, 15.0, 0.4, 0.1)
    assert (n.sigma_pos, n.sigma_vel, n.sigma_acc, n.sigma_m) == pytest.approx((0.5, 0.5, 0.0, 0.2))
    assert n.threshold == pytest.approx(0.75)
    # §III-E: Crazyflie, 1.2 m/s, 1.2 m/s², 12 cm → 0.04, 0.04, σ_m 0.06, σ_threshold 0.09.
    n = eq11_parameters(1.2, 1.2, 0.12, 0.1)
    assert (n.sigma_pos, n.sigma_vel, n.sigma_m, n.threshold) == pytest.approx(
        (0.04, 0.04, 0.06, 0.09)
    )


def _state(n: int, g: np.random.Generator) -> np.ndarray:
    return g.normal(size=(n, 9))


@given(st.integers(0, 2**32 - 1), st.floats(0.05, 1.0))
def test_motion_models_without_noise(seed: int, rho: float) -> None:
    g = np.random.default_rng(seed)
    X = _state(50, g)
    quiet = NoiseParameters(0.0, 0.0, 0.0, 0.1, 0.1)
    Z = g.normal(size=(50, 9))
    T = 0.1
    p, v, a = X[:, :3], X[:, 3:6], X[:, 6:]
    # Constant acceleration: x + v T + ½ a T², v + a T, a.
    ca = predict(X, "ca", quiet, 1.0, Z)
    np.testing.assert_allclose(ca[:, :3], p + v * T + 0.5 * a * T**2, atol=1e-12)
    np.testing.assert_allclose(ca[:, 3:6], v + a * T, atol=1e-12)
    np.testing.assert_allclose(ca[:, 6:], a, atol=1e-12)
    # Constant velocity: x + v T, v, 0.
    cv = predict(X, "cv", quiet, 1.0, Z)
    np.testing.assert_allclose(cv[:, :3], p + v * T, atol=1e-12)
    np.testing.assert_allclose(cv[:, 3:6], v, atol=1e-12)
    assert not cv[:, 6:].any()
    # Delta position: x + v T, v = ρ Δx / T.
    delta = predict(X, "delta", quiet, rho, Z)
    np.testing.assert_allclose(delta[:, :3], p + v * T, atol=1e-12)
    np.testing.assert_allclose(delta[:, 3:6], rho * v, atol=1e-12)


def test_process_noise_has_the_configured_spread() -> None:
    g = np.random.default_rng(3)
    X = np.zeros((200_000, 9))
    noise = NoiseParameters(0.5, 0.3, 0.2, 0.2, 0.1)
    out = predict(X, "ca", noise, 1.0, g.standard_normal((200_000, 9)))
    np.testing.assert_allclose(out.std(axis=0), [0.5] * 3 + [0.3] * 3 + [0.2] * 3, rtol=0.01)


def test_cylinder_initialisation() -> None:
    X = cylinder_particles(np.random.default_rng(0), 20_000, np.array([25.0, 0.0, 1.0]), 20.0, 20.0)
    r = np.hypot(X[:, 0] - 25.0, X[:, 1])
    assert r.max() <= 20.0
    assert X[:, 2].min() >= 1.0
    assert X[:, 2].max() <= 21.0
    # r ~ U[0, R] as in the reference: the median radius is R/2 (not R/√2).
    assert np.median(r) == pytest.approx(10.0, rel=0.03)
    assert not X[:, 3:].any()


@given(arrays(np.float64, 30, elements=st.floats(0.0, 5.0)), st.floats(0.01, 1.0))
def test_weights_are_normalised_and_fall_with_distance(d: np.ndarray, sigma: float) -> None:
    w = likelihood_weights(d, sigma, 1e-4)
    assert w.sum() == pytest.approx(1.0)
    order = np.argsort(d)
    assert np.all(np.diff(w[order]) <= 1e-15)


@given(st.floats(0.01, 1.0), st.floats(1e-6, 1e-2), st.floats(1.0, 100.0))
def test_points_beyond_the_gate_cannot_change_the_weights(
    sigma: float, floor: float, beyond: float
) -> None:
    margin = gate_margin(sigma, floor)
    assert margin == pytest.approx(8.0 * sigma)
    d = margin * np.linspace(1.0, beyond, 50)
    w = likelihood_weights(d, sigma, floor)
    np.testing.assert_allclose(w, 1.0 / len(d), rtol=1e-6)


def test_no_gate_without_a_floor() -> None:
    assert gate_margin(0.2, 0.0) == np.inf
    # Without the floor, far points still rank the particles.
    w = likelihood_weights(np.array([1.6, 2.0]), 0.2, 0.0)
    assert w[0] > 0.99


@given(st.floats(0.01, 1.0), st.floats(40.0, 1e4), st.floats(0.0, 0.5))
def test_far_weights_without_a_floor_keep_their_ratios(
    sigma: float, k: float, delta: float
) -> None:
    """Beyond ~38 σ every Gaussian density underflows to 0; the log-weights still give
    w_0 / w_1 = exp(((d + δσ)² − d²) / (2σ²)) = exp(k δ + δ²/2) for d = k σ."""
    d = np.array([k * sigma, (k + delta) * sigma])
    assert np.all(np.exp(-0.5 * (d / sigma) ** 2) == 0.0)  # the linear form underflows
    w = likelihood_weights(d, sigma, 0.0)
    assert w.sum() == pytest.approx(1.0)
    # log of the known ratio; as k δ grows w_1 itself underflows, so compare in logs
    # only while w_1 is a normal number.
    log_ratio = k * delta + 0.5 * delta**2
    if log_ratio < 700.0:
        assert np.log(w[0]) - np.log(w[1]) == pytest.approx(log_ratio, rel=1e-6, abs=1e-6)
    else:
        assert w[0] == pytest.approx(1.0)


@settings(max_examples=20)
@given(st.integers(0, 2**32 - 1), st.integers(1, 1500))  # both sides of the switch
def test_nearest_distances_match_a_kd_tree(seed: int, m: int) -> None:
    g = np.random.default_rng(seed)
    q = g.uniform(-100, 100, (500, 3))
    p = g.uniform(-100, 100, (m, 3))
    expected, _ = cKDTree(p).query(q)
    np.testing.assert_allclose(nearest_distances(q, p), expected, atol=1e-4)


def _skewed_weights() -> np.ndarray:
    """Geometric weights over 60 particles with a heavy last one (30 %)."""
    w = 0.9 ** np.arange(59.0)
    return np.append(0.7 * w / w.sum(), 0.3)


def _chi_square_p(resample, w: np.ndarray, g: np.random.Generator) -> float:  # type: ignore[no-untyped-def]
    """p-value of the counts of 100 resamplings against the expected n·w."""
    draws = np.concatenate([resample(w, g) for _ in range(100)])
    counts = np.bincount(draws, minlength=len(w))
    expected = len(draws) * w
    # Pool the sparse tail so every bin expects ≥ 5 (the χ² approximation).
    order = np.argsort(expected)
    small = order[np.cumsum(expected[order]) < 5.0 * 3]
    keep = np.setdiff1d(np.arange(len(w)), small)
    obs = np.append(counts[keep], counts[small].sum())
    exp = np.append(expected[keep], expected[small].sum())
    return float(chisquare(obs, exp).pvalue)


@pytest.mark.parametrize("resample", [multinomial, systematic])
def test_resampling_draws_in_proportion_to_the_weights(resample) -> None:  # type: ignore[no-untyped-def]
    g = np.random.default_rng(0)
    one_hot = np.zeros(100)
    one_hot[37] = 1.0
    assert np.all(resample(one_hot, g) == 37)
    assert len(resample(_skewed_weights(), g)) == 60
    assert _chi_square_p(resample, _skewed_weights(), g) > 1e-3


def test_the_chi_square_check_rejects_a_biased_resampler() -> None:
    """The check above has power: drawing uniformly, or never the last index, fails it."""
    g = np.random.default_rng(0)
    w = _skewed_weights()

    def uniform(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return rng.integers(0, len(weights), len(weights))

    def drops_last(weights: np.ndarray, rng: np.random.Generator) -> np.ndarray:
        return multinomial(np.append(weights[:-1], 0.0) / weights[:-1].sum(), rng)

    assert _chi_square_p(uniform, w, g) < 1e-6
    assert _chi_square_p(drops_last, w, g) < 1e-6


def test_systematic_counts_are_within_one_of_n_w() -> None:
    g = np.random.default_rng(1)
    w = g.uniform(size=500)
    w /= w.sum()
    counts = np.bincount(systematic(w, g), minlength=500)
    assert np.all(np.abs(counts - 500 * w) < 1.0 + 1e-9)


def _filter(model: MotionModel = "delta", n: int = 5000, seed: int = 0) -> ParticleFilter:
    pf = ParticleFilter(
        n, model, eq11_parameters(15.0, 15.0, 0.4, 0.1), np.random.default_rng(seed)
    )
    pf.reset(np.array([25.0, 0.0, 1.0]), 20.0, 20.0)
    return pf


def _drone_points(center: np.ndarray, g: np.random.Generator, n: int = 5) -> np.ndarray:
    return center + g.normal(0.0, 0.05, (n, 3))


@pytest.mark.parametrize("model", ["delta", "cv", "ca"])
def test_the_filter_locks_on_and_follows(model: MotionModel) -> None:
    g = np.random.default_rng(2)
    pf = _filter(model)
    assert not pf.tracked
    center = np.array([30.0, 5.0, 12.0])
    velocity = np.array([5.0, 0.0, 0.0])
    for _ in range(30):
        pf.predict()
        center = center + 0.1 * velocity
        pf.update(_drone_points(center, g))
    assert pf.tracked
    pos, vel = pf.estimate()
    assert np.linalg.norm(pos - center) < 0.3
    assert np.linalg.norm(vel - velocity) < 2.0


def test_redetection_after_the_target_hides() -> None:
    g = np.random.default_rng(3)
    pf = _filter()
    here = np.array([30.0, 0.0, 10.0])
    for _ in range(20):
        pf.predict()
        pf.update(_drone_points(here, g))
    assert pf.tracked
    locked = pf.sigma_particles
    # Hidden for 3 s: no points, the cloud inflates and the filter reports the loss.
    spreads = []
    for _ in range(30):
        pf.predict()
        pf.update(np.empty((0, 3)))
        spreads.append(pf.sigma_particles)
    assert not pf.tracked
    assert np.all(np.diff(spreads[5:]) > 0)
    assert spreads[-1] > 3 * locked
    # It reappears 1.5 m away: two frames condense the cloud on it.
    there = here + np.array([0.0, 1.5, 0.0])
    for _ in range(2):
        pf.predict()
        pf.update(_drone_points(there, g))
    pos, _ = pf.estimate()
    assert pf.tracked
    assert np.linalg.norm(pos - there) < 0.3


def test_delta_velocity_is_damped_while_lost() -> None:
    # ρ = σ_pos / σ_particles once the spread exceeds σ_threshold (eq. 2).
    pf = _filter()
    assert not pf.tracked
    before = np.abs(pf.X[:, 3:6]).mean()
    pf.predict()
    pf.predict()
    rho = pf.noise.sigma_pos / pf.sigma_particles
    assert rho < 0.1
    # Undamped, the velocity would be the position noise over T: σ_pos/T = 5 m/s.
    assert np.abs(pf.X[:, 3:6]).mean() < 0.2 * 5.0 + before


def test_spread_is_the_mean_per_axis_std() -> None:
    X = np.random.default_rng(0).normal(0, [1.0, 2.0, 3.0, 0, 0, 0, 0, 0, 0], (100_000, 9))
    assert spread(X) == pytest.approx(2.0, rel=0.01)


def test_bad_filter_settings() -> None:
    noise = eq11_parameters(15.0, 15.0, 0.4, 0.1)
    with pytest.raises(ConfigError, match="motion model"):
        ParticleFilter(10, "jerk", noise, np.random.default_rng(0))  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="resampling"):
        ParticleFilter(10, "cv", noise, np.random.default_rng(0), resampling="stratified")


def test_the_tracker_can_be_reset_to_a_new_cylinder() -> None:
    tracker = ParticleTracker(
        3000,
        "delta",
        eq11_parameters(15.0, 15.0, 0.4, 0.1),
        np.random.default_rng(0),
        np.array([25.0, 0.0, 1.0]),
        20.0,
        20.0,
    )
    first = tracker.step(0.1, np.empty((0, 3)), 1)
    assert np.hypot(*(first.position[:2] - [25.0, 0.0])) < 2.0
    tracker.reset(center=np.array([-40.0, 10.0, 5.0]), radius=2.0, height=1.0)
    after = tracker.step(0.2, np.empty((0, 3)), 1)
    assert np.hypot(*(after.position[:2] - [-40.0, 10.0])) < 0.5
    assert 5.0 <= after.position[2] <= 6.0
    assert after.particles is not None
    assert np.all(np.hypot(after.particles[:, 0] + 40.0, after.particles[:, 1] - 10.0) < 2.0 + 2.0)


def _candidate(position: np.ndarray, velocity: np.ndarray) -> Candidates:
    return Candidates(
        position[None, :], velocity[None, :], np.array([3]), np.array([0.4]), np.array([7])
    )


@pytest.mark.parametrize("model", ["delta", "cv", "ca"])
def test_births_on_a_confirmed_candidate_lock_in_two_updates(model: MotionModel) -> None:
    """A drone 60 m from the start cylinder, flying at 10 m/s: with births the filter
    locks on the second update (the weight floor lets one or two of the old particles,
    60 m off, through the first resampling, which alone puts σ_particles above
    σ_threshold = 0.75 m); without births the cloud has not spread that far in 3 s."""
    noise = eq11_parameters(15.0, 15.0, 0.4, 0.1)
    v = np.array([10.0, 0.0, 0.0])

    def run(births: bool) -> list[bool]:
        rng = np.random.default_rng(5)
        pf = ParticleTracker(
            5000,
            model,
            noise,
            rng,
            np.array([25.0, 0.0, 1.0]),
            20.0,
            20.0,
        )
        locked = []
        for k in range(30):
            p = np.array([90.0, 40.0, 30.0]) + v * (0.1 * k)
            if births:
                pf.acquire(_candidate(p, v))
            e = pf.step(0.1 * k, _drone_points(p, rng), 1)
            locked.append(e.tracked and float(np.linalg.norm(e.position - p)) < 1.0)
        return locked

    assert all(run(births=True)[1:])
    assert not any(run(births=False))


def test_births_wait_while_locked_and_are_used_once() -> None:
    noise = eq11_parameters(15.0, 15.0, 0.4, 0.1)
    rng = np.random.default_rng(1)
    pf = ParticleTracker(2000, "delta", noise, rng, np.array([25.0, 0.0, 1.0]), 20.0, 20.0)
    here = np.array([80.0, 30.0, 20.0])  # outside the start cylinder
    for k in range(2):
        pf.acquire(_candidate(here, np.zeros(3)))
        locked = pf.step(0.1 * k, _drone_points(here, rng), 1).tracked
    assert locked
    # Locked: a candidate elsewhere (a bird, say) is offered but not taken.
    elsewhere = np.array([70.0, -20.0, 15.0])
    pf.acquire(_candidate(elsewhere, np.zeros(3)))
    e = pf.step(0.3, _drone_points(here, rng), 1)
    assert e.tracked
    assert e.particles is not None
    assert np.linalg.norm(e.particles - elsewhere, axis=1).min() > 10.0


def test_birth_share_is_validated() -> None:
    noise = eq11_parameters(15.0, 15.0, 0.4, 0.1)
    with pytest.raises(ConfigError, match="birth_share"):
        ParticleTracker(
            100, "delta", noise, np.random.default_rng(0), np.zeros(3), 1.0, 1.0, birth_share=1.5
        )
