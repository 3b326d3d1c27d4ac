"""The Kalman-filter family's maths, as pure functions on numpy arrays.

Linear Kalman filter (state x, covariance P, transition F, process noise Q,
measurement z = H x + v with v ~ N(0, R)):

    predict:  x⁻ = F x,                P⁻ = F P Fᵀ + Q
    update:   d = z − H x⁻              (innovation)
              S = H P⁻ Hᵀ + R           (innovation covariance)
              K = P⁻ Hᵀ S⁻¹             (gain, by a linear solve)
              x⁺ = x⁻ + K d,            P⁺ = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ   (Joseph form)
              ε = z − H x⁺              (residual)

Motion models: constant velocity (CV, [p, v]), constant acceleration (CA,
[p, v, a], seed 002 eqs. 1-4), and the CTRV model of Gazdag et al.'s "type 2"
re-implementation of Catalano et al. (state [x, y, z, v, ψ, ω]).

Seed 002's adaptive noise (eqs. 6, 8) and Mahalanobis gate (eq. 9), and the
search spheres of the Dogru / Catalano re-implementations, are here too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dronetrack.geometry.transforms import FloatArray

__all__ = [
    "CHI2_3DOF_99",
    "CTRV_STRAIGHT_LIMIT",
    "KalmanUpdate",
    "adapt_measurement_noise",
    "adapt_process_noise",
    "ca_transition",
    "centroid_within",
    "ctrv_jacobian",
    "ctrv_predict",
    "cv_transition",
    "dogru_search_radius",
    "kf_predict",
    "kf_update",
    "mahalanobis_sq",
    "position_selector",
    "symmetrise",
]

# The 99 % quantile of χ²(3): a 3-D innovation of a consistent filter exceeds it
# one time in a hundred.
CHI2_3DOF_99 = 11.344866730144373
# Below this |ω| [rad/s] the CTRV model uses its straight-line limit (as TIERS' code).
CTRV_STRAIGHT_LIMIT = 1e-3


@dataclass(frozen=True, slots=True)
class KalmanUpdate:
    """The result of one measurement update."""

    x: FloatArray  # x⁺ (n,)
    P: FloatArray  # P⁺ (n, n)
    d: FloatArray  # innovation z − H x⁻ (m,)
    S: FloatArray  # innovation covariance H P⁻ Hᵀ + R (m, m)
    K: FloatArray  # gain P⁻ Hᵀ S⁻¹ (n, m)
    eps: FloatArray  # residual z − H x⁺ (m,)


def symmetrise(A: FloatArray) -> FloatArray:
    """½ (A + Aᵀ): removes the round-off asymmetry of a covariance."""
    out: FloatArray = 0.5 * (A + A.T)
    return out


def kf_predict(
    x: FloatArray, P: FloatArray, F: FloatArray, Q: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """x⁻ = F x;  P⁻ = F P Fᵀ + Q"""
    return F @ x, F @ P @ F.T + Q


def kf_update(
    x: FloatArray, P: FloatArray, z: FloatArray, H: FloatArray, R: FloatArray
) -> KalmanUpdate:
    """The measurement update of the predicted (x⁻, P⁻) with z (see the module docstring)."""
    # d = z − H x⁻
    d = z - H @ x
    PHt = P @ H.T
    # S = H P⁻ Hᵀ + R
    S = H @ PHt + R
    # K = P⁻ Hᵀ S⁻¹  ⇔  Sᵀ Kᵀ = (P⁻ Hᵀ)ᵀ
    K = np.linalg.solve(S.T, PHt.T).T.astype(np.float64, copy=False)
    # x⁺ = x⁻ + K d
    x_post = x + K @ d
    # P⁺ = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ  (the Joseph form: symmetric and positive
    # semi-definite whatever the rounding, where (I − K H) P⁻ can lose both)
    I_KH = np.eye(len(x)) - K @ H
    P_post = symmetrise(I_KH @ P @ I_KH.T + K @ R @ K.T)
    # ε = z − H x⁺
    eps = z - H @ x_post
    return KalmanUpdate(x_post, P_post, d, S, K, eps)


def cv_transition(T: float) -> FloatArray:
    """F of constant velocity for [p, v] (6×6):  p' = p + v T,  v' = v."""
    F = np.eye(6)
    F[0:3, 3:6] = T * np.eye(3)
    return F


def ca_transition(T: float) -> FloatArray:
    """F of constant acceleration for [p, v, a] (9×9), seed 002 eq. (2):

    p' = p + v T + ½ a T²,   v' = v + a T,   a' = a
    """
    F = np.eye(9)
    F[0:3, 3:6] = T * np.eye(3)
    F[0:3, 6:9] = 0.5 * T * T * np.eye(3)
    F[3:6, 6:9] = T * np.eye(3)
    return F


def position_selector(n: int) -> FloatArray:
    """H = [I₃ 0] (3×n): the measurement is the position, seed 002 eq. (4)."""
    H = np.zeros((3, n))
    H[:, 0:3] = np.eye(3)
    return H


def ctrv_predict(x: FloatArray, T: float) -> FloatArray:
    """CTRV step of Gazdag et al.'s type 2 re-implementation of Catalano et al.

    State [x, y, z, v, ψ, ω]; ψ' = ψ + ω T.  For |ω| ≥ 10⁻³ rad/s:

        x' = x + (v/ω) (sin ψ' − sin ψ),   y' = y + (v/ω) (cos ψ − cos ψ')

    else the straight-line limit x' = x + v T cos ψ, y' = y + v T sin ψ.
    v' = v, ω' = ω, and z' = z + v T: the vertical rate is the *horizontal*
    speed v (seed 000 §III: "a CTRV model extended with a constant vertical
    velocity component equal to that of the planar motion").  This is the
    reference's model, kept on purpose: it is what degrades [24]'s vertical
    accuracy in seed 000's Table IV.
    """
    px, py, pz, v, psi, omega = x
    psi_next = psi + omega * T
    out = np.array(x, dtype=np.float64)
    if abs(omega) >= CTRV_STRAIGHT_LIMIT:
        out[0] = px + v / omega * (np.sin(psi_next) - np.sin(psi))
        out[1] = py + v / omega * (np.cos(psi) - np.cos(psi_next))
    else:
        out[0] = px + v * T * np.cos(psi)
        out[1] = py + v * T * np.sin(psi)
    out[2] = pz + v * T
    out[4] = psi_next
    return out


def ctrv_jacobian(x: FloatArray, T: float, dz_dv: bool = True) -> FloatArray:
    """F = ∂ ctrv_predict / ∂x (6×6), with F(4,5) = ∂ψ'/∂ω = T as in the type 2 code.

    Turning (|ω| ≥ 10⁻³), with Δs = sin ψ' − sin ψ and Δc = cos ψ − cos ψ':

        ∂x'/∂v = Δs/ω,   ∂x'/∂ψ = (v/ω)(cos ψ' − cos ψ),   ∂x'/∂ω = (v/ω) T cos ψ' − (v/ω²) Δs
        ∂y'/∂v = Δc/ω,   ∂y'/∂ψ = (v/ω)(sin ψ' − sin ψ),   ∂y'/∂ω = (v/ω) T sin ψ' − (v/ω²) Δc

    Straight (|ω| < 10⁻³): the ω → 0 limits, ∂x'/∂v = T cos ψ, ∂x'/∂ψ = −v T sin ψ,
    ∂x'/∂ω = −½ v T² sin ψ (and y alike with cos → sin, sin → −cos).  The ω column
    is the limit of the turning model, not the derivative of the straight branch
    (which ignores ω), so the gain still reaches ω on straight flight.

    ``dz_dv``: the ∂z'/∂v = T term of z' = z + v T.  The released type 2 code has
    no such term (``dz_dv=False`` reproduces it); the exact Jacobian has it.
    """
    _, _, _, v, psi, omega = x
    psi_next = psi + omega * T
    F = np.eye(6)
    if abs(omega) >= CTRV_STRAIGHT_LIMIT:
        ds = np.sin(psi_next) - np.sin(psi)
        dc = np.cos(psi) - np.cos(psi_next)
        F[0, 3] = ds / omega
        F[0, 4] = v / omega * (np.cos(psi_next) - np.cos(psi))
        F[0, 5] = v / omega * T * np.cos(psi_next) - v / omega**2 * ds
        F[1, 3] = dc / omega
        F[1, 4] = v / omega * (np.sin(psi_next) - np.sin(psi))
        F[1, 5] = v / omega * T * np.sin(psi_next) - v / omega**2 * dc
    else:
        F[0, 3] = T * np.cos(psi)
        F[0, 4] = -v * T * np.sin(psi)
        F[0, 5] = -0.5 * v * T * T * np.sin(psi)
        F[1, 3] = T * np.sin(psi)
        F[1, 4] = v * T * np.cos(psi)
        F[1, 5] = 0.5 * v * T * T * np.cos(psi)
    if dz_dv:
        F[2, 3] = T
    F[4, 5] = T
    return F


def adapt_process_noise(Q: FloatArray, K: FloatArray, d: FloatArray, alpha: float) -> FloatArray:
    """Seed 002 eq. (6):  Q_k = α Q_{k−1} + (1 − α) K_k d_k d_kᵀ K_kᵀ"""
    Kd = K @ d
    out: FloatArray = alpha * Q + (1.0 - alpha) * np.outer(Kd, Kd)
    return out


def adapt_measurement_noise(
    R: FloatArray, eps: FloatArray, H: FloatArray, P_pred: FloatArray, beta: float
) -> FloatArray:
    """Seed 002 eq. (8), as printed (with the *predicted* P⁻):

    R_k = β R_{k−1} + (1 − β) (ε_k ε_kᵀ + H P⁻_k Hᵀ)

    (Akhlaghi et al.'s covariance matching, which seed 002 cites, has H P⁺ Hᵀ there.)
    """
    out: FloatArray = beta * R + (1.0 - beta) * (np.outer(eps, eps) + symmetrise(H @ P_pred @ H.T))
    return out


def mahalanobis_sq(d: FloatArray, S: FloatArray) -> float:
    """Seed 002 eq. (9):  D_M = dᵀ S⁻¹ d  (a squared distance, compared with τ)."""
    return float(d @ np.linalg.solve(S, d))


def dogru_search_radius(P: FloatArray, floor: float | None = None) -> float:
    """r = 3 √max(P_xx, P_yy, P_zz), then r = max(r, floor) when a floor is given [m]."""
    r = 3.0 * float(np.sqrt(max(P[0, 0], P[1, 1], P[2, 2])))
    return r if floor is None else max(r, floor)


def centroid_within(
    points: FloatArray, center: FloatArray, radius: float
) -> tuple[FloatArray | None, int]:
    """The centroid of the points within ``radius`` of ``center`` (|p − c| ≤ r) and their count;
    (None, 0) when the sphere is empty."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    inside = np.sum((pts - center) ** 2, axis=1) <= radius * radius
    n = int(np.count_nonzero(inside))
    if n == 0:
        return None, 0
    centroid: FloatArray = pts[inside].mean(axis=0)
    return centroid, n
