"""The height spread of a track's clusters, and its test against a drone.

A track's *height spread*: the heights z of its clusters, each against the line through
the two before it (updates at most ``SPREAD_GAP_S`` apart), deviate by
d = z₀ − (1 + ρ) z₁ + ρ z₂ (ρ the ratio of the gaps; a climb at constant speed leaves
none), of variance c σ² with c = 1 + (1 + ρ)² + ρ² where the heights scatter by σ.  A
drone's few returns a frame land within its size s and the beam's vertical footprint
θ_b r at range r, σ_d = (s + θ_b r)/√12, while a pole's or a person's land anywhere
over their height.  Its life (``classify.features``) keeps Q = Σ d²/(c σ_d²) over
its n triples, which ``taller_than_drone`` tests, and √(Σ 12 d²/c / n), the height
its returns land over.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2

from dronetrack.classify.observe import BEAM_RAD
from dronetrack.geometry.transforms import FloatArray

__all__ = [
    "SPREAD_ALPHA",
    "SPREAD_GAP_S",
    "SPREAD_KAPPA",
    "spread_deviation",
    "spread_height",
    "spread_scale",
    "taller_than_drone",
]

# The longest gap between updates of a triple the height spread takes: about a frame at
# 10 Hz, over which a drone's vertical acceleration (|a_z| ≤ 5 m/s²) bends its path by
# a g₀ (g₀ + g₁) / 2 ≤ 0.11 m, under the deviation's scale √c σ_d (≥ √6 s/√12, 0.28 m
# for s = 0.4 m: ``spread_scale``)
SPREAD_GAP_S = 0.15
# The height spread's test (``taller_than_drone``): its significance level, and κ of the
# Satterthwaite approximation κ Q ~ χ²(κ n) for overlapping deviations.  With equal
# gaps, d_i and d_{i+1} correlate by −2/3 and d_i and d_{i+2} by 1/6, so
# Var Σ (d_i/σ_d)²/c = 2 n (1 + 2 (2/3)² + 2 (1/6)²) = 2 n · 35/18, and κ = 18/35
SPREAD_ALPHA = 0.01
SPREAD_KAPPA = 18.0 / 35.0


def spread_deviation(
    z0: FloatArray, z1: FloatArray, z2: FloatArray, rho: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The deviation d of each height ``z0`` from the line through the two before it,
    ``z2`` then ``z1``, with ρ = g₀ / g₁ the ratio of the gaps, and the factor c of its
    variance for independent heights of variance σ²:

        d = z₀ − (1 + ρ) z₁ + ρ z₂,   Var d = c σ²,   c = 1 + (1 + ρ)² + ρ²

    A climb or descent at constant speed leaves d = 0."""
    d: FloatArray = z0 - (1.0 + rho) * z1 + rho * z2
    c: FloatArray = 1.0 + (1.0 + rho) ** 2 + rho**2
    return d, c


def spread_scale(size_m: float, range_m: FloatArray) -> FloatArray:
    """σ_d: the spread of a drone's cluster heights at range r [m], as if its returns
    landed anywhere over its size s and the beam's vertical footprint θ_b r
    (``observe.BEAM_RAD``): σ_d = (s + θ_b r) / √12."""
    out: FloatArray = (size_m + BEAM_RAD * range_m) / math.sqrt(12.0)
    return out


def spread_height(u: FloatArray, n: NDArray[np.int64]) -> FloatArray:
    """√(Σ 12 d²/c / n) [m]: the height over which an object's returns land, uniformly
    (NaN where n = 0)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        out: FloatArray = np.sqrt(np.where(n > 0, u / n, np.nan))
    return out


def taller_than_drone(q: FloatArray, n: NDArray[np.int64]) -> NDArray[np.bool_]:
    """(K,) whether the height spread Q over n triples (``classify.features``) rejects
    a drone at ``SPREAD_ALPHA``: κ Q > χ²₁₋α(κ n), its returns landing over more height
    than a drone and the beam's footprint at its range hold."""
    k = SPREAD_KAPPA
    with np.errstate(invalid="ignore"):
        bound = chi2.ppf(1.0 - SPREAD_ALPHA, k * np.maximum(n, 1))
    out: NDArray[np.bool_] = (n > 0) & (k * q > bound)
    return out
