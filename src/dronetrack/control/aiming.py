"""Pan and tilt angles that put a world point on the sensor's optical axis.

Seed 000's eq. (10) for a sensor at the turret's pivot:

    α = atan2(y, x),    β = −atan2(z, √(x² + y²))

generalised to the mount's offsets.  Pan: the axis runs parallel to the panned
x axis at lateral offset d_y, so the target (a, b) relative to the pan axis must
satisfy −a sin α + b cos α = d_y:

    α = atan2(b, a) − asin(d_y / √(a² + b²))

Tilt: in the panned x-z plane the axis passes at perpendicular offset s_z from
the tilt pivot, so the target (u, w) relative to the pivot satisfies
u sin β + w cos β = s_z:

    β = asin(s_z / √(u² + w²)) − atan2(w, u)
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.geometry.mount import MountGeometry
from dronetrack.geometry.transforms import rot_z

__all__ = ["aim_angles"]


def aim_angles(target: ArrayLike, mount: MountGeometry) -> tuple[float, float]:
    """(pan, tilt) [rad] that point the sensor's x axis at ``target`` (3,) in the world."""
    p = np.asarray(target, dtype=np.float64) - mount.base_vec
    d_y = mount.pan_to_tilt[1] + mount.tilt_to_sensor[1]
    rho = float(np.hypot(p[0], p[1]))
    pan = float(np.arctan2(p[1], p[0]))
    if rho > abs(d_y):
        pan -= float(np.arcsin(d_y / rho))
    # Target relative to the tilt pivot, in the panned frame.
    rel = rot_z(pan).T @ (p - rot_z(pan) @ mount.pan_to_tilt_vec)
    u, w = float(rel[0]), float(rel[2])
    s_z = mount.tilt_to_sensor[2]
    r0 = float(np.hypot(u, w))
    tilt = -float(np.arctan2(w, u))
    if r0 > abs(s_z):
        tilt += float(np.arcsin(s_z / r0))
    return pan, tilt
