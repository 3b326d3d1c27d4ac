"""Read-only copies of the arrays the stages pass on."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError

__all__ = ["frozen"]


def frozen(a: NDArray[Any], dtype: type[np.generic], shape: tuple[int, ...]) -> NDArray[Any]:
    """A read-only copy of ``a`` as ``dtype`` (``a`` itself when it is one already, as a
    field handed on by ``dataclasses.replace`` is); InputError unless its shape is
    ``shape``."""
    if (
        isinstance(a, np.ndarray)
        and not a.flags.writeable
        and a.dtype == dtype
        and a.shape == shape
        and a.base is None
    ):
        return a
    out = np.array(a, dtype=dtype)
    if out.shape != shape:
        raise InputError(f"expected shape {shape}, got {out.shape}")
    out.flags.writeable = False
    return out
