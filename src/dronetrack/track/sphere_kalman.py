"""Gazdag et al.'s sphere-search EKFs behind the Tracker protocol (maths in ``track.kalman``).

DogruEKF ("ekf-dogru"), CatalanoEKF ("ekf-catalano", "ekf-catalano-mod"): Gazdag
et al.'s re-implementations.  Each measures the centroid of the points inside a
sphere around its prediction.  The shared contract (home point, ``initialize``, the
estimate) is ``track.kalman_base``'s.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.geometry.transforms import FloatArray, wrap_angle
from dronetrack.track.kalman import (
    centroid_within,
    ctrv_jacobian,
    ctrv_predict,
    cv_transition,
    dogru_search_radius,
    kf_predict,
    kf_update,
)
from dronetrack.track.kalman_base import _KalmanTracker, _positive

__all__ = ["CatalanoEKF", "DogruEKF"]


class _SphereKalman(_KalmanTracker):
    """Gazdag et al.'s EKF loop: z is the centroid of the points in a sphere around the
    prediction; no points, no update.  The first non-empty frame sets the position to
    the centroid of all its points (velocity 0, P = P0); prediction starts after it."""

    def __init__(
        self,
        period: float,
        home: ArrayLike,
        P0: FloatArray,
        sigma_acc: float,
        sigma_lidar: float,
        tracked_threshold: float,
    ) -> None:
        _positive(sigma_acc=sigma_acc, sigma_lidar=sigma_lidar, tracked_threshold=tracked_threshold)
        super().__init__(period, home, P0)
        # Q = σ_acc² I (a scaled identity, as the reference), R = σ_lidar² I₃
        self.Q = sigma_acc**2 * np.eye(len(P0))
        self.R = sigma_lidar**2 * np.eye(3)
        self.tracked_threshold = tracked_threshold
        self.search_radius = 0.0  # the sphere of the last update attempt [m]

    @property
    def tracked(self) -> bool:
        """P_xx, P_yy and P_zz all below the threshold (the reference compares these
        variances with its search radius parameter, m² against m)."""
        return self.initialised and bool(np.all(np.diag(self.P)[0:3] < self.tracked_threshold))

    def _predict(self) -> None:
        raise NotImplementedError

    def _set_velocity(self, velocity: FloatArray) -> None:
        """The CTRV state starts at rest, as on its own first frame."""

    def _radius(self) -> float:
        raise NotImplementedError

    def _advance(self, t: float, points: FloatArray, steps: int) -> None:
        if not self.initialised:
            if len(points) and self.self_start:
                self._z = points.mean(axis=0)
                self._start(self._z)
            return
        for _ in range(steps):
            self._predict()
        self.search_radius = self._radius()
        z, _ = centroid_within(points, self.x[0:3], self.search_radius)
        if z is not None:
            u = kf_update(self.x, self.P, z, self.H, self.R)
            self.x, self.P, self._z = u.x, u.P, z


class DogruEKF(_SphereKalman):
    """Dogru & Marques' constant-velocity EKF as Gazdag et al. re-implemented it ("type 0").

    State [p, v]; F = cv_transition(T); P0 = I₆; Q = σ_acc² I₆; R = σ_lidar² I₃ (yaml
    values σ_acc 0.05, σ_lidar 0.1).  Search radius r = 3 √max(P_xx, P_yy, P_zz) around
    the prediction, floored at ``min_search_radius`` if given (the outdoor tests use
    no floor); while no points fall inside, P grows every period and the sphere
    widens until it re-captures the target.  ``tracked_threshold`` is the reference's
    KF_Search_Radius (1.5 outdoors).  No deviation from the reference known.
    """

    def __init__(
        self,
        *,
        period: float = 0.1,
        sigma_acc: float = 0.05,
        sigma_lidar: float = 0.1,
        min_search_radius: float | None = None,
        tracked_threshold: float = 1.5,
        home: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        if min_search_radius is not None:
            _positive(min_search_radius=min_search_radius)
        self.min_search_radius = min_search_radius
        self.F = cv_transition(period)
        super().__init__(period, home, np.eye(6), sigma_acc, sigma_lidar, tracked_threshold)

    def _predict(self) -> None:
        self.x, self.P = kf_predict(self.x, self.P, self.F, self.Q)

    def _radius(self) -> float:
        return dogru_search_radius(self.P, self.min_search_radius)


class CatalanoEKF(_SphereKalman):
    """Catalano et al.'s CTRV EKF as Gazdag et al.'s "type 2" re-implementation runs it.

    State [x, y, z, v, ψ, ω]; ``ctrv_predict`` with the predicted state written back
    and F(4,5) = T; z' = z + v T with the *horizontal* speed v (no vertical velocity),
    which is what degrades its vertical accuracy in seed 000's Table IV; kept on
    purpose.  ``exact_jacobian=False`` (default) leaves out ∂z'/∂v as the released
    code does.  P0 = I₆, Q = σ_acc² I₆, R = σ_lidar² I₃.  FIXED search radius: 0.2 m
    ("ekf-catalano", the TIERS code's value) or 1.5 m ("ekf-catalano-mod"); once the
    target leaves the sphere it stays lost until ``reset``/``initialize``.

    The reported velocity is the model's, (v cos ψ, v sin ψ, v): its vertical rate
    is v, as its prediction assumes; its variance is diag(J Σ Jᵀ) with J the
    Jacobian of that velocity with respect to (v, ψ).  The reference does not wrap ψ;
    wrapping it to [−π, π) here changes no prediction (only sin and cos of ψ enter).
    """

    def __init__(
        self,
        *,
        period: float = 0.1,
        search_radius: float = 0.2,
        sigma_acc: float = 0.05,
        sigma_lidar: float = 0.1,
        tracked_threshold: float = 1.5,
        exact_jacobian: bool = False,
        home: ArrayLike = (0.0, 0.0, 0.0),
    ) -> None:
        _positive(search_radius=search_radius)
        self.fixed_radius = search_radius
        self.exact_jacobian = exact_jacobian
        super().__init__(period, home, np.eye(6), sigma_acc, sigma_lidar, tracked_threshold)

    def _predict(self) -> None:
        F = ctrv_jacobian(self.x, self.period, dz_dv=self.exact_jacobian)
        # x⁻ = f(x),  P⁻ = F P Fᵀ + Q
        self.x = ctrv_predict(self.x, self.period)
        self.x[4] = float(wrap_angle(self.x[4]))
        self.P = F @ self.P @ F.T + self.Q

    def _radius(self) -> float:
        return self.fixed_radius

    def _velocity(self) -> tuple[FloatArray, FloatArray]:
        v, psi = self.x[3], self.x[4]
        c, s = np.cos(psi), np.sin(psi)
        # ∂(v cos ψ, v sin ψ, v) / ∂(v, ψ)
        J = np.array([[c, -v * s], [s, v * c], [1.0, 0.0]])
        return np.array([v * c, v * s, v]), np.diag(J @ self.P[3:5, 3:5] @ J.T).copy()
