"""Every object a track: an identity, a state, a covariance and a life for each object
the detect stage confirms, beside the one target the turret's tracker is locked on.

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

A track unseen for longer than ``stale_s`` (0.3 s: the detect stage's N − M + 1 = 3
frames) is matched only with a confirmed candidate's cluster, or a cluster within
``stale_gate_m`` (5 m) of its prediction: its gate has grown with
its covariance (σ ≈ 6 m after 1.5 s at σ_a = 15 m/s²), and a lone false return in it
would otherwise carry it off (``default`` seed 0: a duplicate of the drone's track
jumped 24 m to a stray return and wandered 60 m away for 4 s, holding the drone's
hover).  A matched track is updated (Joseph form, ``track.kalman``).  A track is **born** on
a confirmed candidate of the detect stage (M-of-N, ``detect.tentative``) whose
cluster no track took and lies farther than ``merge_m`` from every track (closer, it
is a piece of that track's object: see below); it starts at the candidate's centroid
with the tentative track's velocity.  A track **dies** ``coast_s`` after its last
update, or when it has followed another track's object: two tracks whose positions
have stayed within ``merge_m`` of each other for ``merge_s`` are one object, as the
clustering joins any two returns closer than its ε (``merge_m`` = ε in a run), so two
objects that close give one cluster, never two.  The one with fewer updates ends (of
equals, the younger), and the object keeps the identity it had longest.  (On ``outdoor-clutter``
a drone 60 m out, its cluster now and then split or missed, kept two tracks 0.5-0.9 m
apart for 20 s, which took its cluster in turn.)  ``merge_s`` (1 s) keeps apart two
objects that cross: at 2 m/s between them they are within 1 m of each other for
1 s at most.  Identities are consecutive integers from 1, never reused in a run.

**The lock carries an identity.**  The turret's tracker follows one object with its
own filter (``note_lock``: after each frame its estimate and the track it holds, or,
while it stays locked, the one it held last).
When the held track misses a frame's cluster and a track would be born within
``SAME_TARGET_M`` (2 m) of the lock's estimate predicted to the frame, the held track
takes that cluster instead: it restarts there, as a birth would, but keeps its
identity and its life (a hover seen earlier says it is a drone).  A Kalman track on a
drone 60 m out with few returns can lose it for a frame while the particle filter
holds it (``outdoor-clutter`` seed 0: a new identity each time, classed bird, as a
drone flying fast that never hovered).

Why global nearest neighbour and not JPDA: the candidates of one frame lie metres
apart at the ranges we track (a drone's returns form one cluster within ε = 1 m), so
a gate rarely holds two clusters; where it does (two drones crossing), the assignment
keeps each on the cluster its prediction points at.  JPDA's blending would pull both
estimates to the midpoint of the two clusters at the crossing.  See the README for
the figures measured on the two-drone scenarios.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment
from scipy.stats import chi2

from dronetrack.detect.lock import SAME_TARGET_M
from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Candidates, Detections, TrackEstimate, Tracks

LockNote = tuple[int, FloatArray, FloatArray, float]  # held id, estimate p, v, its time

__all__ = [
    "MultiTargetTracker",
    "TrackSettings",
    "associate",
    "close_pairs",
    "cv_predict",
    "cv_process_noise",
    "cv_update",
    "gate_costs",
]

_INFEASIBLE = 1e12  # an assignment cost no pair inside the gates can reach


@dataclass(frozen=True, slots=True)
class TrackSettings:
    """The track layer's parameters (SI units; see the module docstring).

    sigma_acc: σ_a; sigma_meas: σ₀; gate_probability: the χ²₃ quantile of the
    Mahalanobis gate; v_max, gate_m: the speed gate (as the detect stage's);
    coast_s: the longest a track lives without an update; stale_s: after this long
    without one, only a confirmed candidate's cluster updates it; birth_sigma_v: the
    velocity's σ at birth; max_tracks: the most tracks kept (the longest unseen die
    first; of equals, the least updated); merge_m, merge_s: two tracks this close for
    this long follow one object.
    """

    sigma_acc: float = 5.0
    sigma_meas: float = 0.2
    gate_probability: float = 0.9999
    v_max: float = 15.0
    gate_m: float = 1.0
    coast_s: float = 5.0
    stale_s: float = 0.3
    stale_gate_m: float = 5.0
    birth_sigma_v: float = 5.0
    max_tracks: int = 64
    merge_m: float = 1.0
    merge_s: float = 1.0

    def __post_init__(self) -> None:
        for name in ("sigma_acc", "sigma_meas", "v_max", "coast_s", "stale_s", "birth_sigma_v"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"tracks: {name} must be positive, got {getattr(self, name)}")
        if not 0.0 < self.gate_probability < 1.0:
            raise ConfigError(
                f"tracks: gate_probability must be in (0, 1), got {self.gate_probability}"
            )
        if self.merge_m < 0 or self.merge_s < 0:
            raise ConfigError(
                f"tracks: need merge_m ≥ 0 and merge_s ≥ 0, got {self.merge_m}, {self.merge_s}"
            )
        if self.gate_m < 0 or self.max_tracks < 1:
            raise ConfigError(
                f"tracks: need gate_m ≥ 0 and max_tracks ≥ 1, got {self.gate_m}, {self.max_tracks}"
            )

    @property
    def gate(self) -> float:
        """γ: the Mahalanobis gate, χ²₃ at ``gate_probability``."""
        return float(chi2.ppf(self.gate_probability, 3))


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
    ``_INFEASIBLE`` outside the gates: d² > γ, or |c_j − p_k| > reach_k where p_k is
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
    gates, ``_INFEASIBLE`` outside."""
    K, D = x.shape[0], z.shape[0]
    cost = np.full((K, D), _INFEASIBLE)
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


