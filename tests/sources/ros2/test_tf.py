"""The /tf buffer: chains, interpolation, sample times, bad trees."""

from __future__ import annotations

import numpy as np
import pytest

from dronetrack.errors import RecordingError
from dronetrack.geometry.mount import MountGeometry, sensor_poses, turret_links
from dronetrack.geometry.transforms import make_pose, matrix_to_quaternion, rot_y, rot_z
from dronetrack.sources.ros2.tf import TransformBuffer, transform_matrix, valid_transform


def _turret_buffer(
    mount: MountGeometry, t: np.ndarray, pan: np.ndarray, tilt: np.ndarray
) -> TransformBuffer:
    tf = TransformBuffer()
    links = turret_links(pan, tilt, mount)
    for parent, child, T in (links[0], links[-1]):
        tf.add(parent, child, 0.0, T, static=True)
    for parent, child, T in links[1:3]:
        for k, tk in enumerate(t):
            tf.add(parent, child, float(tk), T[k])
    return tf


def test_chain_composes_the_turret_to_the_sensor_pose() -> None:
    mount = MountGeometry((1.0, -2.0, 1.5), (0.05, 0.0, 0.2), (0.1, 0.0, 0.03))
    t = np.linspace(0.0, 1.0, 11)
    pan, tilt = 0.8 * t - 0.3, -0.4 * t + 0.1  # constant rates: nlerp of one axis is exact in angle
    tf = _turret_buffer(mount, t, pan, tilt)
    assert tf.chain("lidar") == ["world", "turret_base", "pan_link", "tilt_link", "lidar"]
    assert tf.root("lidar") == "world"
    got = tf.lookup("world", "lidar", t)
    np.testing.assert_allclose(got, sensor_poses(pan, tilt, mount), atol=1e-12)
    # Between samples, the pose is the interpolated one: each joint turns about one axis,
    # so nlerp gives an angle within δ²/8-relative of the linear one.
    mid = tf.lookup("world", "lidar", [0.05])[0]
    want = sensor_poses(0.8 * 0.05 - 0.3, -0.4 * 0.05 + 0.1, mount)
    np.testing.assert_allclose(mid, want, atol=1e-6)
    # A sub-chain: the tilt link in the pan frame is a pure tilt.
    np.testing.assert_allclose(
        tf.lookup("pan_link", "tilt_link", [0.0])[0][:3, :3], rot_y(0.1), atol=1e-12
    )


def test_samples_beyond_the_ends_hold_and_sample_times_are_listed() -> None:
    mount = MountGeometry()
    t = np.array([1.0, 1.1, 1.2])
    tf = _turret_buffer(mount, t, np.array([0.0, 0.1, 0.2]), np.zeros(3))
    before, after = tf.lookup("world", "lidar", [0.0, 5.0])
    np.testing.assert_allclose(before[:3, :3], rot_z(0.0), atol=1e-12)
    np.testing.assert_allclose(after[:3, :3], rot_z(0.2), atol=1e-12)
    np.testing.assert_allclose(tf.sample_times("world", "lidar", 1.0, 1.2), [1.1])
    assert len(tf.sample_times("world", "lidar", 2.0, 3.0)) == 0


def test_transform_matrix_takes_ros_quaternion_order() -> None:
    R = rot_z(0.7) @ rot_y(-0.2)
    w, x, y, z = matrix_to_quaternion(R)
    np.testing.assert_allclose(
        transform_matrix((1, 2, 3), (x, y, z, w)), make_pose(R, (1, 2, 3)), atol=1e-12
    )


def test_bad_trees_raise_recording_errors() -> None:
    tf = TransformBuffer()
    tf.add("a", "b", 0.0, np.eye(4), static=True)
    tf.add("b", "a", 0.0, np.eye(4), static=True)
    with pytest.raises(RecordingError, match="loop"):
        tf.chain("b")
    tf2 = TransformBuffer()
    tf2.add("world", "lidar", 0.0, np.eye(4), static=True)
    with pytest.raises(RecordingError, match="'map' is not in the /tf tree; its frames are: "):
        tf2.lookup("map", "lidar", [0.0])
    assert tf2.frames() == ["lidar", "world"]
    tf2.add("world", "radar", 0.0, np.eye(4), static=True)
    with pytest.raises(RecordingError, match=r"not below 'radar'.*chain is world → lidar"):
        tf2.lookup("radar", "lidar", [0.0])
    # A second parent for a frame is ignored and counted.
    tf2.add("odom", "lidar", 0.0, np.eye(4), static=True)
    assert tf2.conflicts == 1
    assert tf2.chain("lidar") == ["world", "lidar"]


@pytest.mark.parametrize(
    ("t", "translation", "quaternion", "ok"),
    [
        (0.0, (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0), True),
        (0.0, (1.0, 2.0, 3.0), (0.0, 0.0, 0.6, 0.6), True),  # |q| = 0.85: normalised on use
        (0.0, (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1e200), False),  # |q|² would overflow
        (0.0, (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 0.0), False),
        (0.0, (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 3.0), False),
        (0.0, (1.0, float("nan"), 3.0), (0.0, 0.0, 0.0, 1.0), False),
        (float("inf"), (1.0, 2.0, 3.0), (0.0, 0.0, 0.0, 1.0), False),
        (0.0, (1.0, 2.0, 3.0), (0.0, 0.0, float("inf"), 1.0), False),
    ],
)
def test_damaged_transforms_are_counted_and_left_out(
    t: float, translation: tuple[float, ...], quaternion: tuple[float, ...], ok: bool
) -> None:
    assert valid_transform(t, translation, quaternion) is ok
    tf = TransformBuffer()
    tf.add_transform("world", "sensor", t, translation, quaternion)
    assert tf.invalid == (0 if ok else 1)
    assert ("sensor" in tf) is ok
