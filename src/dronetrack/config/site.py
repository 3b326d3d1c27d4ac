"""A site in the world: where the turret stands on the Earth (``[site]``), and the zones it
protects (``[[zones]]``).

``[site]`` gives the WGS-84 position of the turret base (the foot of its pan axis) and
``heading_deg``, the bearing of the world x axis from true north (clockwise, as a
compass reads).  With it every track also has a latitude, longitude and altitude, and
an azimuth, elevation and range from the turret (``geometry.geodesy.SiteFrame``).

A ``[[zones]]`` entry is a protected area: a polygon of ``[lat, lon]`` vertices, or a
circle (``centre`` and ``radius_m``), between an optional ``floor_m`` and
``ceiling_m`` above the turret base's ground.  Its warning margin is ``margin_m``
(a band around it) and ``margin_s`` (the time in which a drone would enter it at its
present velocity); a zone has one or both.  ``zones.alerts`` raises the alerts.

``[sapient]`` names the node to a SAPIENT fusion node (``--sapient``): its UUID, name
and status period.
"""

from __future__ import annotations

from typing import Self

from pydantic import Field, model_validator

from dronetrack.config.pipeline import StrictModel

__all__ = ["LatLon", "SapientConfig", "SiteConfig", "ZoneConfig", "polygon_problem"]

LatLon = tuple[float, float]  # (latitude, longitude) [°]

_Lat = Field(ge=-90.0, le=90.0, allow_inf_nan=False)
_Lon = Field(ge=-180.0, le=180.0, allow_inf_nan=False)


class SiteConfig(StrictModel):
    """``[site]``: the turret base's WGS-84 position and the world frame's heading."""

    latitude_deg: float = _Lat
    longitude_deg: float = _Lon
    altitude_m: float = Field(0.0, ge=-500.0, le=9000.0, allow_inf_nan=False)  # ellipsoidal
    heading_deg: float = Field(0.0, ge=-360.0, le=360.0, allow_inf_nan=False)  # world x, from N


class SapientConfig(StrictModel):
    """``[sapient]``: the node as a SAPIENT fusion node sees it (``--sapient``)."""

    # The node's UUID, a lower-case version 4 as dstl's Apex middleware checks node
    # IDs; by default one fixed by the site's name and place
    node_id: str | None = Field(
        None, pattern=r"^[0-9a-f]{8}-[0-9a-f]{4}-4[0-9a-f]{3}-[89ab][0-9a-f]{3}-[0-9a-f]{12}$"
    )
    name: str = Field("dronetrack", min_length=1, max_length=200)
    status_period_s: float = Field(5.0, gt=0, le=3600, allow_inf_nan=False)


class ZoneConfig(StrictModel):
    """``[[zones]]``: a protected area with its warning margin."""

    name: str = Field(min_length=1)
    polygon: tuple[LatLon, ...] | None = None  # [[lat, lon], ...], in order around it
    centre: LatLon | None = None
    radius_m: float | None = Field(None, gt=0, allow_inf_nan=False)
    floor_m: float | None = Field(None, allow_inf_nan=False)  # above the turret's ground [m]
    ceiling_m: float | None = Field(None, allow_inf_nan=False)
    margin_m: float | None = Field(None, ge=0, allow_inf_nan=False)
    margin_s: float | None = Field(None, gt=0, le=3600, allow_inf_nan=False)

    @model_validator(mode="after")
    def _one_shape_and_a_margin(self) -> Self:
        if (self.polygon is None) == (self.centre is None):
            raise ValueError(
                f"zone {self.name!r}: give either polygon = [[lat, lon], ...] or "
                "centre = [lat, lon] with radius_m"
            )
        if self.centre is not None and self.radius_m is None:
            raise ValueError(f"zone {self.name!r}: a circle needs radius_m")
        if self.polygon is not None and self.radius_m is not None:
            raise ValueError(f"zone {self.name!r}: radius_m belongs to a circle, not a polygon")
        for lat, lon in (*(self.polygon or ()), *((self.centre,) if self.centre else ())):
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
                raise ValueError(
                    f"zone {self.name!r}: [{lat:g}, {lon:g}] is no [latitude, longitude] in "
                    "degrees (latitude first)"
                )
        if self.polygon is not None:
            problem = polygon_problem(self.polygon)
            if problem is not None:
                raise ValueError(f"zone {self.name!r}: {problem}")
        if self.margin_m is None and self.margin_s is None:
            raise ValueError(
                f"zone {self.name!r}: give its warning margin, margin_m [m] or margin_s [s]"
            )
        if (
            self.floor_m is not None
            and self.ceiling_m is not None
            and self.ceiling_m <= self.floor_m
        ):
            raise ValueError(
                f"zone {self.name!r}: ceiling_m = {self.ceiling_m:g} is not above "
                f"floor_m = {self.floor_m:g}"
            )
        return self


def polygon_problem(vertices: tuple[LatLon, ...]) -> str | None:
    """Why ``vertices`` make no zone (fewer than 3 distinct vertices, no area, or edges
    that cross), or None.  Checked in (longitude, latitude) degrees: straight edges at a
    site's scale."""
    from shapely.geometry import Polygon

    distinct = {(float(a), float(b)) for a, b in vertices}
    if len(distinct) < 3:
        return f"a polygon needs at least 3 distinct vertices, not {len(distinct)}"
    shape = Polygon([(lon, lat) for lat, lon in vertices])
    lo_x, lo_y, hi_x, hi_y = shape.bounds
    if shape.convex_hull.area <= 1e-9 * max(hi_x - lo_x, hi_y - lo_y) ** 2:  # to rounding
        return "its vertices lie on one line"
    if not shape.exterior.is_simple:
        return "its edges cross each other; give the vertices in order around the zone"
    return None
