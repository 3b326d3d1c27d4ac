"""The parts every SAPIENT message shares: IDs, timestamps, the envelope, WGS-84
locations and range-bearings.

Conventions, from the .proto comments: locations are ``LAT_LNG_DEG_M`` on the WGS-84
ellipsoid (x longitude, y latitude [°], z altitude [m]), their errors in the same
units (1σ); range-bearing is ``DEGREES_M`` from true north.  Node IDs are UUIDs
(version 4, lower case, as Apex's strict ID check wants them); report, object, task
and alert IDs are ULIDs (``new_ulid``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from google.protobuf.timestamp_pb2 import Timestamp
from numpy.typing import ArrayLike
from ulid import ULID

from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0 import location_pb2, range_bearing_pb2
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)

__all__ = [
    "DEG_M",
    "LAT_LNG_DEG_M",
    "TRUE_NORTH",
    "WGS84_A",
    "WGS84_E",
    "RangeBearing",
    "envelope",
    "metres_to_degrees",
    "new_ulid",
    "timestamp",
    "wgs84_location",
]

LAT_LNG_DEG_M = location_pb2.LOCATION_COORDINATE_SYSTEM_LAT_LNG_DEG_M
WGS84_E = location_pb2.LOCATION_DATUM_WGS84_E
DEG_M = range_bearing_pb2.RANGE_BEARING_COORDINATE_SYSTEM_DEGREES_M
TRUE_NORTH = range_bearing_pb2.RANGE_BEARING_DATUM_TRUE
WGS84_A = 6378137.0  # the ellipsoid's semi-major axis [m], for errors in degrees only


def new_ulid(rng: np.random.Generator, t_unix_s: float) -> str:
    """A ULID: 48 bits of Unix milliseconds, then 80 random bits from ``rng``."""
    ms = max(0, int(t_unix_s * 1000.0))
    return str(ULID.from_bytes(ms.to_bytes(6, "big") + rng.bytes(10)))


def timestamp(t_unix_s: float) -> Timestamp:
    """A protobuf Timestamp of a Unix time [s], to the nanosecond."""
    stamp = Timestamp()
    sec = math.floor(t_unix_s)
    stamp.seconds, stamp.nanos = sec, min(round((t_unix_s - sec) * 1e9), 999_999_999)
    return stamp


def envelope(node_id: str, t_unix_s: float, destination: str | None = None) -> SapientMessage:
    """An empty message from ``node_id``, stamped ``t_unix_s``: fill one content field."""
    msg = SapientMessage(node_id=node_id, timestamp=timestamp(t_unix_s))
    if destination is not None:
        msg.destination_id = destination
    return msg


def metres_to_degrees(lat_deg: float, east_m: float, north_m: float) -> tuple[float, float]:
    """East and north lengths [m] at latitude ``lat_deg`` as degrees of longitude and
    latitude, on a sphere of the ellipsoid's radius a: Δλ = e / (a cos φ), Δφ = n / a
    (for errors, which need no better)."""
    phi = math.radians(lat_deg)
    return (
        math.degrees(east_m / (WGS84_A * max(math.cos(phi), 1e-9))),
        math.degrees(north_m / WGS84_A),
    )


def wgs84_location(
    lat: float, lon: float, alt: float, sigma_enu: ArrayLike | None = None
) -> location_pb2.Location:
    """A WGS-84 Location (x longitude, y latitude [°], z altitude [m]); ``sigma_enu``:
    1σ east, north, up [m], carried as errors in the location's own units (east and
    north as degrees of longitude and latitude at ``lat``, up in metres)."""
    loc = location_pb2.Location(x=lon, y=lat, z=alt, coordinate_system=LAT_LNG_DEG_M, datum=WGS84_E)
    if sigma_enu is not None:
        east, north, up = (float(a) for a in np.asarray(sigma_enu, dtype=np.float64)[:3])
        loc.x_error, loc.y_error = metres_to_degrees(lat, east, north)
        loc.z_error = up
    return loc


@dataclass(frozen=True, slots=True)
class RangeBearing:
    """Azimuth from true north and elevation [°], range [m], and their 1σ errors."""

    azimuth: float
    elevation: float
    range: float
    azimuth_error: float | None = None
    elevation_error: float | None = None
    range_error: float | None = None
