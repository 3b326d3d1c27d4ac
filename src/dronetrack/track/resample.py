"""Resampling: indices drawn in proportion to normalised weights.

Multinomial: N independent draws (the reference implementation's
``std::discrete_distribution``).  Systematic: one uniform offset and N evenly
spaced positions on the cumulative weights (lower variance, O(N)).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry import FloatArray

__all__ = ["RESAMPLERS", "multinomial", "systematic"]

Resampler = Callable[[FloatArray, np.random.Generator], NDArray[np.int64]]


def _cumulative(weights: FloatArray) -> FloatArray:
    c = np.cumsum(weights)
    c /= c[-1]
    c[-1] = 1.0  # guard the last bin against rounding
    return c


def multinomial(weights: FloatArray, rng: np.random.Generator) -> NDArray[np.int64]:
    """N independent draws i ~ Categorical(w)."""
    idx: NDArray[np.int64] = np.searchsorted(_cumulative(weights), rng.random(len(weights)))
    return idx


def systematic(weights: FloatArray, rng: np.random.Generator) -> NDArray[np.int64]:
    """Positions (u + k) / N, k = 0 … N−1, u ~ U[0, 1), located on the cumulative weights."""
    n = len(weights)
    positions = (rng.random() + np.arange(n)) / n
    idx: NDArray[np.int64] = np.searchsorted(_cumulative(weights), positions)
    return idx


RESAMPLERS: dict[str, Resampler] = {"multinomial": multinomial, "systematic": systematic}
