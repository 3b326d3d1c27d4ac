"""Kalman-family trackers fed by detected clusters (maths in ``track.kalman``).

The injected detector (``detect.candidates.CandidateDetector``) turns a frame's
foreground points into ``Detections``; the filters measure their centroids.
CentroidEKF ("ekf-cv"): seed 003; ConstantAccelerationKF ("kf-ca"), AdaptiveEKF
("aekf-ca"): seed 002.  The shared contract (home point, ``initialize``, the
estimate) is ``track.kalman_base``'s.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.detect.candidates import SEED002_DETECTOR, SEED003_DETECTOR, CandidateDetector
from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.track.kalman import (
    CHI2_3DOF_99,
    adapt_measurement_noise,
    adapt_process_noise,
    ca_transition,
    cv_transition,
    kf_predict,
    kf_update,
    mahalanobis_sq,
    symmetrise,
)
from dronetrack.track.kalman_base import _KalmanTracker, _positive

__all__ = ["AdaptiveEKF", "CentroidEKF", "ConstantAccelerationKF"]


class _TimedKalman(_KalmanTracker):
    """A tracker on detected clusters that counts the time since its last fix; lost
    after ``patience`` seconds without one, or when ``_overdue`` says so."""

    def __init__(self, period: float, home: ArrayLike, P0: FloatArray, patience: float) -> None:
        _positive(lost_after=patience)
        self.patience = patience
        super().__init__(period, home, P0)

    def reset(self) -> None:
        super().reset()
        self.lost = False
        self._t_last: float | None = None  # set by the first step after a start

    def _start(self, position: FloatArray) -> None:
        super()._start(position)
        self.lost = False
        self._t_last = None

    @property
    def tracked(self) -> bool:
        return self.initialised and not self.lost

    def _check_lost(self, t: float) -> None:
        if not self.initialised:
            return
        if self._z is not None or self._t_last is None:
            self._t_last = t
        # Recomputed every frame: only a fix (or a restart) brings a lost track back.
        self.lost = t - self._t_last > self.patience or self._overdue()

    def _overdue(self) -> bool:
        return False

    def _fixed(self, t: float) -> None:
        self._check_lost(t)  # a start is a fix: not lost, the clock from t


SEED003_P0 = (1.0, 1.0, 1.0, 16.0, 16.0, 16.0)


class CentroidEKF(_TimedKalman):
    """Seed 003's EKF (§4.3): constant velocity on cluster centroids.

    State [p, v]; F = cv_transition(T); Q = 0.01 I₆; R = diag(1, 1, 0.2);
    P0 = diag(1, 1, 1, 16, 16, 16).  The thesis prints R = diag(1², 1², 0.2²) and
    P0 = diag(1², 1², 0.2², 4², 4², 4²), but its text reads "variances of 1 … and 0.2
    for the z position" and "1 for the position states": the issue's values (the
    text's) are used.  z is the centroid of the detected cluster nearest the
    prediction (no gate), the largest one before the first fix (``detector``,
    default ``SEED003_DETECTOR``).  Lost when max(P_xx, P_yy, P_zz) > ``cov_threshold``
    [m²] or no detection for ``lost_after_s``; the next centroid (the largest
    cluster) then re-initialises it (velocity 0, P = P0).  Until then the prediction
    goes on (the thesis does not say; this is the filter's own behaviour).
    """

    def __init__(
        self,
        *,
        period: float = 0.1,
        process_variance: float = 0.01,
        measurement_variance: tuple[float, float, float] = (1.0, 1.0, 0.2),
        initial_variance: tuple[float, ...] = SEED003_P0,
        cov_threshold: float = 25.0,
        lost_after_s: float = 2.0,
        detector: CandidateDetector = SEED003_DETECTOR,
        home: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        R = np.asarray(measurement_variance, dtype=np.float64)
        P0 = np.asarray(initial_variance, dtype=np.float64)
        if R.shape != (3,) or P0.shape != (6,) or np.any(R <= 0) or np.any(P0 <= 0):
            raise ConfigError("need 3 positive measurement and 6 positive initial variances")
        _positive(process_variance=process_variance, cov_threshold=cov_threshold)
        self.F = cv_transition(period)
        self.Q = process_variance * np.eye(6)
        self.R = np.diag(R)
        self.cov_threshold = cov_threshold
        self.detector = detector
        super().__init__(period, home, np.diag(P0), lost_after_s)

    def _overdue(self) -> bool:
        return bool(np.diag(self.P)[0:3].max() > self.cov_threshold)

    def _advance(self, t: float, points: FloatArray, steps: int) -> None:
        found = self.detector(points)
        if self.initialised:
            for _ in range(steps):
                self.x, self.P = kf_predict(self.x, self.P, self.F, self.Q)
        if len(found) and not self.tracked and self.self_start:
            self._z = found.centroids[found.largest()]
            self._start(self._z)
        elif len(found) and self.tracked:
            distance = [float(np.sum((c - self.x[0:3]) ** 2)) for c in found.centroids]
            self._z = found.centroids[int(np.argmin(distance))]
            u = kf_update(self.x, self.P, self._z, self.H, self.R)
            self.x, self.P = u.x, u.P
        self._check_lost(t)


class ConstantAccelerationKF(_TimedKalman):
    """Seed 002's "Fixed CA-KF" baseline: the CA model (eqs. 1-4) with fixed Q and R.

    Candidates and gate as AdaptiveEKF (same detector, eq. 9 with τ), but Q and R
    never adapt and nothing re-initialises it: through gaps it extrapolates with
    the last acceleration for as long as the gap lasts, the divergence seed 002
    reports (§4.2, Fig. 4); the next candidate inside its (grown) gate updates it.
    ``t_occ`` only sets the flag: ``tracked`` is False after t_occ without an
    accepted measurement.  Defaults and their reasons: see AdaptiveEKF.
    """

    adaptive = False  # eqs. (6) and (8)
    reinitialises = False  # from the largest candidate once lost

    def __init__(
        self,
        *,
        period: float = 0.1,
        sigma_pos: float = 0.05,
        sigma_vel: float = 0.1,
        sigma_acc: float = 0.5,
        sigma_lidar: float = 0.1,
        initial_sigmas: tuple[float, float, float] = (1.0, 5.0, 5.0),
        gate: float = CHI2_3DOF_99,
        t_occ: float = 1.0,
        detector: CandidateDetector = SEED002_DETECTOR,
        home: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        _positive(
            sigma_pos=sigma_pos,
            sigma_vel=sigma_vel,
            sigma_acc=sigma_acc,
            sigma_lidar=sigma_lidar,
            gate=gate,
            initial_sigmas=min(initial_sigmas),
        )
        self.F = ca_transition(period)
        # Q₀ = diag(σ_p² I₃, σ_v² I₃, σ_a² I₃);  R₀ = σ_lidar² I₃
        self.Q0 = np.diag(np.repeat([sigma_pos**2, sigma_vel**2, sigma_acc**2], 3))
        self.R0 = sigma_lidar**2 * np.eye(3)
        self.gate = gate
        self.detector = detector
        self.distances: list[float] = []  # D_M of this frame's candidates
        P0 = np.diag(np.repeat(np.square(np.asarray(initial_sigmas, dtype=np.float64)), 3))
        super().__init__(period, home, P0, t_occ)

    def reset(self) -> None:
        super().reset()
        self.Q, self.R = self.Q0.copy(), self.R0.copy()

    def _start(self, position: FloatArray) -> None:
        super()._start(position)
        self.Q, self.R = self.Q0.copy(), self.R0.copy()

    def _advance(self, t: float, points: FloatArray, steps: int) -> None:
        found = self.detector(points)
        self.distances = []
        # Every period; with no accepted measurement below this is eq. (10).  A track
        # the filter has ended (lost, and waiting to be re-initialised) holds its
        # last state instead of extrapolating.
        if self.initialised and not (self.lost and self.reinitialises):
            for _ in range(steps):
                self.x, self.P = kf_predict(self.x, self.P, self.F, self.Q)
        ended = not self.initialised or (self.lost and self.reinitialises)
        if len(found) and ended and self.self_start:
            self._z = found.centroids[found.largest()]
            self._start(self._z)
        elif len(found) and not ended:
            # eq. (9): D_M = dᵀ S⁻¹ d, S = H P⁻ Hᵀ + R; the nearest is accepted if D_M < τ
            S = symmetrise(self.H @ self.P @ self.H.T) + self.R
            self.distances = [mahalanobis_sq(c - self.x[0:3], S) for c in found.centroids]
            best = int(np.argmin(self.distances))
            if self.distances[best] < self.gate:
                self._z = found.centroids[best]
                u = kf_update(self.x, self.P, self._z, self.H, self.R)
                if self.adaptive:
                    self.Q = adapt_process_noise(self.Q, u.K, u.d, self.alpha)
                    self.R = adapt_measurement_noise(self.R, u.eps, self.H, self.P, self.beta)
                self.x, self.P = u.x, u.P
        self._check_lost(t)

    alpha = 1.0  # eq. (6) forgetting factor (1: Q fixed)
    beta = 1.0  # eq. (8) weighting factor (1: R fixed)


class AdaptiveEKF(ConstantAccelerationKF):
    """Seed 002's adaptive CA filter (CAEKF / AEKF, Khosravi et al.).

    CA model (eqs. 1-4); Q adapted by eq. (6) with forgetting factor α, R by eq. (8)
    with β (as printed, with H P⁻ Hᵀ); Mahalanobis gate, eq. (9), τ = χ²₃(0.99)
    = 11.345; prediction only through occlusions (eq. 10); after ``t_occ`` without an
    accepted measurement the track is lost and the next candidate (the largest)
    re-initialises it (velocity and acceleration 0, P0, Q0, R0).  Candidates come
    from ``CandidateDetector`` (Algorithm 1 and a size check); the geometric check is
    the largest principal extent only (seed 002 also names aspect ratio and
    planarity, without thresholds).

    Seed 002 gives no numbers for α, β, Q0, R0, P0 or t_occ.  Chosen here:
    α = β = 0.98, a memory of 1/(1 − α) = 50 updates (5 s at 10 Hz): the rank-one
    terms K d dᵀ Kᵀ and ε εᵀ then fix each entry to ≈ √(2(1 − α)/(1 + α)) = 14 %
    (0.9 would leave 32 %), and a change of flight regime still shows within
    seconds.  Q0 = diag(σ_p², σ_v², σ_a²) per axis, σ_p = 0.05 m (half a voxel),
    σ_v = 0.1 m/s (1 m/s² over a period), σ_a = 0.5 m/s² (a random walk reaching
    ≈ 1.6 m/s² in 1 s, a small drone's manoeuvre).  R0 = σ_lidar² I₃, σ_lidar = 0.1 m
    as the reference yamls (and the voxel size).  P0 = diag(1 m², (5 m/s)²,
    (5 m/s²)²): 1 m² as the other baselines; 5 = a third of seed 000's 15 m/s and
    15 m/s² drone.  t_occ = 1 s: a 1 m/s² acceleration error extrapolates to
    ½ a t² = 0.5 m, about a drone's size, in that time.  Once lost, the track is
    ended: it holds its last state, instead of extrapolating the CA model without
    bound, until a candidate re-initialises it (seed 002's track management).
    """

    adaptive = True
    reinitialises = True

    def __init__(
        self,
        *,
        period: float = 0.1,
        alpha: float = 0.98,
        beta: float = 0.98,
        sigma_pos: float = 0.05,
        sigma_vel: float = 0.1,
        sigma_acc: float = 0.5,
        sigma_lidar: float = 0.1,
        initial_sigmas: tuple[float, float, float] = (1.0, 5.0, 5.0),
        gate: float = CHI2_3DOF_99,
        t_occ: float = 1.0,
        detector: CandidateDetector = SEED002_DETECTOR,
        home: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        if not (0.0 <= alpha <= 1.0 and 0.0 <= beta <= 1.0):
            raise ConfigError(f"alpha and beta must be in [0, 1], got {alpha}, {beta}")
        self.alpha, self.beta = alpha, beta
        super().__init__(
            period=period,
            sigma_pos=sigma_pos,
            sigma_vel=sigma_vel,
            sigma_acc=sigma_acc,
            sigma_lidar=sigma_lidar,
            initial_sigmas=initial_sigmas,
            gate=gate,
            t_occ=t_occ,
            detector=detector,
            home=home,
        )
