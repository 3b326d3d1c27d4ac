"""Turret kinematics: the /tf links and the inverse (pointing angles)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.geometry.mount import MountGeometry, pointing_angles, sensor_poses, turret_links

MOUNT = MountGeometry((0.5, -1.0, 1.2), (0.02, 0.0, 0.15), (0.08, 0.01, 0.04))


@given(st.floats(-3.1, 3.1), st.floats(-1.5, 1.5))
def test_links_compose_to_the_sensor_pose_and_angles_invert_it(pan: float, tilt: float) -> None:
    links = turret_links(pan, tilt, MOUNT)
    T = links[0][2] @ links[1][2] @ links[2][2] @ links[3][2]
    np.testing.assert_allclose(T, sensor_poses(pan, tilt, MOUNT), atol=1e-12)
    assert [(p, c) for p, c, _ in links] == [
        ("world", "turret_base"),
        ("turret_base", "pan_link"),
        ("pan_link", "tilt_link"),
        ("tilt_link", "lidar"),
    ]
    got_pan, got_tilt = pointing_angles(T)
    assert abs(float(got_pan) - pan) < 1e-9
    assert abs(float(got_tilt) - tilt) < 1e-9
