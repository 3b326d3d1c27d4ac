from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import (
    MAX_SEGMENT_ANGLE,
    apply_interpolated_poses,
    azimuth_elevation,
    direction_from_azimuth_elevation,
    interpolate_poses,
    make_pose,
    matrix_to_quaternion,
    pose_tables,
    quaternion_to_matrix,
    rot_x,
    rot_y,
    rot_z,
    transform_points,
    wrap_angle,
)

angles = st.floats(-10.0, 10.0, allow_nan=False)


def test_axis_rotations_known_answers() -> None:
    x, y, z = np.eye(3)
    np.testing.assert_allclose(rot_z(np.pi / 2) @ x, y, atol=1e-15)
    np.testing.assert_allclose(rot_x(np.pi / 2) @ y, z, atol=1e-15)
    np.testing.assert_allclose(rot_y(np.pi / 2) @ z, x, atol=1e-15)
    # A positive rotation about y tips +x down: that is a positive (downward) tilt.
    assert (rot_y(0.3) @ x)[2] < 0


def test_rotations_vectorise() -> None:
    a = np.array([0.1, 0.2, 0.3])
    stacked = rot_z(a)
    assert stacked.shape == (3, 3, 3)
    for k in range(3):
        np.testing.assert_allclose(stacked[k], rot_z(a[k]))


@given(angles, angles, angles)
def test_quaternion_round_trip(a: float, b: float, c: float) -> None:
    R = rot_z(a) @ rot_y(b) @ rot_x(c)
    q = matrix_to_quaternion(R)
    assert np.isclose(np.linalg.norm(q), 1.0)
    np.testing.assert_allclose(quaternion_to_matrix(q), R, atol=1e-12)


@given(st.floats(-np.pi, np.pi * 0.999), st.floats(-1.5, 1.5))
def test_azimuth_elevation_round_trip(az: float, el: float) -> None:
    d = direction_from_azimuth_elevation(az, el)
    az2, el2 = azimuth_elevation(d)
    assert np.isclose(el2, el, atol=1e-12)
    assert np.isclose(wrap_angle(az2 - az), 0.0, atol=1e-9)


@given(arrays(np.float64, 5, elements=st.floats(-1e3, 1e3)))
def test_wrap_angle_range_and_equivalence(a: np.ndarray) -> None:
    w = wrap_angle(a)
    assert np.all((w >= -np.pi) & (w < np.pi))
    np.testing.assert_allclose(np.cos(w), np.cos(a), atol=1e-9)
    np.testing.assert_allclose(np.sin(w), np.sin(a), atol=1e-9)


def test_transform_points_single_and_per_point() -> None:
    T = make_pose(rot_z(np.pi / 2), [1.0, 2.0, 3.0])
    P = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(
        transform_points(T, P), [[1.0, 3.0, 3.0], [1.0, 2.0, 4.0]], atol=1e-15
    )
    both = np.stack([T, np.eye(4)])
    np.testing.assert_allclose(
        transform_points(both, P), [[1.0, 3.0, 3.0], [0.0, 0.0, 1.0]], atol=1e-15
    )
    with pytest.raises(InputError, match=r"\(N, 3\)"):
        transform_points(T, np.zeros((2, 2)))
    with pytest.raises(InputError, match="poses"):
        transform_points(np.stack([T] * 3), P)


def test_interpolated_poses_hit_samples_and_midpoints() -> None:
    ts = np.array([0.0, 1.0, 2.0])
    poses = make_pose(rot_z(np.array([0.0, 0.2, 0.6])), [[0, 0, 0], [1, 0, 0], [1, 2, 0]])
    R, p = interpolate_poses(ts, poses, ts)
    np.testing.assert_allclose(R, poses[:, :3, :3], atol=1e-12)
    np.testing.assert_allclose(p, poses[:, :3, 3], atol=1e-12)
    R, p = interpolate_poses(ts, poses, [0.5, 1.5, -1.0, 3.0])
    np.testing.assert_allclose(p, [[0.5, 0, 0], [1, 1, 0], [0, 0, 0], [1, 2, 0]], atol=1e-12)
    # nlerp of a rotation about one axis stays about that axis; at the midpoint it
    # is the average angle (nlerp is symmetric there).
    np.testing.assert_allclose(R[0], rot_z(0.1), atol=1e-12)
    np.testing.assert_allclose(R[1], rot_z(0.4), atol=1e-12)


