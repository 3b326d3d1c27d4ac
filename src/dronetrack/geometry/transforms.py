"""Rigid-body geometry on numpy arrays.

Conventions (REP-103): right-handed frames, x forward, y left, z up; angles in
radians; poses are 4x4 homogeneous matrices ``parent_T_child``.  Functions take
one pose ``(4, 4)`` or a stack ``(N, 4, 4)``.

Azimuth is ``atan2(y, x)`` and elevation is ``atan2(z, hypot(x, y))``.
"""

from __future__ import annotations

import numba as nb
import numpy as np
from numpy.typing import ArrayLike, NDArray

from dronetrack.errors import InputError

FloatArray = NDArray[np.float64]

__all__ = [
    "FloatArray",
    "align_hemispheres",
    "aligned_quaternions",
    "apply_interpolated_poses",
    "azimuth_elevation",
    "direction_from_azimuth_elevation",
    "interpolate_poses",
    "interpolate_quaternions",
    "make_pose",
    "matrix_to_quaternion",
    "pose_segments",
    "pose_tables",
    "quaternion_to_matrix",
    "rot_x",
    "rot_y",
    "rot_z",
    "transform_at_times",
    "transform_points",
    "unit",
    "wrap_angle",
]


def _axis_rotation(angle: ArrayLike, i: int, j: int) -> FloatArray:
    """Rotation by ``angle`` in the (i, j) plane; shape (3, 3) or (N, 3, 3)."""
    a = np.asarray(angle, dtype=np.float64)
    c, s = np.cos(a), np.sin(a)
    R = np.zeros((*a.shape, 3, 3))
    k = 3 - i - j
    R[..., k, k] = 1.0
    R[..., i, i] = c
    R[..., j, j] = c
    R[..., i, j] = -s
    R[..., j, i] = s
    return R


def rot_x(angle: ArrayLike) -> FloatArray:
    """Rotation about x: y turns towards z for a positive angle."""
    return _axis_rotation(angle, 1, 2)


def rot_y(angle: ArrayLike) -> FloatArray:
    """Rotation about y: z turns towards x, so a positive angle tips +x down."""
    return _axis_rotation(angle, 2, 0)


def rot_z(angle: ArrayLike) -> FloatArray:
    """Rotation about z: x turns towards y (counter-clockwise seen from above)."""
    return _axis_rotation(angle, 0, 1)


def make_pose(R: ArrayLike, p: ArrayLike) -> FloatArray:
    """Homogeneous pose from rotation ``R`` (..., 3, 3) and translation ``p`` (..., 3)."""
    Rm = np.asarray(R, dtype=np.float64)
    pv = np.asarray(p, dtype=np.float64)
    shape = np.broadcast_shapes(Rm.shape[:-2], pv.shape[:-1])
    T = np.zeros((*shape, 4, 4))
    T[..., :3, :3] = Rm
    T[..., :3, 3] = pv
    T[..., 3, 3] = 1.0
    return T


