"""Point masks: finite values and an axis-aligned box."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dronetrack.geometry import FloatArray

__all__ = ["box_mask", "finite_mask"]


def finite_mask(points: FloatArray) -> NDArray[np.bool_]:
    """Rows of ``points`` (N, 3) whose coordinates are all finite."""
    mask: NDArray[np.bool_] = np.all(np.isfinite(points), axis=1)
    return mask


def box_mask(points: FloatArray, lo: ArrayLike, hi: ArrayLike) -> NDArray[np.bool_]:
    """Rows inside the box lo ≤ p < hi (NaN rows are outside)."""
    lo_a = np.asarray(lo, dtype=np.float64)
    hi_a = np.asarray(hi, dtype=np.float64)
    mask: NDArray[np.bool_] = np.all((points >= lo_a) & (points < hi_a), axis=1)
    return mask
