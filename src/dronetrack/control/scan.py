"""Scanning patterns for the turret: triangle waves in pan and tilt."""

from __future__ import annotations

import math

__all__ = ["raster", "triangle"]


def triangle(t: float, lo: float, hi: float, period: float) -> float:
    """A triangle wave from lo to hi and back in ``period`` seconds, starting at lo."""
    phase = (t / period) % 1.0
    s = 2.0 * phase if phase < 0.5 else 2.0 - 2.0 * phase
    return lo + (hi - lo) * s


def raster(
    t: float, pan: tuple[float, float], tilt: tuple[float, float], period: float
) -> tuple[float, float]:
    """Pan sweeps ``pan`` every ``period``; tilt sweeps ``tilt`` π times slower.

    The irrational ratio keeps the sweeps from repeating, so over time the
    pattern covers the whole pan-tilt rectangle.
    """
    return triangle(t, *pan, period), triangle(t, *tilt, period * math.pi)
