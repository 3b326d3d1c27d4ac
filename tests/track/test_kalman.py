"""The Kalman maths: against FilterPy, finite differences, closed forms and hand-worked cases."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter
from hypothesis import given
from hypothesis import strategies as st
from scipy.linalg import expm
from scipy.stats import chi2

from dronetrack.track.kalman import (
    CHI2_3DOF_99,
    CTRV_STRAIGHT_LIMIT,
    adapt_measurement_noise,
    adapt_process_noise,
    ca_transition,
    centroid_within,
    ctrv_jacobian,
    ctrv_predict,
    cv_transition,
    dogru_search_radius,
    kf_predict,
    kf_update,
    mahalanobis_sq,
    position_selector,
)

seeds = st.integers(0, 2**32 - 1)
W = np.eye(6)[5]  # the yaw-rate direction of the CTRV state


def _spd(g: np.random.Generator, n: int, scale: float = 1.0) -> np.ndarray:
    """A random symmetric positive definite matrix, eigenvalues in [0.1, 2.1]·scale."""
    A = g.normal(size=(n, n))
    Qm, _ = np.linalg.qr(A)
    out: np.ndarray = scale * (Qm * g.uniform(0.1, 2.1, n)) @ Qm.T
    return 0.5 * (out + out.T)


def _filterpy(x: np.ndarray, P: np.ndarray, m: int) -> KalmanFilter:
    kf = KalmanFilter(dim_x=len(x), dim_z=m)
    kf.x = x.reshape(-1, 1).copy()
    kf.P = P.copy()
    return kf


@given(seeds, st.integers(1, 9))
def test_predict_matches_filterpy(seed: int, n: int) -> None:
    g = np.random.default_rng(seed)
    x, P, F, Q = g.normal(size=n), _spd(g, n), g.normal(size=(n, n)), _spd(g, n, 0.1)
    kf = _filterpy(x, P, 1)
    kf.F, kf.Q = F, Q
    kf.predict()
    x1, P1 = kf_predict(x, P, F, Q)
    np.testing.assert_allclose(x1, kf.x.ravel(), rtol=0, atol=1e-9)
    np.testing.assert_allclose(P1, kf.P, rtol=0, atol=1e-9)


@given(seeds, st.integers(1, 9), st.integers(1, 3))
def test_update_matches_filterpy(seed: int, n: int, m: int) -> None:
    g = np.random.default_rng(seed)
    m = min(m, n)
    x, P, R = g.normal(size=n), _spd(g, n), _spd(g, m, 0.5)
    H, z = g.normal(size=(m, n)), g.normal(size=m)
    kf = _filterpy(x, P, m)
    kf.H, kf.R = H, R
    kf.update(z.reshape(-1, 1))
    u = kf_update(x, P, z, H, R)
    np.testing.assert_allclose(u.d, kf.y.ravel(), rtol=0, atol=1e-9)
    np.testing.assert_allclose(u.S, kf.S, rtol=0, atol=1e-9)
    np.testing.assert_allclose(u.K, kf.K, rtol=0, atol=1e-9)
    np.testing.assert_allclose(u.x, kf.x.ravel(), rtol=0, atol=1e-9)
    # FilterPy's Joseph form (I − KH)P(I − KH)ᵀ + KRKᵀ equals (I − KH)P for the optimal K.
    np.testing.assert_allclose(u.P, kf.P, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(u.P, u.P.T)
    # ε = z − H x⁺
    np.testing.assert_allclose(u.eps, z - H @ kf.x.ravel(), rtol=0, atol=1e-9)


def test_update_by_hand_scalar() -> None:
    # One state, one measurement: S = p + r, K = p/S, x⁺ = x + K d, P⁺ = p r / S.
    u = kf_update(np.array([1.0]), np.array([[3.0]]), np.array([5.0]), np.eye(1), np.eye(1))
    assert u.d[0] == pytest.approx(4.0)
    assert u.S[0, 0] == pytest.approx(4.0)
    assert u.K[0, 0] == pytest.approx(0.75)
    assert u.x[0] == pytest.approx(4.0)
    assert u.P[0, 0] == pytest.approx(0.75)
    assert u.eps[0] == pytest.approx(1.0)


@pytest.mark.parametrize("T", [0.05, 0.1, 0.37])
def test_transitions_are_the_exponentials_of_the_kinematics(T: float) -> None:
    # d/dt [p, v] = [v, 0] and d/dt [p, v, a] = [v, a, 0]: F = exp(A T).
    A6 = np.zeros((6, 6))
    A6[0:3, 3:6] = np.eye(3)
    np.testing.assert_allclose(cv_transition(T), expm(A6 * T), atol=1e-12)
    A9 = np.zeros((9, 9))
    A9[0:3, 3:6] = np.eye(3)
    A9[3:6, 6:9] = np.eye(3)
    np.testing.assert_allclose(ca_transition(T), expm(A9 * T), atol=1e-12)


def test_position_selector() -> None:
    x = np.arange(9.0)
    np.testing.assert_array_equal(position_selector(9) @ x, [0.0, 1.0, 2.0])
    assert position_selector(6).shape == (3, 6)


def test_ctrv_straight_and_quarter_turn() -> None:
    T, v = 0.1, 2.0
    # Straight, heading 30°: v T along the heading; z rises by the horizontal speed.
    x = np.array([1.0, 2.0, 3.0, v, np.pi / 6, 0.0])
    out = ctrv_predict(x, T)
    np.testing.assert_allclose(
        out,
        [1 + v * T * np.cos(np.pi / 6), 2 + v * T * np.sin(np.pi / 6), 3 + v * T, v, np.pi / 6, 0],
    )
    # A quarter circle to the left from the origin heading +x ends at (ρ, ρ), ρ = v/ω.
    n = 25
    omega = (np.pi / 2) / (n * T)
    s = np.array([0.0, 0.0, 0.0, v, 0.0, omega])
    for _ in range(n):
        s = ctrv_predict(s, T)
    rho = v / omega
    np.testing.assert_allclose(s[0:2], [rho, rho], atol=1e-12)
    assert s[2] == pytest.approx(v * n * T)  # the model's vertical assumption: ż = v
    assert s[4] == pytest.approx(np.pi / 2)


def test_ctrv_is_continuous_at_the_straight_limit() -> None:
    T = 0.1
    x = np.array([0.0, 0.0, 0.0, 5.0, 0.7, 0.0])
    below = ctrv_predict(x + 0.999 * CTRV_STRAIGHT_LIMIT * W, T)
    above = ctrv_predict(x + 1.001 * CTRV_STRAIGHT_LIMIT * W, T)
    # The turning term the straight branch drops is ½ v T² ω ≈ 2.5e-5 m.
    np.testing.assert_allclose(below, above, atol=0.5 * 5.0 * T**2 * 1.1e-3 + 1e-12)


def _central_difference(x: np.ndarray, T: float, h: float = 1e-6) -> np.ndarray:
    J = np.zeros((6, 6))
    for j in range(6):
        e = np.zeros(6)
        e[j] = h
        J[:, j] = (ctrv_predict(x + e, T) - ctrv_predict(x - e, T)) / (2 * h)
    return J


@given(seeds)
def test_ctrv_jacobian_matches_central_differences(seed: int) -> None:
    g = np.random.default_rng(seed)
    T = g.uniform(0.02, 0.2)
    omega = g.choice([-1, 1]) * g.uniform(0.01, 2.0)  # clear of the straight branch
    x = np.array([*g.normal(size=3) * 10, g.uniform(-10, 10), g.uniform(-np.pi, np.pi), omega])
    numeric = _central_difference(x, T)
    np.testing.assert_allclose(ctrv_jacobian(x, T), numeric, rtol=0, atol=1e-6)
    # The released code's Jacobian lacks ∂z'/∂v = T, and only that.
    reference = ctrv_jacobian(x, T, dz_dv=False)
    diff = numeric - reference
    assert diff[2, 3] == pytest.approx(T, abs=1e-6)
    diff[2, 3] = 0.0
    np.testing.assert_allclose(diff, 0.0, atol=1e-6)


@given(seeds)
def test_straight_jacobian_is_the_limit_of_the_turning_one(seed: int) -> None:
    g = np.random.default_rng(seed)
    T, v = g.uniform(0.02, 0.2), g.uniform(-10, 10)
    x = np.array([0.0, 0.0, 0.0, v, g.uniform(-np.pi, np.pi), 0.0])
    straight = ctrv_jacobian(x, T)
    omega = 2 * CTRV_STRAIGHT_LIMIT
    turning = ctrv_jacobian(x + omega * W, T)
    # Taylor in ωT: the turning entries differ from their ω → 0 limits by ½ T² ω (∂/∂v),
    # ½ |v| T² ω (∂/∂ψ) and |v| T³ ω / 3 (∂/∂ω), all below (1 + |v|) T² ω.
    np.testing.assert_allclose(straight, turning, rtol=0, atol=(1 + abs(v)) * T**2 * omega)
    assert straight[4, 5] == T


def test_process_noise_adaptation_by_hand() -> None:
    # K d = (3, 6): ½ diag(1, 2) + ½ [[9, 18], [18, 36]]
    Q = adapt_process_noise(np.diag([1.0, 2.0]), np.array([[1.0], [2.0]]), np.array([3.0]), 0.5)
    np.testing.assert_allclose(Q, [[5.0, 9.0], [9.0, 19.0]])


def test_measurement_noise_adaptation_by_hand() -> None:
    # ½ I + ½ (ε εᵀ + H P⁻ Hᵀ), ε = (1, 2), H picks states 0 and 2 of P⁻ = diag(4, 7, 9).
    H = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    R = adapt_measurement_noise(np.eye(2), np.array([1.0, 2.0]), H, np.diag([4.0, 7.0, 9.0]), 0.5)
    np.testing.assert_allclose(R, [[3.0, 1.0], [1.0, 7.0]])


@given(seeds, st.floats(0.0, 1.0))
def test_adapted_noise_stays_symmetric_psd(seed: int, w: float) -> None:
    g = np.random.default_rng(seed)
    n = 9
    Q0, P, R0 = _spd(g, n), _spd(g, n), _spd(g, 3)
    K, d, eps, H = g.normal(size=(n, 3)), g.normal(size=3), g.normal(size=3), position_selector(n)
    for A in (adapt_process_noise(Q0, K, d, w), adapt_measurement_noise(R0, eps, H, P, w)):
        np.testing.assert_allclose(A, A.T, atol=1e-12)
        assert np.linalg.eigvalsh(A).min() > -1e-12
    # α = 1 and β = 1 forget nothing: Q and R are unchanged.
    np.testing.assert_array_equal(adapt_process_noise(Q0, K, d, 1.0), Q0)
    np.testing.assert_array_equal(adapt_measurement_noise(R0, eps, H, P, 1.0), R0)


def test_mahalanobis_by_hand() -> None:
    S = np.diag([4.0, 9.0, 1.0])
    assert mahalanobis_sq(np.zeros(3), S) == 0.0
    assert mahalanobis_sq(np.array([2.0, 3.0, 1.0]), S) == pytest.approx(3.0)
    # A correlated S: dᵀ S⁻¹ d with S⁻¹ of [[2, 1], [1, 2]] = [[2, −1], [−1, 2]] / 3
    assert mahalanobis_sq(np.array([1.0, 1.0]), np.array([[2.0, 1.0], [1.0, 2.0]])) == (
        pytest.approx(2.0 / 3.0)
    )


def test_mahalanobis_of_consistent_innovations_is_chi2_3() -> None:
    g = np.random.default_rng(7)
    S = _spd(g, 3, 2.0)
    n = 20000
    d = g.multivariate_normal(np.zeros(3), S, size=n)
    D = np.array([mahalanobis_sq(di, S) for di in d])
    # χ²(3): mean 3, variance 6; the gate's tail is 1 %.
    assert abs(D.mean() - 3.0) < 4 * np.sqrt(6.0 / n)
    assert abs(np.mean(D > CHI2_3DOF_99) - 0.01) < 4 * np.sqrt(0.01 * 0.99 / n)
    assert chi2.ppf(0.99, 3) == pytest.approx(CHI2_3DOF_99, rel=1e-12)


def test_dogru_search_radius() -> None:
    P = np.diag([0.04, 0.09, 0.01, 5.0, 5.0, 5.0])  # velocity variances do not count
    assert dogru_search_radius(P) == pytest.approx(0.9)
    assert dogru_search_radius(P, 1.5) == pytest.approx(1.5)
    assert dogru_search_radius(P, 0.5) == pytest.approx(0.9)


def test_centroid_within() -> None:
    pts = np.array([[1.0, 0, 0], [0, 1.0, 0], [0, 0, 3.0], [0.5, 0.5, 0]])
    c, n = centroid_within(pts, np.zeros(3), 1.0)  # the sphere is closed: |p| = 1 counts
    assert n == 3
    np.testing.assert_allclose(c, [0.5, 0.5, 0.0])
    assert centroid_within(pts, np.array([10.0, 0, 0]), 1.0) == (None, 0)
    assert centroid_within(np.zeros((0, 3)), np.zeros(3), 1.0) == (None, 0)


@given(seeds, st.integers(2, 9), st.integers(1, 3), st.floats(1e-12, 1e-3))
def test_joseph_update_stays_symmetric_and_positive_semidefinite(
    seed: int, n: int, m: int, r: float
) -> None:
    """An ill-conditioned prior (eigenvalues from 10⁻⁶ to 10⁶) and a nearly exact
    measurement: P⁺ keeps P⁺ = P⁺ᵀ and no eigenvalue below −10⁻¹² of the largest."""
    g = np.random.default_rng(seed)
    m = min(m, n)
    Q, _ = np.linalg.qr(g.normal(size=(n, n)))
    P = (Q * np.logspace(-6, 6, n)) @ Q.T
    P = 0.5 * (P + P.T)
    H, R = g.normal(size=(m, n)), r * np.eye(m)
    u = kf_update(g.normal(size=n), P, g.normal(size=m), H, R)
    np.testing.assert_array_equal(u.P, u.P.T)
    eig = np.linalg.eigvalsh(u.P)
    assert eig.min() >= -1e-12 * eig.max()
    # The measured directions shrink to about R: H P⁺ Hᵀ ≤ R + (rounding).
    assert np.all(np.diag(H @ u.P @ H.T) <= r * (1.0 + 1e-3) + 1e-9 * eig.max())