@settings(max_examples=25)
@given(st.integers(0, 2**32 - 1))
@pytest.mark.slow
def test_apply_interpolated_poses_matches_matrices(seed: int) -> None:
    g = np.random.default_rng(seed)
    ts = np.sort(g.uniform(0, 1, 6))
    R = rot_z(g.uniform(-3, 3, 6)) @ rot_y(g.uniform(-1, 1, 6)) @ rot_x(g.uniform(-3, 3, 6))
    poses = make_pose(R, g.normal(size=(6, 3)))
    t = g.uniform(-0.2, 1.2, 40)
    v = g.normal(size=(40, 3))
    p = g.normal(size=(40, 3))
    Ri, pi = interpolate_poses(ts, poses, t)
    rv, rp = apply_interpolated_poses(ts, poses, t, v, p)
    # Linear interpolation between samples at most MAX_SEGMENT_ANGLE apart errs by
    # at most δ²/8 of the vector's length (nlerp and the lerp share the samples).
    bound = MAX_SEGMENT_ANGLE**2 / 8
    exact_v = np.einsum("nij,nj->ni", Ri, v)
    exact_p = np.einsum("nij,nj->ni", Ri, p) + pi
    assert np.all(np.linalg.norm(rv - exact_v, axis=1) <= bound * np.linalg.norm(v, axis=1) + 1e-12)
    assert np.all(np.linalg.norm(rp - exact_p, axis=1) <= bound * np.linalg.norm(p, axis=1) + 1e-12)


def test_pose_tables_split_large_turns() -> None:
    ts = np.array([0.0, 1.0])
    poses = make_pose(rot_z(np.array([0.0, 0.5])), np.zeros((2, 3)))
    dense_t, R, _ = pose_tables(ts, poses)
    # 0.5 rad in steps of at most MAX_SEGMENT_ANGLE, and not many more than needed.
    assert np.ceil(0.5 / MAX_SEGMENT_ANGLE) <= len(dense_t) - 1 <= 1.1 * 0.5 / MAX_SEGMENT_ANGLE
    steps = np.arccos(np.clip((np.einsum("kij,kij->k", R[:-1], R[1:]) - 1) / 2, -1, 1))
    assert steps.max() <= MAX_SEGMENT_ANGLE + 1e-12
    # A single pose is held at all times.
    one = make_pose(rot_z(0.3), [1.0, 2.0, 3.0])[None]
    v, p = apply_interpolated_poses([5.0], one, [0.0, 9.0], np.eye(3)[:2])
    np.testing.assert_allclose(v, (rot_z(0.3) @ np.eye(3)[:2].T).T, atol=1e-15)
    np.testing.assert_allclose(p, [[1.0, 2.0, 3.0]] * 2)


def test_pose_samples_are_checked() -> None:
    with pytest.raises(InputError, match="pose samples"):
        interpolate_poses([0.0, 1.0], np.zeros((3, 4, 4)), [0.5])
    with pytest.raises(InputError, match="pose samples"):
        apply_interpolated_poses([], np.zeros((0, 4, 4)), [0.5], np.zeros((1, 3)))
    good = make_pose(rot_z(np.array([0.0, 0.1])), np.zeros((2, 3)))
    mirrored = good.copy()
    mirrored[1, :3, 0] *= -1.0  # det R = −1
    skewed = good.copy()
    skewed[0, 0, 1] += 1e-3  # RᵀR off the identity by 10⁻³
    tilted_row = good.copy()
    tilted_row[1, 3, 0] = 0.5
    for bad in (mirrored, skewed, tilted_row):
        with pytest.raises(InputError, match="rigid"):
            interpolate_poses([0.0, 1.0], bad, [0.5])
    # float32 rounding of a recorded pose is accepted.
    interpolate_poses([0.0, 1.0], good.astype(np.float32), [0.5])
    with pytest.raises(InputError, match="finite"):
        interpolate_poses([0.0, 1.0], np.where(good == 0.0, np.nan, good), [0.5])
