"""WGS-84 geodetic coordinates and the local world frame, through pymap3d.

Two users:

- Seed 000's outdoor ground truth is the drone's GNSS fix (``sensor_msgs/NavSatFix``);
  ``enu_from_geodetic`` expresses it in a local east-north-up (ENU) frame at the
  sensor site, optionally turned about up so that the frame's x axis points along a
  given yaw from east (``--gt-origin``, ``--gt-heading``).
- A site (``[site]``, ``config/site.py``) places the world frame on the Earth:
  ``SiteFrame`` turns world positions into latitude, longitude and altitude, and into
  azimuth (from true north), elevation and range from the turret base.

The geodesy itself (ellipsoid, ECEF, ENU, AER) is pymap3d's; here is only the yaw
between the world frame and ENU.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymap3d
from numpy.typing import ArrayLike

from dronetrack.geometry.transforms import FloatArray, rot_z

__all__ = ["SiteFrame", "enu_from_geodetic"]


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
    e, n, u = pymap3d.geodetic2enu(
        np.asarray(lat_deg, dtype=np.float64),
        np.asarray(lon_deg, dtype=np.float64),
        np.asarray(alt_m, dtype=np.float64),
        *origin,
    )
    enu = np.stack(np.broadcast_arrays(e, n, u), axis=-1).astype(np.float64)
    if heading_deg:
        enu = enu @ rot_z(-math.radians(heading_deg)).T
    out: FloatArray = enu
    return out


@dataclass(frozen=True, slots=True)
class SiteFrame:
    """The world frame on the Earth.

    The turret base (world point ``base``) stands at ``latitude_deg``,
    ``longitude_deg``, ``altitude_m`` (WGS-84, height above the ellipsoid); the world x
    axis points along the bearing ``heading_deg`` ψ from true north (clockwise), and z
    up.  So the world frame is ENU turned about up by θ = 90° − ψ (x from east,
    counter-clockwise): p_ENU = Rz(θ) (p − base).
    """

    latitude_deg: float
    longitude_deg: float
    altitude_m: float
    heading_deg: float = 0.0
    base: tuple[float, float, float] = (0.0, 0.0, 0.0)

    @property
    def _rotation(self) -> FloatArray:
        # θ = 90° − ψ: the yaw of world x from east, counter-clockwise
        return rot_z(math.radians(90.0 - self.heading_deg))

    @property
    def _origin(self) -> tuple[float, float, float]:
        return (self.latitude_deg, self.longitude_deg, self.altitude_m)

    def enu_vectors(self, v: ArrayLike) -> FloatArray:
        """Directions, velocities (..., 3) of the world frame in ENU: Rz(θ) v."""
        out: FloatArray = np.asarray(v, dtype=np.float64) @ self._rotation.T
        return out

    def enu_covariance(self, P: ArrayLike) -> FloatArray:
        """Covariances (..., 3, 3) of world positions or velocities in ENU: R P Rᵀ."""
        R = self._rotation
        out: FloatArray = R @ np.asarray(P, dtype=np.float64) @ R.T
        return out

    def enu(self, p: ArrayLike) -> FloatArray:
        """World positions (..., 3) [m] in the ENU frame at the turret base."""
        return self.enu_vectors(np.asarray(p, dtype=np.float64) - np.asarray(self.base))

    def world(self, enu: ArrayLike) -> FloatArray:
        """ENU positions (..., 3) at the turret base in the world frame: base + Rzᵀ enu."""
        out: FloatArray = np.asarray(enu, dtype=np.float64) @ self._rotation + np.asarray(self.base)
        return out

    def geodetic(self, p: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Latitude [°], longitude [°] and altitude [m] (WGS-84) of world positions (..., 3)."""
        enu = self.enu(p)
        lat, lon, alt = pymap3d.enu2geodetic(enu[..., 0], enu[..., 1], enu[..., 2], *self._origin)
        return _f64(lat), _f64(lon), _f64(alt)

    def from_geodetic(self, lat_deg: ArrayLike, lon_deg: ArrayLike, alt_m: ArrayLike) -> FloatArray:
        """World positions (..., 3) of WGS-84 latitudes, longitudes [°] and altitudes [m]."""
        return self.world(enu_from_geodetic(lat_deg, lon_deg, alt_m, self._origin))

    def aer(self, p: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Azimuth from true north [°, 0-360, clockwise], elevation above the local
        horizontal [°] and slant range [m] of world positions (..., 3) from the turret
        base."""
        enu = self.enu(p)
        az, el, rng = pymap3d.enu2aer(enu[..., 0], enu[..., 1], enu[..., 2])
        return _f64(az), _f64(el), _f64(rng)

    def from_aer(self, az_deg: ArrayLike, el_deg: ArrayLike, range_m: ArrayLike) -> FloatArray:
        """World positions (..., 3) at azimuth [°, from true north], elevation [°] and
        range [m] from the turret base."""
        e, n, u = pymap3d.aer2enu(
            np.asarray(az_deg, dtype=np.float64),
            np.asarray(el_deg, dtype=np.float64),
            np.asarray(range_m, dtype=np.float64),
        )
        return self.world(np.stack(np.broadcast_arrays(e, n, u), axis=-1))


def _f64(a: ArrayLike) -> FloatArray:
    out: FloatArray = np.asarray(a, dtype=np.float64)
    return out
