"""Pan-tilt turret kinematics shared by the simulator, the controller and the readers.

world_T_sensor = T(base) · Rz(pan) · T(pan→tilt) · Ry(tilt) · T(tilt→sensor)

Pan turns about world z (counter-clockwise from above is positive).  Tilt turns
about the panned y axis, so a positive tilt points the sensor *down*, as the
minus sign in seed 000's eq. (10) says.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.geometry.transforms import FloatArray, make_pose, rot_y, rot_z

__all__ = ["TURRET_FRAMES", "MountGeometry", "pointing_angles", "sensor_poses", "turret_links"]

# The /tf frames of a turret, from the world down to the sensor.
TURRET_FRAMES = ("world", "turret_base", "pan_link", "tilt_link", "lidar")


def _vec3(values: tuple[float, float, float]) -> FloatArray:
    return np.asarray(values, dtype=np.float64)


@dataclass(frozen=True, slots=True)
class MountGeometry:
    """Where the sensor sits on the turret [m].

    base: turret base (the pan axis foot) in the world frame.
    pan_to_tilt: tilt-axis centre in the pan frame.
    tilt_to_sensor: sensor origin in the tilt frame (x along the optical axis).
    """

    base: tuple[float, float, float] = (0.0, 0.0, 1.0)
    pan_to_tilt: tuple[float, float, float] = (0.0, 0.0, 0.0)
    tilt_to_sensor: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def base_vec(self) -> FloatArray:
        return _vec3(self.base)

    @property
    def pan_to_tilt_vec(self) -> FloatArray:
        return _vec3(self.pan_to_tilt)

    @property
    def tilt_to_sensor_vec(self) -> FloatArray:
        return _vec3(self.tilt_to_sensor)


def sensor_poses(pan: ArrayLike, tilt: ArrayLike, mount: MountGeometry) -> FloatArray:
    """world_T_sensor for pan and tilt angles [rad]; shape (..., 4, 4)."""
    pan_a = np.asarray(pan, dtype=np.float64)
    tilt_a = np.asarray(tilt, dtype=np.float64)
    Rz = rot_z(pan_a)
    Ry = rot_y(tilt_a)
    # R = Rz(pan) Ry(tilt)
    R = Rz @ Ry
    # p = base + Rz(pan) (pan_to_tilt + Ry(tilt) tilt_to_sensor)
    local = mount.pan_to_tilt_vec + Ry @ mount.tilt_to_sensor_vec
    p = mount.base_vec + np.einsum("...ij,...j->...i", Rz, local)
    return make_pose(R, p)


def turret_links(
    pan: ArrayLike, tilt: ArrayLike, mount: MountGeometry
) -> list[tuple[str, str, FloatArray]]:
    """The turret's /tf edges (parent, child, parent_T_child (..., 4, 4)) along
    ``TURRET_FRAMES``; their product is ``sensor_poses(pan, tilt, mount)``:

        world_T_lidar = T(base) · Rz(pan) · T(pan→tilt) Ry(tilt) · T(tilt→sensor)
    """
    pan_a = np.asarray(pan, dtype=np.float64)
    tilt_a = np.asarray(tilt, dtype=np.float64)
    eye = np.eye(3)
    zero = np.zeros(3)
    world, base, pan_f, tilt_f, lidar = TURRET_FRAMES
    return [
        (world, base, make_pose(eye, mount.base_vec)),
        (base, pan_f, make_pose(rot_z(pan_a), np.broadcast_to(zero, (*pan_a.shape, 3)))),
        (
            pan_f,
            tilt_f,
            make_pose(rot_y(tilt_a), np.broadcast_to(mount.pan_to_tilt_vec, (*tilt_a.shape, 3))),
        ),
        (tilt_f, lidar, make_pose(eye, mount.tilt_to_sensor_vec)),
    ]


def pointing_angles(poses: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Pan and tilt [rad] of sensor poses (..., 4, 4), the inverse of ``sensor_poses``'s
    rotation for |tilt| < 90°: the optical axis R e_x = (cos pan cos tilt,
    sin pan cos tilt, −sin tilt), so pan = atan2(R₁₀, R₀₀) and tilt = asin(−R₂₀)."""
    R = np.asarray(poses, dtype=np.float64)[..., :3, :3]
    pan: FloatArray = np.arctan2(R[..., 1, 0], R[..., 0, 0])
    tilt: FloatArray = np.arcsin(np.clip(-R[..., 2, 0], -1.0, 1.0))
    return pan, tilt
