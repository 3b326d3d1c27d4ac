"""Scanning patterns for the turret: triangle waves in pan and tilt."""

from __future__ import annotations

import math

__all__ = ["raster", "triangle", "triangle_phase"]


def triangle(t: float, lo: float, hi: float, period: float) -> float:
    """A triangle wave from lo to hi and back in ``period`` seconds, starting at lo."""
    phase = (t / period) % 1.0
    s = 2.0 * phase if phase < 0.5 else 2.0 - 2.0 * phase
    return lo + (hi - lo) * s


def triangle_phase(x: float, lo: float, hi: float, period: float) -> float:
    """The time into ``triangle(·, lo, hi, period)`` at which it rises through x
    (clipped into [lo, hi]): τ = P (x − lo) / (2 (hi − lo))."""
    if hi <= lo:
        return 0.0
    return period * (min(max(x, lo), hi) - lo) / (2.0 * (hi - lo))


def raster(
    t: float,
    pan: tuple[float, float],
    tilt: tuple[float, float],
    period: float,
    end: tuple[float, float, float] | None = None,
) -> tuple[float, float]:
    """Pan sweeps ``pan`` every ``period``; tilt sweeps ``tilt`` π times slower.

    The irrational ratio keeps the sweeps from repeating, so over time the
    pattern covers the whole pan-tilt rectangle.  With ``end`` = (t_e, pan_e,
    tilt_e) each wave is shifted in time to pass through the end angles at t_e,
    rising: the scan then ends where tracking begins.
    """
    if end is None:
        return triangle(t, *pan, period), triangle(t, *tilt, period * math.pi)
    t_e, pan_e, tilt_e = end
    p_tilt = period * math.pi
    # θ(t) = triangle(t − t_e + τ(θ_e)): θ(t_e) = θ_e
    return (
        triangle(t - t_e + triangle_phase(pan_e, *pan, period), *pan, period),
        triangle(t - t_e + triangle_phase(tilt_e, *tilt, p_tilt), *tilt, p_tilt),
    )
