"""A frame built from a reader's arrays, for sensors whose pose is fixed or sampled."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Frame

__all__ = ["fixed_pose_frame"]


def fixed_pose_frame(
    stamp: float,
    duration: float,
    points: FloatArray,
    t: FloatArray | None = None,
    intensity: ArrayLike | None = None,
    line: ArrayLike | None = None,
    pose: FloatArray | None = None,
    pose_t: FloatArray | None = None,
) -> Frame:
    """A frame from its arrays.  ``pose`` (4, 4) world_T_sensor of a sensor that does
    not move, identity by default; or, with ``pose_t`` (K,), poses (K, 4, 4) sampled
    then.  Every point is at ``stamp`` unless per-point times ``t`` are given."""
    n = len(points)
    if pose_t is None:
        pose_t = np.array([stamp])
        poses = (np.eye(4) if pose is None else np.asarray(pose, dtype=np.float64))[None]
    else:
        assert pose is not None
        poses = np.asarray(pose, dtype=np.float64)
    return Frame(
        stamp=stamp,
        duration=duration,
        points=np.asarray(points, dtype=np.float64).reshape(n, 3),
        t=np.full(n, stamp) if t is None else np.asarray(t, dtype=np.float64),
        line=np.zeros(n, np.uint8) if line is None else np.asarray(line, dtype=np.uint8),
        intensity=(
            np.zeros(n, np.float32) if intensity is None else np.asarray(intensity, np.float32)
        ),
        pose_t=pose_t,
        poses=poses,
    )
