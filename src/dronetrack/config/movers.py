"""Walkers and vehicles in a scenario (``[[walkers]]``, ``[[vehicles]]``): people and cars
on the ground, each labelled in the truth (``sim/movers.py`` moves and casts them)."""

from __future__ import annotations

from typing import Self

from pydantic import Field, model_validator

from dronetrack.config.pipeline import StrictModel

__all__ = ["MAX_VEHICLE_SPEED_M_S", "MAX_WALKER_SPEED_M_S", "VehicleConfig", "WalkerConfig"]

Pair = tuple[float, float]
MAX_WALKER_SPEED_M_S = 5.0  # a run, not a walk, beyond this
MAX_VEHICLE_SPEED_M_S = 40.0
MAX_EXTENT_M = 10_000.0  # coordinates within 10 km of the turret base
MIN_AREA_SIDE_M = 2.0  # a walker's area is at least this wide each way
MAX_PAUSE_S = 3600.0


class WalkerConfig(StrictModel):
    """``count`` people walking in ``area_m`` (x0, y0, x1, y1) on the ground from the start
    of the run (the background scan too): between random waypoints, each leg at a speed
    drawn from ``speed_m_s``, pausing a time drawn from ``pause_s`` at each waypoint."""

    count: int = Field(1, ge=1, le=100)
    area_m: tuple[float, float, float, float]
    speed_m_s: Pair = (1.0, 1.6)
    pause_s: Pair = (0.0, 5.0)

    @model_validator(mode="after")
    def _check(self) -> Self:
        x0, y0, x1, y1 = self.area_m
        if not (x1 - x0 >= MIN_AREA_SIDE_M and y1 - y0 >= MIN_AREA_SIDE_M):
            raise ValueError(
                f"area_m must be (x0, y0, x1, y1) with x1 − x0 and y1 − y0 at least "
                f"{MIN_AREA_SIDE_M:g} m, got {x0:g}, {y0:g}, {x1:g}, {y1:g}"
            )
        if max(abs(v) for v in self.area_m) > MAX_EXTENT_M:
            raise ValueError(f"area_m must lie within {MAX_EXTENT_M:g} m of the turret base")
        lo, hi = self.speed_m_s
        if not 0 < lo <= hi <= MAX_WALKER_SPEED_M_S:
            raise ValueError(
                f"speed_m_s must be (low, high) with 0 < low ≤ high ≤ {MAX_WALKER_SPEED_M_S:g} "
                f"m/s, got {lo:g}, {hi:g}"
            )
        lo, hi = self.pause_s
        if not 0 <= lo <= hi <= MAX_PAUSE_S:
            raise ValueError(
                f"pause_s must be (low, high) with 0 ≤ low ≤ high ≤ {MAX_PAUSE_S:g} s, "
                f"got {lo:g}, {hi:g}"
            )
        return self


class VehicleConfig(StrictModel):
    """A car that drives ``path_m`` (points (x, y) on the ground), stopping at each, and
    parks at the last one ``arrive_s`` seconds into the flight (counted as ``duration_s``
    is: from the end of the background scan in ``simulate``), where it stays.  It enters
    the world at the first point as late as that allows; before, it is not there."""

    path_m: tuple[Pair, ...] = Field(min_length=2)
    arrive_s: float = Field(0.0, ge=0)
    speed_m_s: float = Field(5.0, gt=0, le=MAX_VEHICLE_SPEED_M_S)
    size_m: tuple[float, float, float] = (4.5, 1.8, 1.5)  # length, width, height
    reflectivity: float = Field(0.4, gt=0, le=1)  # the paint's, at 905 nm

    @model_validator(mode="after")
    def _check(self) -> Self:
        if any(abs(v) > MAX_EXTENT_M for point in self.path_m for v in point):
            raise ValueError(f"path_m must lie within {MAX_EXTENT_M:g} m of the turret base")
        if not all(0 < s <= 20.0 for s in self.size_m):
            raise ValueError(f"size_m must be 3 lengths in (0, 20] m, got {self.size_m}")
        return self
