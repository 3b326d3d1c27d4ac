"""A protected zone in the world frame: a horizontal shape between a floor and a
ceiling, with a warning margin around it.

The geometry in the plane is shapely's (GEOS): containment, distance and where a
straight path crosses the shape.  Heights are world z [m], the ground at the turret
being 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from shapely import LineString, Point, Polygon

__all__ = ["Zone", "circle", "entry_time"]

# A circle's polygon: 4 × 32 edges, within r (1 − cos(π/128)) ≈ 3e-4 r of the circle
QUAD_SEGS = 32


@dataclass(frozen=True, slots=True)
class Zone:
    """``shape``: the zone's outline in world (x, y) [m]; ``floor``, ``ceiling``: its
    heights (world z) [m], −inf and inf when open; ``margin_m``: the warning band
    around it [m] (0: none); ``margin_s``: how far ahead a drone's present velocity is
    followed to warn that it will enter [s] (0: not)."""

    name: str
    shape: Polygon
    floor: float = -math.inf
    ceiling: float = math.inf
    margin_m: float = 0.0
    margin_s: float = 0.0
    band: Any = None  # the shape grown by margin_m (a shapely geometry), set in __post_init__

    def __post_init__(self) -> None:
        band = self.shape.buffer(self.margin_m, quad_segs=QUAD_SEGS) if self.margin_m else None
        object.__setattr__(self, "band", band)

    def contains(self, p: ArrayLike) -> bool:
        """Whether world point ``p`` (3,) is inside the zone (its boundary included)."""
        x, y, z = (float(a) for a in np.asarray(p, dtype=np.float64))
        return self.floor <= z <= self.ceiling and bool(self.shape.covers(Point(x, y)))

    def in_margin(self, p: ArrayLike) -> bool:
        """Whether world point ``p`` (3,) is within ``margin_m`` of the zone (and not
        only of its outline in the plane: the floor and the ceiling move out too)."""
        if self.band is None:
            return False
        x, y, z = (float(a) for a in np.asarray(p, dtype=np.float64))
        m = self.margin_m
        return self.floor - m <= z <= self.ceiling + m and bool(self.band.covers(Point(x, y)))

    def distance(self, p: ArrayLike) -> float:
        """The distance [m] from world point ``p`` to the zone, 0 inside:
        d = √(d_xy² + d_z²), with d_xy to the outline in the plane and d_z to the
        floor-ceiling band."""
        x, y, z = (float(a) for a in np.asarray(p, dtype=np.float64))
        d_xy = float(self.shape.distance(Point(x, y)))
        d_z = max(self.floor - z, z - self.ceiling, 0.0)
        return math.hypot(d_xy, d_z)


def circle(name: str, centre: tuple[float, float], radius: float, **kw: Any) -> Zone:
    """A round zone about world (x, y) ``centre`` with ``radius`` [m]."""
    return Zone(name, Point(*centre).buffer(radius, quad_segs=QUAD_SEGS), **kw)


def entry_time(zone: Zone, p: ArrayLike, v: ArrayLike, horizon: float) -> float:
    """When the straight path p + v t first enters ``zone`` within ``horizon`` s
    (0 if p is inside it; inf if it does not enter).

    In the plane the path's pieces inside the shape are shapely's intersection of the
    segment p_xy → p_xy + v_xy T with it; in height the path is inside while
    floor ≤ z + v_z t ≤ ceiling.  The answer is the earliest t in both.
    """
    p = np.asarray(p, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(v))) or horizon <= 0:
        return math.inf
    if zone.contains(p):
        return 0.0
    lo, hi = _height_window(float(p[2]), float(v[2]), zone.floor, zone.ceiling, horizon)
    if lo > hi:
        return math.inf
    speed_xy = math.hypot(float(v[0]), float(v[1]))
    start = Point(float(p[0]), float(p[1]))
    if speed_xy < 1e-9:  # still in the plane: inside it for all t or none
        return lo if zone.shape.covers(start) else math.inf
    end = (float(p[0] + v[0] * horizon), float(p[1] + v[1] * horizon))
    path = LineString([(start.x, start.y), end])
    best = math.inf
    for piece in _lines(path.intersection(zone.shape)):
        # t of a point on the path: its distance from the start over the speed in the plane
        ts = sorted(start.distance(Point(c)) / speed_xy for c in piece.coords)
        t0, t1 = max(ts[0], lo), min(ts[-1], hi)
        if t0 <= t1:
            best = min(best, t0)
    return best


def _height_window(
    z: float, vz: float, floor: float, ceiling: float, horizon: float
) -> tuple[float, float]:
    """The times t in [0, horizon] at which floor ≤ z + v_z t ≤ ceiling (lo > hi: none)."""
    if abs(vz) < 1e-12:
        return (0.0, horizon) if floor <= z <= ceiling else (1.0, 0.0)
    # t = (h − z) / v_z at each of the band's two heights
    a, b = (floor - z) / vz, (ceiling - z) / vz
    lo, hi = min(a, b), max(a, b)
    return max(lo, 0.0), min(hi, horizon)


def _lines(geometry: Any) -> list[Any]:
    """The line pieces of a shapely intersection (points, where the path only touches a
    corner, are pieces of no length)."""
    if geometry.is_empty:
        return []
    if geometry.geom_type in ("LineString", "Point"):
        return [geometry]
    return [g for g in getattr(geometry, "geoms", []) if g.geom_type in ("LineString", "Point")]
