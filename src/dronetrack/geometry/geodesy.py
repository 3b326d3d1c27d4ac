"""WGS-84 geodetic coordinates to a local east-north-up (ENU) frame.

Seed 000's outdoor ground truth is the drone's GNSS fix (``sensor_msgs/NavSatFix``);
to compare it with the tracker it is expressed in a local frame at the sensor
site, optionally turned about z so that the frame's x axis points along a given
heading.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.geometry.transforms import FloatArray, rot_z

__all__ = ["WGS84_A", "WGS84_F", "enu_from_geodetic", "geodetic_to_ecef"]

WGS84_A = 6378137.0  # semi-major axis [m]
WGS84_F = 1.0 / 298.257223563  # flattening
_E2 = WGS84_F * (2.0 - WGS84_F)  # first eccentricity squared: e² = f (2 − f)


def geodetic_to_ecef(lat_deg: ArrayLike, lon_deg: ArrayLike, alt_m: ArrayLike) -> FloatArray:
    """Earth-centred, Earth-fixed coordinates (..., 3) [m] of latitude, longitude [°]
    and height above the ellipsoid [m]."""
    lat = np.radians(np.asarray(lat_deg, dtype=np.float64))
    lon = np.radians(np.asarray(lon_deg, dtype=np.float64))
    h = np.asarray(alt_m, dtype=np.float64)
    # N = a / √(1 − e² sin² φ), the prime-vertical radius of curvature
    N = WGS84_A / np.sqrt(1.0 - _E2 * np.sin(lat) ** 2)
    # x = (N + h) cos φ cos λ,  y = (N + h) cos φ sin λ,  z = (N (1 − e²) + h) sin φ
    x = (N + h) * np.cos(lat) * np.cos(lon)
    y = (N + h) * np.cos(lat) * np.sin(lon)
    z = (N * (1.0 - _E2) + h) * np.sin(lat)
    return np.stack([x, y, z], axis=-1)


def enu_from_geodetic(
    lat_deg: ArrayLike,
    lon_deg: ArrayLike,
    alt_m: ArrayLike,
    origin: tuple[float, float, float],
    heading_deg: float = 0.0,
) -> FloatArray:
    """Positions (..., 3) [m] in the ENU frame at ``origin`` (lat°, lon°, alt m).

    With ``heading_deg`` ψ the local frame's x axis points ψ counter-clockwise from
    east (a yaw about up), so p = Rz(−ψ) p_ENU.
    """
    lat0, lon0, _ = origin
    d = geodetic_to_ecef(lat_deg, lon_deg, alt_m) - geodetic_to_ecef(*origin)
    phi, lam = np.radians(lat0), np.radians(lon0)
    # Rows of the ECEF → ENU rotation:
    #   e = (−sin λ, cos λ, 0)
    #   n = (−sin φ cos λ, −sin φ sin λ, cos φ)
    #   u = ( cos φ cos λ,  cos φ sin λ, sin φ)
    R = np.array(
        [
            [-np.sin(lam), np.cos(lam), 0.0],
            [-np.sin(phi) * np.cos(lam), -np.sin(phi) * np.sin(lam), np.cos(phi)],
            [np.cos(phi) * np.cos(lam), np.cos(phi) * np.sin(lam), np.sin(phi)],
        ]
    )
    enu = d @ R.T
    if heading_deg:
        enu = enu @ rot_z(-np.radians(heading_deg)).T
    out: FloatArray = enu
    return out
