"""The field of regard: the region a site watches, as the turret sees it.

A point p belongs to it when, seen from the turret base b (d = p − b),

    pan  = atan2(d_y, d_x)           ∈ [pan_lo, pan_hi]
    tilt = −atan2(d_z, √(d_x² + d_y²)) ∈ [tilt_lo, tilt_hi]   (negative looks up)
    ‖d‖ ≤ range

with the turret's own angle conventions (``geometry.mount``), so a pan range of
[−π, π] is the full circle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray, azimuth_elevation

__all__ = ["FieldOfRegard", "in_field_of_view", "wrap_angle"]


def wrap_angle(a: FloatArray | float) -> FloatArray:
    """Angles [rad] wrapped into [−π, π)."""
    wrapped: FloatArray = (np.asarray(a, dtype=np.float64) + math.pi) % (2.0 * math.pi) - math.pi
    return wrapped


def in_field_of_view(
    points: FloatArray, pose: FloatArray, fov: tuple[float, float]
) -> NDArray[np.bool_]:
    """(K,) whether each world point (K, 3) [m] lies in the field of view of a sensor at
    ``pose`` (4, 4: sensor to world), looking along its x axis, ``fov`` (horizontal,
    vertical) wide [rad]: within the ellipse of those half-widths in azimuth and
    elevation, d = Rᵀ (p − o) in the sensor's frame,

        (az / (h/2))² + (el / (v/2))² ≤ 1,  az = atan2(d_y, d_x),
        el = atan2(d_z, √(d_x² + d_y²))

    (a rosette's field is round)."""
    d = (np.asarray(points, dtype=np.float64) - pose[:3, 3]) @ pose[:3, :3]
    az, el = azimuth_elevation(d)
    h, v = fov
    out: NDArray[np.bool_] = (az / (0.5 * h)) ** 2 + (el / (0.5 * v)) ** 2 <= 1.0
    return out


@dataclass(frozen=True, slots=True)
class FieldOfRegard:
    """Pan and tilt ranges [rad] and a range limit [m] around ``base`` (3,) [m]."""

    pan: tuple[float, float]
    tilt: tuple[float, float]
    range_m: float
    base: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        lo, hi = self.pan
        if not (lo < hi and hi - lo <= 2.0 * math.pi + 1e-9):
            raise ValueError(f"pan range must satisfy lo < hi ≤ lo + 2π, got {self.pan}")
        if not (-math.pi / 2 <= self.tilt[0] < self.tilt[1] <= math.pi / 2):
            raise ValueError(f"tilt range must satisfy −π/2 ≤ lo < hi ≤ π/2, got {self.tilt}")
        if not self.range_m > 0.0:
            raise ValueError(f"range must be positive, got {self.range_m}")

    @property
    def full_circle(self) -> bool:
        return self.pan[1] - self.pan[0] >= 2.0 * math.pi - 1e-9

    def angles(self, points: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(pan, tilt, range) of points (N, 3) seen from the base."""
        d = np.atleast_2d(np.asarray(points, dtype=np.float64)) - np.asarray(self.base)
        rho = np.hypot(d[:, 0], d[:, 1])
        return np.arctan2(d[:, 1], d[:, 0]), -np.arctan2(d[:, 2], rho), np.linalg.norm(d, axis=1)

    def contains(self, points: FloatArray) -> NDArray[np.bool_]:
        """(N,) True where a point lies inside (NaN points are outside)."""
        pan, tilt, r = self.angles(points)
        # The pan offset from the range's start, wrapped into [0, 2π): inside up to the span.
        offset = (pan - self.pan[0]) % (2.0 * math.pi)
        in_pan = self.full_circle | (offset <= self.pan[1] - self.pan[0])
        inside: NDArray[np.bool_] = (
            in_pan & (tilt >= self.tilt[0]) & (tilt <= self.tilt[1]) & (r <= self.range_m)
        )
        return inside

    def bounding_box(self, floor_z: float) -> tuple[FloatArray, FloatArray]:
        """The smallest axis-aligned box [m] around the field, with its bottom raised to
        ``floor_z`` where that is higher (the ground is never worth keeping)."""
        # The extremes lie on the boundary: the base, and the far cap's edge at the
        # range's pan ends and at every multiple of π/2 in between, at both tilt ends
        # and at the horizon if it is inside the tilt range.
        quarter = math.pi / 2
        k = np.arange(math.ceil(self.pan[0] / quarter), math.floor(self.pan[1] / quarter) + 1)
        pans = np.concatenate([[self.pan[0], self.pan[1]], k * quarter])
        tilts = [self.tilt[0], self.tilt[1]] + ([0.0] if self.tilt[0] < 0.0 < self.tilt[1] else [])
        a, e = np.meshgrid(pans, -np.asarray(tilts))  # e: elevation
        r = self.range_m
        cap = np.column_stack(
            [
                (r * np.cos(e) * np.cos(a)).ravel(),
                (r * np.cos(e) * np.sin(a)).ravel(),
                (r * np.sin(e)).ravel(),
            ]
        )
        corners = np.vstack([cap, np.zeros((1, 3))]) + np.asarray(self.base)
        lo, hi = corners.min(axis=0), corners.max(axis=0)
        lo[2] = max(lo[2], floor_z)
        hi[2] = max(hi[2], lo[2] + 1e-3)
        return lo, hi
