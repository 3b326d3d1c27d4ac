"""A bank of constant-velocity Kalman filters, one per track, stepped together: the
state, gates and costs of ``track.multi``'s tracks.

Each track is a constant-velocity Kalman filter on x = [p, v] (world frame):

    predict over Δt:  x⁻ = F x,  P⁻ = F P Fᵀ + Q,
        F = [[I, Δt I], [0, I]],
        Q = σ_a² [[Δt⁴/4 I, Δt³/2 I], [Δt³/2 I, Δt² I]]      (white acceleration σ_a)

    measurement: a cluster's centroid c = p + w,  w ~ N(0, R),
        R = Σ_c + σ₀² I      (Σ_c the cluster's point covariance: where in a large or
                              sparsely sampled object its centroid lands; σ₀ a floor)

Every frame all tracks are predicted to the frame's end and associated with all of the
frame's clusters (global nearest neighbour: scipy's ``linear_sum_assignment``) on the
cost

    J = d² + ln|S|,   d² = (c − H x⁻)ᵀ S⁻¹ (c − H x⁻),   S = H P⁻ Hᵀ + R

(the negative log-likelihood of the pair, up to a constant), over the pairs inside
both gates:

    d² ≤ γ                       (Mahalanobis gate, γ = χ²₃ quantile)
    |c − p| ≤ v_max Δt_u + g      (speed gate from the track's last update)
"""

from __future__ import annotations

from collections.abc import Callable

import numba as nb
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Detections

__all__ = [
    "INFEASIBLE",
    "Floor",
    "associate",
    "cv_predict",
    "cv_process_noise",
    "cv_update",
    "gate_costs",
    "ground_bound",
    "measurement_noise",
    "on_or_above",
]

INFEASIBLE = 1e12  # an assignment cost no pair inside the gates can reach
Floor = Callable[[FloatArray], FloatArray]  # points (K, 2) → the ground's height (NaN: unknown)


def cv_process_noise(dt: FloatArray, sigma_a: float) -> FloatArray:
    """Q (K, 6, 6) of white acceleration σ_a over each Δt (K,):
    σ_a² [[Δt⁴/4 I, Δt³/2 I], [Δt³/2 I, Δt² I]]."""
    dt = np.asarray(dt, dtype=np.float64)
    q = sigma_a**2
    eye = np.eye(3)
    Q = np.zeros((len(dt), 6, 6))
    Q[:, :3, :3] = q * (dt**4 / 4.0)[:, None, None] * eye
    Q[:, :3, 3:] = Q[:, 3:, :3] = q * (dt**3 / 2.0)[:, None, None] * eye
    Q[:, 3:, 3:] = q * (dt**2)[:, None, None] * eye
    return Q


def cv_predict(
    x: FloatArray, P: FloatArray, dt: FloatArray, sigma_a: float
) -> tuple[FloatArray, FloatArray]:
    """Every track's (x⁻, P⁻) after its own Δt (K,): x⁻ = F x, P⁻ = F P Fᵀ + Q
    (``_predict_bank``)."""
    x_pred = np.array(x, dtype=np.float64)
    P_pred = np.array(P, dtype=np.float64)
    _predict_bank(x_pred, P_pred, np.array(dt, dtype=np.float64), float(sigma_a) ** 2)
    return x_pred, P_pred


