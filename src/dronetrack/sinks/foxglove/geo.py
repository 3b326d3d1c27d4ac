"""Tracks and zones on Foxglove's Map panel, for a run with a ``[site]``.

Topics (a user contract), written by the MCAP file and the live server alike:

- ``/tracks/fix`` (``foxglove.LocationFix``): one message per track per tracking frame:
  ``frame_id`` ``track/<id>``, WGS-84 latitude, longitude and altitude, the position
  covariance in ENU [m²] (``KNOWN``: the track's own, turned into ENU), its
  velocity in ENU, its heading, its class colour and metadata ``id``, ``class``,
  ``p_drone`` and ``locked``;
- ``/zones`` (``foxglove.GeoJson``): the protected zones as a GeoJSON
  FeatureCollection, a polygon each (a circle as 128 edges) with properties ``name``
  and ``kind`` (``zone``, or ``margin`` for its warning band); written with the first
  frame and again every ``ZONES_EVERY_S`` s, so a viewer that joins late sees them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from dronetrack.geometry.geodesy import SiteFrame
from dronetrack.sinks.view import TRACK_RGB
from dronetrack.types import Tracks
from dronetrack.zones import Zone

if TYPE_CHECKING:
    from foxglove.messages import LocationFix, Timestamp

__all__ = [
    "FIX_TOPIC",
    "ZONES_EVERY_S",
    "ZONES_TOPIC",
    "SiteView",
    "track_fixes",
    "zones_geojson",
]

FIX_TOPIC = "/tracks/fix"
ZONES_TOPIC = "/zones"
ZONES_EVERY_S = 5.0


@dataclass(frozen=True, slots=True)
class SiteView:
    """What the map needs: the world frame on the Earth and the zones in it."""

    site: SiteFrame
    zones: tuple[Zone, ...] = ()


def _ring(site: SiteFrame, xy: Any) -> list[list[float]]:
    """A world (x, y) ring as GeoJSON [lon, lat] pairs at the site's altitude."""
    xy = np.asarray(xy, dtype=np.float64)
    p = np.column_stack([xy, np.full(len(xy), site.base[2])])
    lat, lon, _ = site.geodetic(p)
    return [[float(a), float(b)] for a, b in zip(lon, lat, strict=True)]


def zones_geojson(view: SiteView) -> str:
    """The zones (and their margins) as a GeoJSON FeatureCollection."""
    features = []
    for zone in view.zones:
        shapes = [("zone", zone.shape)]
        if zone.band is not None:
            shapes.append(("margin", zone.band))
        for kind, shape in shapes:
            features.append(
                {
                    "type": "Feature",
                    "properties": {"name": zone.name, "kind": kind},
                    "geometry": {
                        "type": "Polygon",
                        "coordinates": [_ring(view.site, shape.exterior.coords)],
                    },
                }
            )
    return json.dumps({"type": "FeatureCollection", "features": features})


def track_fixes(tracks: Tracks, site: SiteFrame, stamp: Timestamp) -> list[LocationFix]:
    """One ``LocationFix`` per track."""
    from foxglove.messages import (
        Color,
        LocationFix,
        LocationFixPositionCovarianceType,
        Vector3,
    )

    if len(tracks) == 0:
        return []
    lat, lon, alt = site.geodetic(tracks.positions)
    cov = site.enu_covariance(tracks.covariances[:, :3, :3])
    vel = site.enu_vectors(tracks.velocities)
    names = tracks.class_names
    fixes = []
    for k in range(len(tracks)):
        r, g, b = (c / 255.0 for c in TRACK_RGB[names[k]])
        ve, vn = float(vel[k, 0]), float(vel[k, 1])
        fixes.append(
            LocationFix(
                timestamp=stamp,
                frame_id=f"track/{int(tracks.ids[k])}",
                latitude=float(lat[k]),
                longitude=float(lon[k]),
                altitude=float(alt[k]),
                position_covariance=[float(c) for c in cov[k].ravel()],
                position_covariance_type=LocationFixPositionCovarianceType.Known,
                # heading: clockwise from north, atan2(v_e, v_n)
                heading=math.atan2(ve, vn) if math.hypot(ve, vn) > 0.1 else None,
                velocity=Vector3(x=ve, y=vn, z=float(vel[k, 2])),
                color=Color(r=r, g=g, b=b, a=1.0),
                metadata=_metadata(tracks, names, k),
            )
        )
    return fixes


def _metadata(tracks: Tracks, names: Sequence[str], k: int) -> list[Any]:
    from foxglove.messages import KeyValuePair

    values = {
        "id": str(int(tracks.ids[k])),
        "class": names[k],
        "p_drone": f"{float(tracks.p_drone[k]):.3f}" if len(tracks.p_drone) else "nan",
        "locked": str(bool(tracks.locked[k])).lower(),
    }
    return [KeyValuePair(key=key, value=value) for key, value in values.items()]
