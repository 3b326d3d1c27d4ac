"""Pulses and the scan-pattern protocol every simulated sensor's pattern follows.

A pattern maps a time window to the pulses fired in it: times, unit directions
in the sensor frame (x forward, y left, z up), line/channel indices and the
beam origins in the sensor frame.  Patterns run continuously from t = 0, so the
pattern of a frame depends on its absolute time (Livox prisms never reset).
``pulse_indices`` numbers the pulses of a fixed-rate pattern in a window.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray

__all__ = ["Pulses", "ScanPattern", "pulse_indices"]


@dataclass(frozen=True, slots=True)
class Pulses:
    """Pulses fired in a time window."""

    t: FloatArray  # (N,) firing time [s]
    dirs: FloatArray  # (N, 3) unit directions, sensor frame
    line: NDArray[np.uint8]  # (N,) line / laser index
    origins: FloatArray  # (N, 3) beam origins, sensor frame [m]
    max_origin_offset: float = 0.0  # bound on |origins| [m]

    def __len__(self) -> int:
        return len(self.t)


class ScanPattern(Protocol):
    """Anything that fires pulses."""

    @property
    def n_lines(self) -> int:
        """Number of laser lines (channels)."""
        ...

    def pulses(self, t_start: float, t_end: float) -> Pulses:
        """All pulses with t_start ≤ t < t_end."""
        ...


def pulse_indices(t_start: float, t_end: float, rate_hz: float) -> NDArray[np.int64]:
    """Indices k of pulses fired at t_k = k / rate in [t_start, t_end)."""
    # A small tolerance keeps frame boundaries such as 0.1 s · 240 kHz exact.
    k0 = math.ceil(t_start * rate_hz - 1e-6)
    k1 = math.ceil(t_end * rate_hz - 1e-6)
    return np.arange(max(k0, 0), max(k1, 0), dtype=np.int64)
