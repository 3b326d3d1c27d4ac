"""Resampling: indices drawn in proportion to normalised weights.

Multinomial: N independent draws (the reference implementation's
``std::discrete_distribution``).  The draws are generated already sorted, as
cumulative sums of exponential variables over their total (the order statistics
of N uniforms), so one pass over the cumulative weights places them all: the
same distribution as N separate draws, in O(N).  Systematic: one uniform
offset and N evenly spaced positions (u + k) / N (lower variance, O(N)).
"""

from __future__ import annotations

from collections.abc import Callable

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray

__all__ = ["RESAMPLERS", "multinomial", "systematic"]

Resampler = Callable[[FloatArray, np.random.Generator], NDArray[np.int64]]


@nb.njit(cache=True)
def _locate_sorted(weights: FloatArray, positions: FloatArray) -> NDArray[np.int64]:
    """For sorted positions in [0, 1): the bin of each on the cumulative normalised weights."""
    n = weights.shape[0]
    total = 0.0
    for i in range(n):
        total += weights[i]
    out = np.empty(positions.shape[0], dtype=np.int64)
    i = 0
    cumulative = weights[0] / total
    for k in range(positions.shape[0]):
        while positions[k] >= cumulative and i < n - 1:
            i += 1
            cumulative += weights[i] / total
        out[k] = i
    return out


def multinomial(weights: FloatArray, rng: np.random.Generator) -> NDArray[np.int64]:
    """N independent draws i ~ Categorical(w), returned in sorted order."""
    n = len(weights)
    e = rng.standard_exponential(n + 1)
    # Order statistics of N uniforms: U_(k) = (E_1 + … + E_k) / (E_1 + … + E_{N+1})
    positions = np.cumsum(e[:n]) / e.sum()
    return _locate_sorted(np.ascontiguousarray(weights, dtype=np.float64), positions)


def systematic(weights: FloatArray, rng: np.random.Generator) -> NDArray[np.int64]:
    """Positions (u + k) / N, k = 0 … N−1, u ~ U[0, 1), located on the cumulative weights."""
    n = len(weights)
    positions = (rng.random() + np.arange(n)) / n
    return _locate_sorted(np.ascontiguousarray(weights, dtype=np.float64), positions)


RESAMPLERS: dict[str, Resampler] = {"multinomial": multinomial, "systematic": systematic}