def transform_points(T: ArrayLike, points: ArrayLike) -> FloatArray:
    """Apply pose ``T`` (4, 4) or per-point poses (N, 4, 4) to points (N, 3).

    p' = R p + t
    """
    Tm = np.asarray(T, dtype=np.float64)
    P = np.asarray(points, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3:
        raise InputError(f"points must have shape (N, 3), got {P.shape}")
    if Tm.shape == (4, 4):
        return P @ Tm[:3, :3].T + Tm[:3, 3]
    if Tm.shape != (len(P), 4, 4):
        raise InputError(f"poses must have shape (4, 4) or ({len(P)}, 4, 4), got {Tm.shape}")
    out: FloatArray = np.einsum("nij,nj->ni", Tm[:, :3, :3], P) + Tm[:, :3, 3]
    return out


def unit(v: ArrayLike) -> FloatArray:
    """Normalise vectors along the last axis."""
    a = np.asarray(v, dtype=np.float64)
    out: FloatArray = a / np.linalg.norm(a, axis=-1, keepdims=True)
    return out


def wrap_angle(angle: ArrayLike) -> FloatArray:
    """Wrap angles to [-π, π)."""
    a = np.asarray(angle, dtype=np.float64)
    return (a + np.pi) % (2.0 * np.pi) - np.pi


def azimuth_elevation(d: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Azimuth atan2(y, x) and elevation atan2(z, hypot(x, y)) of directions (..., 3)."""
    v = np.asarray(d, dtype=np.float64)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.arctan2(y, x), np.arctan2(z, np.hypot(x, y))


def direction_from_azimuth_elevation(az: ArrayLike, el: ArrayLike) -> FloatArray:
    """Unit directions (..., 3) from azimuth and elevation [rad]."""
    a = np.asarray(az, dtype=np.float64)
    e = np.asarray(el, dtype=np.float64)
    ce = np.cos(e)
    return np.stack([ce * np.cos(a), ce * np.sin(a), np.sin(e)], axis=-1)


def matrix_to_quaternion(R: ArrayLike) -> FloatArray:
    """Unit quaternions (..., 4) as (w, x, y, z) from rotation matrices (..., 3, 3).

    Shepperd's method: take the largest of 4w², 4x², 4y², 4z² from the diagonal,
    then the other components from the off-diagonal terms, which keeps full
    precision for every rotation.
    """
    M = np.asarray(R, dtype=np.float64)
    m00, m01, m02 = M[..., 0, 0], M[..., 0, 1], M[..., 0, 2]
    m10, m11, m12 = M[..., 1, 0], M[..., 1, 1], M[..., 1, 2]
    m20, m21, m22 = M[..., 2, 0], M[..., 2, 1], M[..., 2, 2]
    # 4w² = 1 + tr,         4x² = 1 + m00 − m11 − m22,
    # 4y² = 1 − m00 + m11 − m22,  4z² = 1 − m00 − m11 + m22
    four_sq = np.stack(
        [1 + m00 + m11 + m22, 1 + m00 - m11 - m22, 1 - m00 + m11 - m22, 1 - m00 - m11 + m22],
        axis=-1,
    )
    k = np.argmax(four_sq, axis=-1)
    # s = 4 · (the largest component)
    s = 2.0 * np.sqrt(
        np.maximum(np.take_along_axis(four_sq, k[..., None], axis=-1)[..., 0], 1e-300)
    )
    wx, wy, wz = m21 - m12, m02 - m20, m10 - m01  # 4w·(x, y, z)
    xy, xz, yz = m01 + m10, m02 + m20, m12 + m21  # 4x·y, 4x·z, 4y·z
    candidates = np.stack(
        [
            np.stack([0.25 * s, wx / s, wy / s, wz / s], axis=-1),
            np.stack([wx / s, 0.25 * s, xy / s, xz / s], axis=-1),
            np.stack([wy / s, xy / s, 0.25 * s, yz / s], axis=-1),
            np.stack([wz / s, xz / s, yz / s, 0.25 * s], axis=-1),
        ],
        axis=-2,
    )
    q = np.take_along_axis(candidates, k[..., None, None], axis=-2)[..., 0, :]
    # One sign convention: w ≥ 0.
    return unit(np.where(q[..., :1] < 0, -q, q))


def quaternion_to_matrix(q: ArrayLike) -> FloatArray:
    """Rotation matrices (..., 3, 3) from quaternions (..., 4) as (w, x, y, z)."""
    Q = unit(q)
    w, x, y, z = Q[..., 0], Q[..., 1], Q[..., 2], Q[..., 3]
    R = np.empty((*Q.shape[:-1], 3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


def aligned_quaternions(poses: FloatArray) -> FloatArray:
    """Quaternions of the pose rotations, each in the hemisphere of its predecessor."""
    return align_hemispheres(matrix_to_quaternion(poses[:, :3, :3]))


def align_hemispheres(q: FloatArray) -> FloatArray:
    """Unit quaternions (K, 4), each sign-flipped into the hemisphere of its predecessor
    (q and −q are the same rotation; interpolation needs neighbours with q_i · q_{i+1} ≥ 0)."""
    q = unit(q)
    flips = np.sum(q[1:] * q[:-1], axis=1) < 0
    sign = np.concatenate([[1.0], np.where(np.cumsum(flips) % 2 == 1, -1.0, 1.0)])
    out: FloatArray = q * sign[:, None]
    return out


def interpolate_poses(
    pose_t: ArrayLike, poses: ArrayLike, t: ArrayLike
) -> tuple[FloatArray, FloatArray]:
    """Poses at times ``t`` from samples ``poses`` (K, 4, 4) taken at ``pose_t`` (K,).

    Translation is interpolated linearly, rotation by normalised quaternion
    interpolation (nlerp), which matches slerp to second order in the angle
    between neighbouring samples.  Times outside the samples are clamped.

    Returns rotations (N, 3, 3) and translations (N, 3).
    """
    ts, T = _check_pose_samples(pose_t, poses)
    tq = np.atleast_1d(np.asarray(t, dtype=np.float64))
    if len(ts) == 1:
        n = len(tq)
        return np.broadcast_to(T[0, :3, :3], (n, 3, 3)).copy(), np.tile(T[0, :3, 3], (n, 1))
    return interpolate_quaternions(ts, aligned_quaternions(T), T[:, :3, 3], tq)


def interpolate_quaternions(
    ts: FloatArray, q: FloatArray, p: FloatArray, t: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """``interpolate_poses`` on a prepared table: K ≥ 2 increasing times ``ts``, quaternions
    ``q`` (K, 4) each in its predecessor's hemisphere, translations ``p`` (K, 3)."""
    i = np.clip(np.searchsorted(ts, t, side="right") - 1, 0, len(ts) - 2)
    span = ts[i + 1] - ts[i]
    u = np.clip((t - ts[i]) / np.where(span > 0, span, 1.0), 0.0, 1.0)
    # p(t) = p_i + u (p_{i+1} − p_i),  q(t) = normalise(q_i + u (q_{i+1} − q_i))
    pt = p[i] + u[:, None] * (p[i + 1] - p[i])
    qi = q[i] + u[:, None] * (q[i + 1] - q[i])
    return quaternion_to_matrix(qi), pt


RIGID_TOL = 1e-4  # float32 rounding of a recorded pose passes


@nb.njit(cache=True)
def _rigid_error(T: FloatArray) -> float:
    """Largest departure of poses (K, 4, 4) from rigid transforms: |RᵀR − I|, the
    bottom row against (0, 0, 0, 1), and ∞ for a reflection (det R < 0)."""
    worst = 0.0
    for k in range(T.shape[0]):
        for i in range(3):
            for j in range(3):
                # (RᵀR)_ij = Σ_m R_mi R_mj
                g = T[k, 0, i] * T[k, 0, j] + T[k, 1, i] * T[k, 1, j] + T[k, 2, i] * T[k, 2, j]
                worst = max(worst, abs(g - (1.0 if i == j else 0.0)))
        for j in range(4):
            worst = max(worst, abs(T[k, 3, j] - (1.0 if j == 3 else 0.0)))
        # det R = r₀ · (r₁ × r₂) over the rows
        det = (
            T[k, 0, 0] * (T[k, 1, 1] * T[k, 2, 2] - T[k, 1, 2] * T[k, 2, 1])
            - T[k, 0, 1] * (T[k, 1, 0] * T[k, 2, 2] - T[k, 1, 2] * T[k, 2, 0])
            + T[k, 0, 2] * (T[k, 1, 0] * T[k, 2, 1] - T[k, 1, 1] * T[k, 2, 0])
        )
        if det < 0.0:
            worst = np.inf
    return worst


def _check_pose_samples(pose_t: ArrayLike, poses: ArrayLike) -> tuple[FloatArray, FloatArray]:
    ts = np.asarray(pose_t, dtype=np.float64)
    T = np.asarray(poses, dtype=np.float64)
    if ts.ndim != 1 or len(ts) == 0 or T.shape != (len(ts), 4, 4):
        raise InputError(
            f"pose samples must be (K,) times and (K, 4, 4) poses, got {ts.shape}, {T.shape}"
        )
    if not (np.all(np.isfinite(ts)) and np.all(np.isfinite(T))):
        raise InputError("pose samples must be finite")
    if _rigid_error(T) > RIGID_TOL:
        raise InputError("pose samples must be rigid transforms (orthonormal rotation)")
    return ts, T


# Bulk transforms interpolate rotation matrices linearly between pose samples no more
# than this far apart: R_i + u (R_{i+1} − R_i) differs from the rotation it stands
# for by at most δ²/8 (relative), 2·10⁻⁶ here, 0.4 mm at 200 m.
MAX_SEGMENT_ANGLE = 4e-3  # [rad]


def _step_angles(R: FloatArray) -> FloatArray:
    """Angles between neighbouring rotations: cos θ = (tr(R_iᵀ R_{i+1}) − 1) / 2."""
    trace = np.einsum("kij,kij->k", R[:-1], R[1:])
    angles: FloatArray = np.arccos(np.clip(0.5 * (trace - 1.0), -1.0, 1.0))
    return angles


def pose_tables(pose_t: ArrayLike, poses: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Times (K',), rotations (K', 3, 3) and translations (K', 3) for ``pose_at``.

    Where neighbouring samples turn by more than ``MAX_SEGMENT_ANGLE`` the segment
    is split at nlerp-interpolated poses, so linear interpolation stays accurate.
    """
    ts, T = _check_pose_samples(pose_t, poses)
    if len(ts) == 1:  # one pose: hold it (two equal samples a second apart)
        ts = np.array([ts[0], ts[0] + 1.0])
        T = np.concatenate([T, T])
    if np.any(np.diff(ts) <= 0):
        raise InputError("pose sample times must strictly increase")
    R = T[:, :3, :3]
    splits = np.maximum(1, np.ceil(_step_angles(R) / MAX_SEGMENT_ANGLE).astype(np.int64))
    while np.any(splits > 1):
        u = np.concatenate([np.arange(n) / n for n in splits])
        seg = np.repeat(np.arange(len(splits)), splits)
        dense_t = np.append(ts[seg] + u * (ts[seg + 1] - ts[seg]), ts[-1])
        dense_R, p = interpolate_poses(ts, T, dense_t)
        # nlerp turns a little faster mid-segment than at its ends: split again where needed.
        too_far = np.maximum.reduceat(_step_angles(dense_R), np.r_[0, np.cumsum(splits)[:-1]])
        if np.all(too_far <= MAX_SEGMENT_ANGLE):
            return dense_t, np.ascontiguousarray(dense_R), np.ascontiguousarray(p)
        splits = np.where(too_far > MAX_SEGMENT_ANGLE, splits + 1, splits)
    return ts, np.ascontiguousarray(R), np.ascontiguousarray(T[:, :3, 3])


@nb.njit(cache=True)
def pose_segments(ts: FloatArray, t: FloatArray) -> NDArray[np.int64]:
    """Segment i of the samples with ts[i] ≤ t < ts[i+1] for each time, clamped to [0, K − 2].

    Times are usually sorted: walk on from the previous segment, else bisect.
    """
    k = ts.shape[0]
    out = np.empty(t.shape[0], dtype=np.int64)
    i = 0
    for j in range(t.shape[0]):
        tj = t[j]
        if tj < ts[i]:
            lo, hi = 0, i
            while lo < hi:
                mid = (lo + hi + 1) // 2
                if ts[mid] <= tj:
                    lo = mid
                else:
                    hi = mid - 1
            i = lo
        while i < k - 2 and ts[i + 1] <= tj:
            i += 1
        out[j] = i
    return out


@nb.njit(cache=True, fastmath=True)
def _transform_kernel(
    ts: FloatArray,
    R: FloatArray,
    pos: FloatArray,
    seg: NDArray[np.int64],
    t: FloatArray,
    V: FloatArray,
    translate: bool,
) -> FloatArray:
    """R(t) v (+ p(t) if ``translate``) per row, with the linear pose interpolation of
    ``pose_tables``:  R(u) = R_i + u (R_{i+1} − R_i),  p(u) = p_i + u (p_{i+1} − p_i),
    u = clip((t − t_i) / (t_{i+1} − t_i), 0, 1).  Branch-free, so it vectorises."""
    n = V.shape[0]
    out = np.empty((n, 3))
    for j in range(n):
        i = seg[j]
        u = min(max((t[j] - ts[i]) / (ts[i + 1] - ts[i]), 0.0), 1.0)
        a, b, c = V[j, 0], V[j, 1], V[j, 2]
        for r in range(3):
            value = (
                (R[i, r, 0] + u * (R[i + 1, r, 0] - R[i, r, 0])) * a
                + (R[i, r, 1] + u * (R[i + 1, r, 1] - R[i, r, 1])) * b
                + (R[i, r, 2] + u * (R[i + 1, r, 2] - R[i, r, 2])) * c
            )
            if translate:
                value += pos[i, r] + u * (pos[i + 1, r] - pos[i, r])
            out[j, r] = value
    return out


def transform_at_times(
    pose_t: ArrayLike, poses: ArrayLike, t: ArrayLike, vectors: ArrayLike, translate: bool = True
) -> FloatArray:
    """R(t_j) v_j (+ p(t_j)) for rows v_j (N, 3), poses interpolated as ``pose_tables`` says."""
    ts, R, pos = pose_tables(pose_t, poses)
    tq = np.ascontiguousarray(np.atleast_1d(np.asarray(t, dtype=np.float64)))
    V = np.ascontiguousarray(vectors, dtype=np.float64)
    if V.shape != (len(tq), 3):
        raise InputError(f"vectors must be ({len(tq)}, 3), got {V.shape}")
    return _transform_kernel(ts, R, pos, pose_segments(ts, tq), tq, V, translate)


def apply_interpolated_poses(
    pose_t: ArrayLike,
    poses: ArrayLike,
    t: ArrayLike,
    vectors: ArrayLike,
    points: ArrayLike | None = None,
) -> tuple[FloatArray, FloatArray]:
    """Rotate ``vectors`` (N, 3) and transform ``points`` (N, 3) by the pose at each time.

    Poses between samples as ``interpolate_poses`` gives them, to within
    MAX_SEGMENT_ANGLE²/8 (see ``pose_tables``).  ``points`` defaults to the
    origin, so the second result is then the pose translation.  Returns (R v, R p + t).
    """
    ts, R, pos = pose_tables(pose_t, poses)
    tq = np.ascontiguousarray(np.atleast_1d(np.asarray(t, dtype=np.float64)))
    V = np.ascontiguousarray(vectors, dtype=np.float64)
    P = np.zeros_like(V) if points is None else np.ascontiguousarray(points, dtype=np.float64)
    if V.shape != (len(tq), 3) or P.shape != V.shape:
        raise InputError(f"vectors and points must be ({len(tq)}, 3), got {V.shape}, {P.shape}")
    seg = pose_segments(ts, tq)
    return _transform_kernel(ts, R, pos, seg, tq, V, False), _transform_kernel(
        ts, R, pos, seg, tq, P, True
    )
