"""A LiDAR frame: its returns, their times and the sensor's poses."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray, interpolate_poses, transform_at_times

__all__ = ["Frame"]


@dataclass(frozen=True, slots=True)
class Frame:
    """One integration period of a LiDAR.

    points: (N, 3) returns in the sensor frame [m].
    t: (N,) time of each return [s].
    line: (N,) laser line / channel index.
    intensity: (N,) reflectivity in the Livox encoding (0-150 diffuse, >150 retro).
    pose_t, poses: world_T_sensor sampled during the frame, (K,) and (K, 4, 4).
        The sensor may move while it integrates (a turret or a moving observer);
        ``sensor_poses`` interpolates the pose at each point's time.
    """

    stamp: float
    duration: float
    points: FloatArray
    t: FloatArray
    line: NDArray[np.uint8]
    intensity: NDArray[np.float32]
    pose_t: FloatArray
    poses: FloatArray

    def __post_init__(self) -> None:
        n = len(self.points)
        if self.points.shape != (n, 3):
            raise InputError(f"frame points must be (N, 3), got {self.points.shape}")
        for name in ("t", "line", "intensity"):
            arr = getattr(self, name)
            if arr.shape != (n,):
                raise InputError(f"frame {name} must have shape ({n},), got {arr.shape}")
        if self.poses.shape != (len(self.pose_t), 4, 4) or len(self.pose_t) == 0:
            raise InputError(
                f"frame poses must be (K, 4, 4) with K = len(pose_t) >= 1, got {self.poses.shape}"
            )

    @property
    def end(self) -> float:
        """End of the integration period [s]."""
        return self.stamp + self.duration

    def __len__(self) -> int:
        return len(self.points)

    def sensor_poses(self) -> tuple[FloatArray, FloatArray]:
        """Rotation (N, 3, 3) and origin (N, 3) of the sensor at each point's time."""
        return interpolate_poses(self.pose_t, self.poses, self.t)

    def world_points(self) -> FloatArray:
        """Points (N, 3) in the world frame, each with the sensor pose at its time."""
        if len(self) == 0:
            return np.empty((0, 3))
        return transform_at_times(self.pose_t, self.poses, self.t, self.points)
