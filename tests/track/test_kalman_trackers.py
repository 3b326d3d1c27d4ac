"""The Kalman-family trackers on synthetic targets with known answers."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from filterpy.kalman import ExtendedKalmanFilter, KalmanFilter

from dronetrack.detect.candidates import CandidateDetector
from dronetrack.errors import ConfigError, InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.track.cluster_kalman import (
    SEED003_P0,
    AdaptiveEKF,
    CentroidEKF,
    ConstantAccelerationKF,
)
from dronetrack.track.kalman import (
    CHI2_3DOF_99,
    ca_transition,
    ctrv_jacobian,
    ctrv_predict,
    position_selector,
)
from dronetrack.track.particle import ParticleTracker, eq11_parameters
from dronetrack.track.sphere_kalman import CatalanoEKF, DogruEKF
from dronetrack.types import TrackEstimate

T = 0.1
NONE = np.zeros((0, 3))
Kalman = DogruEKF | CatalanoEKF | CentroidEKF | ConstantAccelerationKF | AdaptiveEKF

TRACKERS: dict[str, Callable[[], Kalman]] = {
    "ekf-dogru": DogruEKF,
    "ekf-catalano": CatalanoEKF,
    "ekf-catalano-mod": lambda: CatalanoEKF(search_radius=1.5),
    "ekf-cv": CentroidEKF,
    "kf-ca": ConstantAccelerationKF,
    "aekf-ca": AdaptiveEKF,
}


def blob(
    rng: np.random.Generator, center: FloatArray, n: int = 40, sigma: float = 0.05
) -> FloatArray:
    """n points around ``center``, per-axis standard deviation σ."""
    out: FloatArray = center + sigma * rng.standard_normal((n, 3))
    return out


def fly(
    tracker: Kalman,
    truth: Callable[[int], FloatArray],
    frames: range,
    rng: np.random.Generator,
    sigma: float = 0.05,
) -> tuple[list[TrackEstimate], FloatArray]:
    estimates, positions = [], []
    for k in frames:
        estimates.append(tracker.step(k * T, blob(rng, truth(k), sigma=sigma), 1))
        positions.append(truth(k))
    return estimates, np.array(positions)


def straight(p0: FloatArray, v: FloatArray) -> Callable[[int], FloatArray]:
    return lambda k: p0 + v * k * T


P0 = np.array([20.0, 5.0, 3.0])
V = np.array([1.0, 0.5, 0.0])  # 1.12 m/s, horizontal
SIDE = np.array([0.0, 5.0, 0.0])


@pytest.mark.parametrize("kind", TRACKERS)
def test_nothing_seen_yet_gives_the_home_point(kind: str) -> None:
    tracker = TRACKERS[kind]()
    for k in range(5):
        e = tracker.step(k * T, NONE, 1)
        np.testing.assert_array_equal(e.position, [0.0, 0.0, 0.0])
        np.testing.assert_array_equal(e.velocity, [0.0, 0.0, 0.0])
        assert not e.tracked
        assert e.measurement is None
        assert e.particles is None
        assert e.variance is not None
        assert np.all(np.isfinite(e.variance))
        assert np.isfinite(e.spread)
    home = np.array([1.0, 2.0, 3.0])
    tracker = type(tracker)(home=home)
    np.testing.assert_array_equal(tracker.step(0.0, NONE, 1).position, home)


@pytest.mark.parametrize("kind", ["ekf-dogru", "ekf-cv", "kf-ca", "aekf-ca"])
def test_converges_on_a_constant_velocity_target(kind: str) -> None:
    rng = np.random.default_rng(1)
    estimates, truth = fly(TRACKERS[kind](), straight(P0, V), range(150), rng)
    err = np.array([e.position for e in estimates[100:]]) - truth[100:]
    # Each measurement is a convex combination of points with per-axis σ = 0.05 m, and
    # the CV and CA models follow a ramp without steady-state lag.  0.1 m is below the
    # 0.11 m the target covers per period, so a filter one period behind fails.
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < 0.1
    vel = np.array([e.velocity for e in estimates[100:]])
    assert np.abs(vel.mean(axis=0) - V).max() < 0.1
    assert all(e.tracked for e in estimates[100:])


def test_catalano_follows_horizontally_and_rises_with_its_horizontal_speed() -> None:
    rng = np.random.default_rng(2)
    estimates, truth = fly(CatalanoEKF(search_radius=1.5), straight(P0, V), range(150), rng)
    err = np.array([e.position for e in estimates[100:]]) - truth[100:]
    assert np.sqrt(np.mean(np.sum(err[:, :2] ** 2, axis=1))) < 0.1
    # z' = z + v T with v the horizontal speed, and no ∂z/∂v: z is a decoupled random
    # walk (q = σ_acc² = 0.0025, r = σ_lidar² = 0.01) pushed up by v T each period.  Its
    # steady prior variance solves p² − q p − q r = 0 and its gain is k = p / (p + r);
    # the bias b of the posterior then satisfies b = (1 − k)(b + v T).
    q, r, speed = 0.05**2, 0.1**2, float(np.linalg.norm(V))
    p = (q + np.sqrt(q * q + 4 * q * r)) / 2
    k = p / (p + r)
    bias = (1 - k) * speed * T / k
    assert err[:, 2].mean() == pytest.approx(bias, abs=0.02)
    # Its reported vertical velocity is the model's: v.
    assert estimates[-1].velocity[2] == pytest.approx(np.hypot(*estimates[-1].velocity[:2]))


def test_catalano_matches_filterpys_ekf() -> None:
    x0 = np.array([1.0, 2.0, 3.0, 1.5, 0.4, 0.3])
    tracker = CatalanoEKF(search_radius=1.5)
    tracker.initialize(x0[:3])
    tracker.x = x0.copy()
    z = np.array([1.2, 2.1, 3.05])
    tracker.step(0.0, np.array([z - 0.01, z + 0.01]), 1)

    class CTRV(ExtendedKalmanFilter):  # type: ignore[misc]
        def predict_x(self, u: object = 0) -> None:
            self.x = ctrv_predict(self.x, T)

    ekf = CTRV(dim_x=6, dim_z=3)
    ekf.x, ekf.P = x0.copy(), np.eye(6)
    ekf.F, ekf.Q = ctrv_jacobian(x0, T, dz_dv=False), 0.05**2 * np.eye(6)
    ekf.R = 0.1**2 * np.eye(3)
    ekf.predict()
    H = position_selector(6)
    ekf.update(z, HJacobian=lambda _x: H, Hx=lambda s: H @ s)
    np.testing.assert_allclose(tracker.x, ekf.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(tracker.P, ekf.P, rtol=0, atol=1e-9)


def test_the_first_frame_sets_the_position_to_the_centroid_of_all_points() -> None:
    rng = np.random.default_rng(3)
    for tracker in (DogruEKF(), CatalanoEKF()):
        tracker.step(0.0, NONE, 1)  # no prediction before the first fix
        np.testing.assert_array_equal(tracker.P, np.eye(6))
        pts = np.vstack([blob(rng, P0), blob(rng, P0 + np.array([30.0, 0, 0]), n=10)])
        e = tracker.step(T, pts, 1)
        np.testing.assert_allclose(e.position, pts.mean(axis=0))
        np.testing.assert_allclose(e.measurement, pts.mean(axis=0))
        np.testing.assert_array_equal(tracker.x[3:], 0.0)
        np.testing.assert_array_equal(tracker.P, np.eye(6))


def test_dogru_measures_the_centroid_inside_its_sphere() -> None:
    rng = np.random.default_rng(4)
    tracker = DogruEKF()
    tracker.initialize(P0)
    pts = blob(rng, P0, sigma=0.02)
    # P⁻_xx = 1 + T² + σ_acc² after one period from P0 = I: r = 3.02 m; a stray point 4 m
    # from the (motionless) prediction stays out of the centroid.
    stray = P0 + np.array([4.0, 0.0, 0.0])
    e = tracker.step(T, np.vstack([pts, stray]), 1)
    assert tracker.search_radius == pytest.approx(3 * np.sqrt(1 + T**2 + 0.05**2))
    np.testing.assert_allclose(e.measurement, pts.mean(axis=0))


def _hover_then_sidestep(
    tracker: Kalman, rng: np.random.Generator
) -> tuple[list[float], list[TrackEstimate], FloatArray]:
    """Hover 6 s, hide 1 s, reappear 0.8 m to the side; radii during the gap."""
    for k in range(60):
        tracker.step(k * T, blob(rng, P0, sigma=0.02), 1)
    radii = []
    for k in range(60, 70):
        tracker.step(k * T, NONE, 1)
        radii.append(tracker.search_radius)  # type: ignore[union-attr]
    moved = P0 + np.array([0.0, 0.8, 0.0])
    return (
        radii,
        [tracker.step(k * T, blob(rng, moved, sigma=0.02), 1) for k in range(70, 120)],
        moved,
    )


def test_dogru_widens_its_sphere_until_it_recaptures() -> None:
    rng = np.random.default_rng(5)
    tracker = DogruEKF()
    radii, after, moved = _hover_then_sidestep(tracker, rng)
    assert np.all(np.diff(radii) > 0)
    assert radii[0] < 0.8 - 4 * 0.02  # the sidestep leaves the sphere it had
    assert any(e.measurement is not None for e in after)
    for e in after:
        assert e.variance is not None
        assert e.tracked == bool(np.all(e.variance[:3] < 1.5))
    assert np.linalg.norm(after[-1].position - moved) < 0.05
    assert after[-1].tracked


def test_catalanos_fixed_sphere_never_recaptures() -> None:
    rng = np.random.default_rng(5)
    tracker = CatalanoEKF()
    radii, after, moved = _hover_then_sidestep(tracker, rng)
    assert radii == [0.2] * len(radii)
    # 0.8 m away with points within 4σ = 0.08 m of the centre: none within 0.2 m.
    assert all(e.measurement is None for e in after)
    tracker.initialize(moved)
    e = tracker.step(12.0, blob(rng, moved, sigma=0.02), 1)
    assert e.measurement is not None


def test_centroid_ekf_is_lost_after_the_timeout_and_restarts_on_the_next_centroid() -> None:
    rng = np.random.default_rng(6)
    tracker = CentroidEKF()
    truth = straight(P0, V)
    fly(tracker, truth, range(50), rng)
    t_last = 49 * T
    for k in range(50, 80):
        e = tracker.step(k * T, NONE, 1)
        if k * T - t_last < 2.0 - 1e-9:
            assert e.tracked
        elif k * T - t_last > 2.0 + 1e-9:
            assert not e.tracked
    far = blob(rng, P0 + np.array([30.0, -10.0, 2.0]), n=30, sigma=0.05)
    e = tracker.step(80 * T, far, 1)
    assert e.tracked
    np.testing.assert_allclose(e.position, far.mean(axis=0))
    np.testing.assert_allclose(e.measurement, far.mean(axis=0))
    np.testing.assert_array_equal(e.velocity, 0.0)
    np.testing.assert_allclose(e.variance, SEED003_P0)


def test_centroid_ekf_is_lost_when_its_variance_passes_the_threshold() -> None:
    tracker = CentroidEKF(lost_after_s=100.0)
    tracker.initialize(P0)
    q = 0.01
    # With no update, P_xx(n) = [Fⁿ P0 Fⁿᵀ]ₓₓ + Σ_{j<n} [Fʲ Q Fʲᵀ]ₓₓ
    #                          = 1 + 16 (nT)² + q Σ_{j<n} (1 + (jT)²)
    for n in range(1, 30):
        pxx = 1 + 16 * (n * T) ** 2 + q * sum(1 + (j * T) ** 2 for j in range(n))
        e = tracker.step(n * T, NONE, 1)
        assert e.variance is not None
        assert e.variance[0] == pytest.approx(pxx)
        assert e.tracked == (pxx <= 25.0)


def _ca_run(
    tracker: ConstantAccelerationKF, rng: np.random.Generator, frames: int = 80
) -> Callable[[int], FloatArray]:
    truth = straight(P0, V)
    fly(tracker, truth, range(frames), rng, sigma=0.1)
    return truth


@pytest.mark.parametrize("kind", [ConstantAccelerationKF, AdaptiveEKF])
def test_the_gate_rejects_a_far_cluster(kind: type[ConstantAccelerationKF]) -> None:
    rng = np.random.default_rng(7)
    tracker = kind()
    truth = _ca_run(tracker, rng)
    # The drone hides; a bigger, drone-sized cluster shows up 5 m away.
    before = tracker.x.copy()
    e = tracker.step(80 * T, blob(rng, truth(80) + SIDE, n=120, sigma=0.1), 1)
    assert e.measurement is None
    assert min(tracker.distances) > CHI2_3DOF_99
    np.testing.assert_allclose(tracker.x, tracker.F @ before, atol=1e-12)
    # With both in view the drone's cluster is taken, although it is the smaller one.
    drone = blob(rng, truth(81), sigma=0.1)
    e = tracker.step(81 * T, np.vstack([drone, blob(rng, truth(81) + SIDE, n=120)]), 1)
    assert e.measurement is not None
    assert np.linalg.norm(e.measurement - truth(81)) < 0.2


def test_clusters_larger_than_a_drone_are_no_candidates() -> None:
    rng = np.random.default_rng(8)
    tracker = AdaptiveEKF()
    wall = np.column_stack([np.linspace(0, 4, 200), np.zeros(200), np.full(200, 3.0)])
    assert not tracker.step(0.0, wall + 0.01 * rng.standard_normal((200, 3)), 1).tracked
    drone = blob(rng, P0, sigma=0.1)
    e = tracker.step(T, np.vstack([wall, drone]), 1)
    assert e.tracked
    # Initialised at the (voxel-averaged) drone cluster, well away from the wall.
    assert np.linalg.norm(e.position - P0) < 0.2


def test_after_t_occ_only_the_adaptive_filter_restarts_elsewhere() -> None:
    rng = np.random.default_rng(9)
    fixed, adaptive = ConstantAccelerationKF(), AdaptiveEKF()
    truth = _ca_run(fixed, rng)
    _ca_run(adaptive, rng)
    x0 = fixed.x.copy()
    p, v, a = x0[0:3], x0[3:6], x0[6:9]
    for n in range(1, 21):  # 2 s in the dark
        ef, ea = fixed.step((79 + n) * T, NONE, 1), adaptive.step((79 + n) * T, NONE, 1)
        # Prediction only: p + v t + ½ a t² with the last state.
        np.testing.assert_allclose(ef.position, p + v * n * T + 0.5 * a * (n * T) ** 2, atol=1e-9)
        assert ef.tracked == ea.tracked == (n * T <= 1.0 + 1e-9)
    far = blob(rng, truth(100) + np.array([100.0, 0.0, 0.0]), sigma=0.1)
    ef, ea = fixed.step(100 * T, far, 1), adaptive.step(100 * T, far, 1)
    # The fixed filter gates it out: D_M ≥ |d|² / λ_max(S) and λ_max(S) ≤ tr(H P⁻ Hᵀ) + σ_lidar².
    assert ef.measurement is None
    assert ef.variance is not None
    # Without an update the reported variance is P⁻'s and the position x⁻'s.
    bound = np.sum((far.mean(axis=0) - ef.position) ** 2) / (ef.variance[:3].sum() + 0.1**2)
    assert bound > 2 * CHI2_3DOF_99  # voxel averaging moves the centroid by centimetres only
    assert min(fixed.distances) > CHI2_3DOF_99
    # The adaptive one starts again there: velocity and acceleration 0, P = P0.
    assert ea.tracked
    assert ea.measurement is not None
    np.testing.assert_allclose(ea.position, ea.measurement)
    np.testing.assert_array_equal(adaptive.x[3:], 0.0)
    np.testing.assert_array_equal(adaptive.P, adaptive.P0)


def test_adaptation_moves_q_and_r_and_keeps_them_symmetric_psd() -> None:
    rng = np.random.default_rng(10)
    tracker = AdaptiveEKF()
    _ca_run(tracker, rng)
    for A, A0 in ((tracker.Q, tracker.Q0), (tracker.R, tracker.R0)):
        assert not np.allclose(A, A0)
        np.testing.assert_allclose(A, A.T, atol=1e-15)
        assert np.linalg.eigvalsh(A).min() >= -1e-15


def test_without_forgetting_the_adaptive_filter_is_the_fixed_one() -> None:
    # α = β = 1 turns eqs. (6) and (8) into Q_k = Q_{k−1}, R_k = R_{k−1}.
    a, b = np.random.default_rng(11), np.random.default_rng(11)
    fixed, adaptive = ConstantAccelerationKF(), AdaptiveEKF(alpha=1.0, beta=1.0)
    _ca_run(fixed, a)
    _ca_run(adaptive, b)
    np.testing.assert_array_equal(adaptive.x, fixed.x)
    np.testing.assert_array_equal(adaptive.P, fixed.P)


def test_one_adaptive_step_is_filterpys_plus_eqs_6_and_8() -> None:
    rng = np.random.default_rng(15)
    tracker = AdaptiveEKF(alpha=0.9, beta=0.8)
    tracker.initialize(P0)
    e = tracker.step(T, blob(rng, P0 + np.array([0.05, 0.0, 0.0]), sigma=0.1), 1)
    z = e.measurement
    assert z is not None
    kf = KalmanFilter(dim_x=9, dim_z=3)
    kf.x = np.concatenate([P0, np.zeros(6)]).reshape(-1, 1)
    kf.P = np.diag([1.0] * 3 + [25.0] * 6)  # (1 m)², (5 m/s)², (5 m/s²)²
    kf.F = ca_transition(T)
    Q0 = np.diag([0.05**2] * 3 + [0.1**2] * 3 + [0.5**2] * 3)
    kf.Q, kf.R = Q0, 0.1**2 * np.eye(3)
    kf.H = position_selector(9)
    kf.predict()
    P_pred = kf.P.copy()
    kf.update(z.reshape(-1, 1))
    np.testing.assert_allclose(tracker.x, kf.x.ravel(), rtol=0, atol=1e-9)
    np.testing.assert_allclose(tracker.P, kf.P, rtol=0, atol=1e-9)
    Kd = (kf.K @ kf.y).ravel()
    eps = z - kf.x.ravel()[:3]
    np.testing.assert_allclose(tracker.Q, 0.9 * Q0 + 0.1 * np.outer(Kd, Kd), rtol=0, atol=1e-12)
    R = 0.8 * kf.R + 0.2 * (np.outer(eps, eps) + P_pred[:3, :3])
    np.testing.assert_allclose(tracker.R, R, rtol=0, atol=1e-12)


@pytest.mark.parametrize("kind", ["ekf-dogru", "kf-ca"])
def test_several_periods_in_one_step(kind: str) -> None:
    # step(t, points, 3) = two empty periods, then the frame.
    rng = np.random.default_rng(16)
    one, three = TRACKERS[kind](), TRACKERS[kind]()
    for tracker in (one, three):
        tracker.initialize(P0)
    pts = blob(rng, P0 + 0.3 * V, sigma=0.1)
    one.step(T, NONE, 1)
    one.step(2 * T, NONE, 1)
    a = one.step(3 * T, pts, 1)
    b = three.step(3 * T, pts, 3)
    assert a.measurement is not None
    np.testing.assert_allclose(b.position, a.position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(three.P, one.P, rtol=0, atol=1e-12)


def test_centroid_ekf_takes_the_largest_cluster_then_the_nearest() -> None:
    rng = np.random.default_rng(17)
    tracker = CentroidEKF()
    small, big = blob(rng, P0, n=10), blob(rng, P0 + SIDE, n=60)
    e = tracker.step(0.0, np.vstack([small, big]), 1)
    np.testing.assert_allclose(e.position, big.mean(axis=0))
    tracker.initialize(P0)
    e = tracker.step(T, np.vstack([small, big]), 1)
    np.testing.assert_allclose(e.measurement, small.mean(axis=0))


INITIAL_VARIANCE = {
    "ekf-dogru": [1.0] * 6,
    # (v cos ψ, v sin ψ, v) at v = ψ = 0 with var v = var ψ = 1: (1, 0, 1)
    "ekf-catalano": [1.0, 1.0, 1.0, 1.0, 0.0, 1.0],
    "ekf-catalano-mod": [1.0, 1.0, 1.0, 1.0, 0.0, 1.0],
    "ekf-cv": list(SEED003_P0),
    "kf-ca": [1.0] * 3 + [25.0] * 3,
    "aekf-ca": [1.0] * 3 + [25.0] * 3,
}


@pytest.mark.parametrize("kind", TRACKERS)
def test_initialize_reset_and_repeated_frames(kind: str) -> None:
    rng = np.random.default_rng(12)
    tracker = TRACKERS[kind]()
    tracker.initialize(P0)
    e = tracker.step(0.0, NONE, 0)
    np.testing.assert_array_equal(e.position, P0)
    np.testing.assert_array_equal(e.velocity, 0.0)
    np.testing.assert_allclose(e.variance, INITIAL_VARIANCE[kind])
    assert e.spread == pytest.approx(1.0)
    # It takes the drone where it was put.
    e = tracker.step(T, blob(rng, P0, sigma=0.03), 1)
    assert e.measurement is not None
    assert e.tracked
    # A repeated frame changes nothing, whatever points come with it.
    x, P = tracker.x.copy(), tracker.P.copy()
    again = tracker.step(T, blob(rng, P0 + 0.5, sigma=0.03), 0)
    np.testing.assert_array_equal(tracker.x, x)
    np.testing.assert_array_equal(tracker.P, P)
    np.testing.assert_array_equal(again.position, e.position)
    assert again.measurement is None
    # reset: back to the home point until the next points start it again.
    tracker.reset()
    e = tracker.step(2 * T, NONE, 1)
    assert not e.tracked
    np.testing.assert_array_equal(e.position, 0.0)
    pts = blob(rng, P0 + 1.0, sigma=0.03)
    e = tracker.step(3 * T, pts, 1)
    assert e.tracked
    assert np.linalg.norm(e.position - pts.mean(axis=0)) < 0.05


def test_bad_arguments() -> None:
    tracker = DogruEKF()
    with pytest.raises(InputError):
        tracker.step(0.0, NONE, -1)
    with pytest.raises(InputError):
        tracker.step(0.0, np.zeros((4, 2)), 1)
    with pytest.raises(ConfigError):
        tracker.initialize(np.array([1.0, np.nan, 0.0]))
    for build in (
        lambda: DogruEKF(period=0.0),
        lambda: CatalanoEKF(search_radius=-1.0),
        lambda: CentroidEKF(measurement_variance=(1.0, 1.0)),  # type: ignore[arg-type]
        lambda: AdaptiveEKF(alpha=1.5),
        lambda: ConstantAccelerationKF(sigma_acc=0.0),
        lambda: CandidateDetector(z_min=5.0, z_max=1.0),
    ):
        with pytest.raises(ConfigError):
            build()


def test_particle_tracker_reports_its_population_variance() -> None:
    noise = eq11_parameters(15.0, 15.0, 0.4, T)
    tracker = ParticleTracker(500, "cv", noise, np.random.default_rng(13), np.zeros(3), 2.0, 2.0)
    e = tracker.step(0.0, blob(np.random.default_rng(14), np.array([0.0, 0.0, 1.0])), 1)
    assert e.variance is not None
    X = tracker.filter.X
    np.testing.assert_allclose(e.variance, ((X[:, :6] - X[:, :6].mean(axis=0)) ** 2).mean(axis=0))
    assert e.measurement is None