@nb.njit(cache=True)
def _predict_bank(x: FloatArray, P: FloatArray, dt: FloatArray, q: float) -> None:
    """In place, per track k with Δt = dt[k], by blocks (F = [[I, Δt I], [0, I]],
    P = [[A, B], [Bᵀ, C]], Q = q [[Δt⁴/4 I, Δt³/2 I], [Δt³/2 I, Δt² I]]):

        p⁻ = p + Δt v,   v⁻ = v
        A⁻ = A + Δt (B + Bᵀ) + Δt² C + Q_pp,   B⁻ = B + Δt C + Q_pv,   C⁻ = C + Q_vv
    """
    for k in range(x.shape[0]):
        d = dt[k]
        if d == 0.0:
            continue
        for a in range(3):
            x[k, a] += d * x[k, 3 + a]
        A = np.empty((3, 3))
        B = np.empty((3, 3))
        for a in range(3):
            for b in range(3):
                bab = P[k, a, 3 + b]
                bba = P[k, b, 3 + a]
                c = P[k, 3 + a, 3 + b]
                A[a, b] = P[k, a, b] + d * (bab + bba) + d * d * c
                B[a, b] = bab + d * c
        for a in range(3):
            A[a, a] += q * d**4 / 4.0
            B[a, a] += q * d**3 / 2.0
            P[k, 3 + a, 3 + a] += q * d * d
        for a in range(3):
            for b in range(3):
                P[k, a, b] = 0.5 * (A[a, b] + A[b, a])
                P[k, a, 3 + b] = B[a, b]
                P[k, 3 + b, a] = B[a, b]
        for a in range(3):  # C stays symmetric: the same q Δt² on its diagonal
            for b in range(a + 1, 3):
                c = 0.5 * (P[k, 3 + a, 3 + b] + P[k, 3 + b, 3 + a])
                P[k, 3 + a, 3 + b] = c
                P[k, 3 + b, 3 + a] = c


@nb.njit(cache=True)
def _inverse3(S: FloatArray) -> tuple[FloatArray, float]:
    """S⁻¹ and det S of a 3 × 3 matrix (the adjugate over the determinant)."""
    inv = np.empty((3, 3))
    inv[0, 0] = S[1, 1] * S[2, 2] - S[1, 2] * S[2, 1]
    inv[0, 1] = S[0, 2] * S[2, 1] - S[0, 1] * S[2, 2]
    inv[0, 2] = S[0, 1] * S[1, 2] - S[0, 2] * S[1, 1]
    inv[1, 0] = S[1, 2] * S[2, 0] - S[1, 0] * S[2, 2]
    inv[1, 1] = S[0, 0] * S[2, 2] - S[0, 2] * S[2, 0]
    inv[1, 2] = S[0, 2] * S[1, 0] - S[0, 0] * S[1, 2]
    inv[2, 0] = S[1, 0] * S[2, 1] - S[1, 1] * S[2, 0]
    inv[2, 1] = S[0, 1] * S[2, 0] - S[0, 0] * S[2, 1]
    inv[2, 2] = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
    det = S[0, 0] * inv[0, 0] + S[0, 1] * inv[1, 0] + S[0, 2] * inv[2, 0]
    for a in range(3):
        for b in range(3):
            inv[a, b] /= det
    return inv, det