def close_pairs(p: FloatArray, radius: float) -> NDArray[np.intp]:
    """(M, 2) the index pairs i < j of positions ``p`` (K, 3) within ``radius`` [m]."""
    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)
    i, j = np.nonzero(np.triu(d <= radius, k=1))
    return np.column_stack([i, j]).astype(np.intp)


def associate(cost: FloatArray) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The feasible pairs (rows, cols) of the minimum-cost assignment of ``cost``."""
    if cost.size == 0:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    rows, cols = linear_sum_assignment(cost)
    keep = cost[rows, cols] < _INFEASIBLE
    return rows[keep], cols[keep]


def measurement_noise(found: Detections, sigma_meas: float) -> FloatArray:
    """R_j = Σ_j + σ₀² I for each cluster j (D, 3, 3)."""
    return np.asarray(found.covariances, dtype=np.float64) + sigma_meas**2 * np.eye(3)


def _cluster_of(candidates: Candidates, found: Detections) -> NDArray[np.intp]:
    """The index of the cluster each confirmed candidate is (its centroid this frame),
    −1 for none: as the detect stage recorded it, else found by its position."""
    if len(candidates) == 0 or len(found) == 0:
        return np.full(len(candidates), -1, dtype=np.intp)
    if np.all(candidates.clusters >= 0):
        return candidates.clusters.astype(np.intp)
    gap = np.linalg.norm(candidates.positions[:, None, :] - found.centroids[None, :, :], axis=2)
    nearest = np.argmin(gap, axis=1)
    return np.where(gap[np.arange(len(candidates)), nearest] <= 1e-9, nearest, -1)


class MultiTargetTracker:
    """The tracks of every confirmed object (see the module docstring); ``step`` once per
    tracking frame with its clusters and confirmed candidates."""

    def __init__(self, settings: TrackSettings = TrackSettings()) -> None:
        self.settings = settings
        self._gate = settings.gate
        self._next_id = 1
        self._together: dict[tuple[int, int], float] = {}  # (id, id) → close since [s]
        self._lock: LockNote | None = None
        self.reset()

    def reset(self) -> None:
        """Forget every track (identities go on counting)."""
        self.ids = np.empty(0, dtype=np.int64)
        self.x = np.empty((0, 6))  # state [p, v] at time t [m, m/s]
        self.P = np.empty((0, 6, 6))
        self.t = np.empty(0)  # time of the state [s]
        self.born = np.empty(0)  # birth time [s]
        self.t_update = np.empty(0)  # time of the last update [s]
        self.p_update = np.empty((0, 3))  # position after the last update [m]
        self.updates = np.empty(0, dtype=np.int64)  # updates over its life
        self.updated = np.empty(0, dtype=bool)  # updated in the last step
        self.cluster = np.empty(0, dtype=np.intp)  # cluster index of that update (-1: none)
        self.hovered = np.empty(0, dtype=bool)  # a candidate of it hovered (detect.tentative)
        self._together = {}
        self._lock = None

    def __len__(self) -> int:
        return len(self.ids)

    def step(
        self, t: float, found: Detections, confirmed: Candidates, t_meas: float | None = None
    ) -> Tracks:
        """Predict every track to the clusters' time ``t_meas`` (default ``t``), update it
        with the cluster assigned to it, start tracks on the confirmed candidates no track
        explains, end those unseen for ``coast_s``, and predict them all to ``t``; the
        tracks after the step.

        A LiDAR frame's returns span its integration period, so its clusters' centroids
        describe its middle (a rosette crosses its dense centre many times a frame), not
        its end: at 15 m/s the half-period of 0.05 s is 0.75 m.
        """
        s = self.settings
        t_z = t if t_meas is None else min(t_meas, t)
        self._predict(t_z)
        R = measurement_noise(found, s.sigma_meas)
        reach = s.v_max * np.maximum(t_z - self.t_update, 0.0) + s.gate_m
        cost = gate_costs(self.x, self.P, self.p_update, reach, found.centroids, R, self._gate)
        # a track unseen for longer than stale_s takes a confirmed candidate's cluster only
        stale = t_z - self.t_update > s.stale_s
        of = _cluster_of(confirmed, found)  # each candidate's cluster
        confirmed_cluster = np.zeros(len(found), dtype=bool)
        confirmed_cluster[of[of >= 0]] = True
        near = (
            np.linalg.norm(self.x[:, None, :3] - found.centroids[None, :, :], axis=2)
            <= s.stale_gate_m
        )
        cost[stale[:, None] & ~confirmed_cluster[None, :] & ~near] = _INFEASIBLE
        rows, cols = associate(cost)
        if len(rows):
            self.x[rows], self.P[rows] = cv_update(
                self.x[rows], self.P[rows], found.centroids[cols], R[cols]
            )
        self.updated = np.zeros(len(self), dtype=bool)
        self.updated[rows] = True
        self.cluster = np.full(len(self), -1, dtype=np.intp)
        self.cluster[rows] = cols
        self.t_update[rows] = t_z
        self.p_update[rows] = self.x[rows, :3]
        self.updates[rows] += 1
        self._note_hover(confirmed, of)
        self._drop(t_z - self.t_update <= s.coast_s)
        self._drop(~self._duplicates(t_z))
        taken = np.zeros(len(found), dtype=bool)
        taken[cols] = True
        self._births(t_z, confirmed, found, of, taken, R)
        self._predict(t)
        return self.snapshot()

    def note_lock(self, tracks: Tracks, estimate: TrackEstimate) -> None:
        """The turret's tracker after a frame: the track it holds (``tracks.locked``, none
        when the estimate is not locked; while it stays locked, the track it held last)
        and its estimate."""
        held = np.flatnonzero(tracks.locked)
        last = self._lock
        self._lock = None
        if not estimate.tracked:
            return
        p, v = np.asarray(estimate.position).copy(), np.asarray(estimate.velocity).copy()
        if len(held):
            self._lock = (int(tracks.ids[held[0]]), p, v, float(estimate.t))
        elif last is not None and np.any(self.ids == last[0]):
            # still locked, the track it held left behind: the lock keeps its identity
            self._lock = (last[0], p, v, float(estimate.t))

    def _hand_over(
        self, t: float, c: Candidates, clusters: NDArray[np.intp], R: FloatArray
    ) -> NDArray[np.bool_]:
        """(B,) which of the births ``c`` (their clusters ``clusters``, measurement noises
        ``R``) the held track takes (see the module docstring): at most one, the nearest
        to the lock's estimate predicted to ``t``, p_L = p + v (t − t_L), within
        SAME_TARGET_M, if the held track missed this frame.  It restarts there as a
        birth would, keeping its identity, its age, its updates and its hover."""
        taken = np.zeros(len(c), dtype=bool)
        if self._lock is None or len(c) == 0:
            return taken
        ident, p, v, t_lock = self._lock
        row = np.flatnonzero(self.ids == ident)
        if len(row) == 0 or self.updated[row[0]]:
            return taken
        gap = np.linalg.norm(c.positions - (p + v * max(t - t_lock, 0.0)), axis=1)
        i = int(np.argmin(gap))
        if gap[i] > SAME_TARGET_M:
            return taken
        k = int(row[0])
        self.x[k] = np.concatenate([c.positions[i], c.velocities[i]])
        self.P[k] = 0.0
        self.P[k, :3, :3] = R[i]
        self.P[k, 3:, 3:] = self.settings.birth_sigma_v**2 * np.eye(3)
        self.t[k] = self.t_update[k] = t
        self.p_update[k] = c.positions[i]
        self.updates[k] += 1
        self.updated[k] = True
        self.cluster[k] = clusters[i]
        self.hovered[k] |= bool(c.hovered[i])
        taken[i] = True
        return taken

    def _duplicates(self, t: float) -> NDArray[np.bool_]:
        """(K,) the tracks that end as duplicates at ``t``: of each pair within ``merge_m``
        since ``merge_s`` ago (``close_pairs``), the one with fewer updates, of equals
        the younger; the pairs' clocks are kept from frame to frame."""
        s = self.settings
        out = np.zeros(len(self), dtype=bool)
        pairs = close_pairs(self.x[:, :3], s.merge_m) if len(self) > 1 else ()
        if not len(pairs):
            self._together = {}
            return out
        ids = self.ids
        now = {(int(ids[i]), int(ids[j])) for i, j in pairs}
        self._together = {key: self._together.get(key, t) for key in now}
        row = {int(k): n for n, k in enumerate(ids)}
        for (a, b), since in sorted(self._together.items()):
            if t - since < s.merge_s:
                continue
            i, j = row[a], row[b]
            if out[i] or out[j]:
                continue
            # a < b: on equal updates the younger, b, ends
            out[j if self.updates[i] >= self.updates[j] else i] = True
        return out

    def _predict(self, t: float) -> None:
        """Every track's state at ``t`` (none goes back in time)."""
        dt = np.maximum(t - self.t, 0.0)
        self.x, self.P = cv_predict(self.x, self.P, dt, self.settings.sigma_acc)
        self.t = np.maximum(self.t, t)

    def _note_hover(self, confirmed: Candidates, of: NDArray[np.intp]) -> None:
        """A track whose cluster is a candidate that hovered has hovered (one-way);
        ``of``: each candidate's cluster."""
        if len(confirmed) == 0 or len(self) == 0:
            return
        hovered_clusters = set(of[confirmed.hovered & (of >= 0)].tolist())
        for k in np.flatnonzero(self.updated):
            if int(self.cluster[k]) in hovered_clusters:
                self.hovered[k] = True

    def _births(
        self,
        t: float,
        confirmed: Candidates,
        found: Detections,
        of: NDArray[np.intp],
        taken: NDArray[np.bool_],
        R_all: FloatArray,
    ) -> None:
        """Start tracks on the confirmed candidates whose clusters (``of``) no track took
        (``taken``) and lie beyond ``merge_m`` of every track, but the one the lock's
        track takes (``_hand_over``); ``R_all`` is every cluster's measurement noise."""
        s = self.settings
        new = np.flatnonzero((of >= 0) & ~taken[np.maximum(of, 0)])
        if len(new) and len(self):
            gap = np.linalg.norm(
                found.centroids[of[new], None, :] - self.x[None, :, :3], axis=2
            ).min(axis=1)
            new = new[gap > s.merge_m]
        if len(new) == 0:
            return
        c, R = confirmed.take(new), R_all[of[new]]
        born = np.flatnonzero(~self._hand_over(t, c, of[new], R))
        new, R, c = new[born], R[born], c.take(born)
        if len(new) == 0:
            return
        k = len(new)
        x = np.concatenate([c.positions, c.velocities], axis=1)
        P = np.zeros((k, 6, 6))
        P[:, :3, :3] = R
        P[:, 3:, 3:] = s.birth_sigma_v**2 * np.eye(3)
        ids = self._next_id + np.arange(k, dtype=np.int64)
        self._next_id += k
        self.ids = np.concatenate([self.ids, ids])
        self.x = np.concatenate([self.x, x])
        self.P = np.concatenate([self.P, P])
        self.t = np.concatenate([self.t, np.full(k, t)])
        self.born = np.concatenate([self.born, np.full(k, t)])
        self.t_update = np.concatenate([self.t_update, np.full(k, t)])
        self.p_update = np.concatenate([self.p_update, c.positions])
        self.updates = np.concatenate([self.updates, np.ones(k, dtype=np.int64)])
        self.updated = np.concatenate([self.updated, np.ones(k, dtype=bool)])
        self.cluster = np.concatenate([self.cluster, of[new]])
        self.hovered = np.concatenate([self.hovered, c.hovered])
        excess = len(self) - s.max_tracks
        if excess > 0:  # the longest unseen die first; of equals, the least updated, then
            # the younger: an established track outlives the births of a cluttered frame
            order = np.lexsort((self.ids, -self.updates, -self.t_update))
            keep = np.zeros(len(self), dtype=bool)
            keep[order[: s.max_tracks]] = True
            self._drop(keep)

    def _drop(self, keep: NDArray[np.bool_]) -> None:
        if keep.all():
            return
        for name in (
            "ids",
            "x",
            "P",
            "t",
            "born",
            "t_update",
            "p_update",
            "updates",
            "updated",
            "cluster",
            "hovered",
        ):
            setattr(self, name, getattr(self, name)[keep])

    def snapshot(self, estimate: TrackEstimate | None = None) -> Tracks:
        """The tracks as they stand, the one nearest a locked ``estimate`` of the turret's
        tracker (within ``detect.lock``'s SAME_TARGET_M) marked locked."""
        k = len(self)
        tracks = Tracks(
            ids=self.ids.copy(),
            positions=self.x[:, :3].copy(),
            velocities=self.x[:, 3:].copy(),
            covariances=self.P.copy(),
            born=self.born.copy(),
            updated=self.updated.copy(),
            hovered=self.hovered.copy(),
            locked=np.zeros(k, dtype=bool),
            clusters=np.where(self.updated, self.cluster, -1),
            last_seen=self.t_update.copy(),
        )
        return tracks if estimate is None else tracks.with_locked(estimate, SAME_TARGET_M)