def cv_update(
    x: FloatArray, P: FloatArray, z: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The position update of K tracks at once (``_update_bank``)."""
    x_post = np.array(x, dtype=np.float64)
    P_post = np.array(P, dtype=np.float64)
    _update_bank(x_post, P_post, np.array(z, dtype=np.float64), np.array(R, dtype=np.float64))
    return x_post, P_post


@nb.njit(cache=True)
def _update_bank(x: FloatArray, P: FloatArray, z: FloatArray, R: FloatArray) -> None:
    """In place, track k with measurement z[k] of noise R[k] (H = [I 0]; Joseph form,
    as ``track.kalman.kf_update``):

        S = P_pp + R,  K = P Hᵀ S⁻¹,  x⁺ = x + K (z − p),
        P⁺ = (I − K H) P (I − K H)ᵀ + K R Kᵀ
    """
    for k in range(x.shape[0]):
        Pk = np.ascontiguousarray(P[k])
        Rk = np.ascontiguousarray(R[k])
        Sinv, _ = _inverse3(Pk[:3, :3] + Rk)
        G = np.ascontiguousarray(Pk[:, :3]) @ Sinv  # K (6, 3)
        nu = z[k] - x[k, :3]
        x[k] += G @ nu
        I_KH = np.eye(6)
        I_KH[:, :3] -= G
        Pn = I_KH @ Pk @ I_KH.T + G @ Rk @ G.T
        P[k] = 0.5 * (Pn + Pn.T)


def gate_costs(
    x_pred: FloatArray,
    P_pred: FloatArray,
    last: FloatArray,
    reach: FloatArray,
    z: FloatArray,
    R: FloatArray,
    gate: float,
) -> FloatArray:
    """The assignment cost J = d² + ln|S| of every (track k, cluster j), (K, D), with
    ``INFEASIBLE`` outside the gates: d² > γ, or |c_j − p_k| > reach_k where p_k is
    ``last`` (the track's last updated position) and reach_k = v_max Δt_u + g
    (``_gate_kernel``)."""
    # copies: writeable C arrays, the one type the kernel is compiled for (the
    # clusters' centroids are read-only)
    return _gate_kernel(
        np.array(x_pred, dtype=np.float64),
        np.array(P_pred, dtype=np.float64),
        np.array(last, dtype=np.float64),
        np.array(reach, dtype=np.float64),
        np.array(z, dtype=np.float64).reshape(-1, 3),
        np.array(R, dtype=np.float64).reshape(-1, 3, 3),
        float(gate),
    )


@nb.njit(cache=True)
def _gate_kernel(
    x: FloatArray,
    P: FloatArray,
    last: FloatArray,
    reach: FloatArray,
    z: FloatArray,
    R: FloatArray,
    gate: float,
) -> FloatArray:
    """S_kj = P_pp,k + R_j,  ν = c_j − p⁻_k,  d² = νᵀ S⁻¹ ν;  J = d² + ln|S| inside both
    gates, ``INFEASIBLE`` outside."""
    K, D = x.shape[0], z.shape[0]
    cost = np.full((K, D), INFEASIBLE)
    for k in range(K):
        for j in range(D):
            moved = 0.0
            for a in range(3):
                moved += (z[j, a] - last[k, a]) ** 2
            if moved > reach[k] ** 2:
                continue
            Sinv, det = _inverse3(P[k, :3, :3] + R[j])
            d2 = 0.0
            for a in range(3):
                for b in range(3):
                    d2 += (z[j, a] - x[k, a]) * Sinv[a, b] * (z[j, b] - x[k, b])
            if d2 <= gate and det > 0.0:
                cost[k, j] = d2 + np.log(det)
    return cost


def associate(cost: FloatArray) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The feasible pairs (rows, cols) of the minimum-cost assignment of ``cost``."""
    if cost.size == 0:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    rows, cols = linear_sum_assignment(cost)
    keep = cost[rows, cols] < INFEASIBLE
    return rows[keep], cols[keep]


def measurement_noise(found: Detections, sigma_meas: float) -> FloatArray:
    """R_j = Σ_j + σ₀² I for each cluster j (D, 3, 3)."""
    return np.asarray(found.covariances, dtype=np.float64) + sigma_meas**2 * np.eye(3)


def on_or_above(x: FloatArray, ground: FloatArray) -> FloatArray:
    """The states ``x`` (K, 6) = [p, v] kept on or above the ``ground``'s height under
    each (K,) [m; NaN: unknown, no bound]: a state below it is projected onto it,
    z ← g, and no longer sinks there, v_z ← max(v_z, 0).

    The ground returns the sensor's pulses, so nothing it tracks is below it; a track
    coasting on a velocity that points down (a far fragment's centroid jitter gives
    metres a second) would otherwise sink tens of metres below it within its coasting
    time.  The projection of the estimate onto z ≥ g with the identity weight (z alone
    moves, not the states correlated with it), the covariance kept, and v_z clipped.
    """
    out = np.array(x, dtype=np.float64, copy=True)
    with np.errstate(invalid="ignore"):
        below = out[:, 2] < ground  # NaN compares False
    out[below, 2] = ground[below]
    out[below, 5] = np.maximum(out[below, 5], 0.0)
    return out


def ground_bound(x: FloatArray, p_update: FloatArray, floor: Floor) -> FloatArray:
    """(K,) the height each track keeps on or above: the ground under it, g, where
    its last fix z_u was on or above it; NaN (no bound) where the ground is not
    known, where its position is not finite, and where it was measured lower
    (z_u < g: the ground learnt there is a crown or a wall top that hid the real
    one, and a measured track is neither lifted nor held at its fix)."""
    xy = x[:, :2]
    finite = np.isfinite(xy).all(axis=1)
    ground = np.full(len(x), np.nan)
    if finite.any():
        g = np.asarray(floor(xy[finite]), dtype=np.float64).reshape(-1)
        if len(g) != int(finite.sum()):
            raise InputError(f"floor: {len(g)} heights for {int(finite.sum())} points")
        ground[finite] = g
    with np.errstate(invalid="ignore"):
        return np.where(ground <= p_update[:, 2], ground, np.nan)
