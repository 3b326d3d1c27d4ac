"""Spinning scan patterns: the Velodyne VLP-16 and a sinusoidal-spin Mid-360 model.

A spinning head turns at a fixed rate and fires its lasers in sequence
(``SpinningPattern``, traced by a numba kernel); ``SinusoidalSpinPattern``
also sweeps each laser in elevation, an approximation of the Livox Mid-360.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import SensorError
from dronetrack.geometry.transforms import FloatArray, direction_from_azimuth_elevation
from dronetrack.sim.pulses import Pulses, pulse_indices

__all__ = [
    "MID360_PATTERN",
    "VLP16_ELEVATION_DEG",
    "VLP16_VERTICAL_OFFSET_MM",
    "SinusoidalSpinPattern",
    "SpinningPattern",
    "vlp16_pattern",
]

# ---------------------------------------------------------------------------
# Spinning multi-laser sensors (Velodyne VLP-16)
# ---------------------------------------------------------------------------

VLP16_ELEVATION_DEG = (-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15)
VLP16_VERTICAL_OFFSET_MM = (
    11.2,
    -0.7,
    9.7,
    -2.2,
    8.1,
    -3.7,
    6.6,
    -5.1,
    5.1,
    -6.6,
    3.7,
    -8.1,
    2.2,
    -9.7,
    0.7,
    -11.2,
)


@dataclass(frozen=True, slots=True)
class SpinningPattern:
    """A spinning head firing its lasers in sequence.

    Laser c of firing sequence s fires at t = s·T_cycle + c·T_fire; the head
    turns clockwise seen from above, so the azimuth is az(t) = az0 − 2π (rpm/60) t.
    """

    elevation: FloatArray  # (C,) [rad], by laser id
    vertical_offset: FloatArray  # (C,) beam origin height above the sensor origin [m]
    firing_interval_s: float
    cycle_s: float
    rpm: float
    azimuth0: float = 0.0

    def __post_init__(self) -> None:
        if not 300.0 <= self.rpm <= 1200.0:
            raise SensorError(f"spin rate must be within 300-1200 rpm, got {self.rpm:g}")

    @property
    def n_lines(self) -> int:
        return len(self.elevation)

    @property
    def revolution_s(self) -> float:
        return 60.0 / self.rpm

    def pulses(self, t_start: float, t_end: float) -> Pulses:
        # Firing sequences with a laser in [t_start, t_end): s T_cycle + (C − 1) T_fire ≥ t_start.
        last_offset = (self.n_lines - 1) * self.firing_interval_s
        seq = pulse_indices(t_start - last_offset, t_end, 1.0 / self.cycle_s)
        s0 = int(seq[0]) if len(seq) else 0
        t, dirs, origins, line = _spinning_kernel(
            s0,
            len(seq),
            t_start,
            t_end,
            self.cycle_s,
            self.firing_interval_s,
            2.0 * np.pi * self.rpm / 60.0,
            self.azimuth0,
            np.ascontiguousarray(self.elevation),
            np.ascontiguousarray(self.vertical_offset),
        )
        return Pulses(
            t=t,
            dirs=dirs,
            line=line,
            origins=origins,
            max_origin_offset=float(np.max(np.abs(self.vertical_offset))),
        )


@nb.njit(cache=True, fastmath=True)
def _spinning_kernel(
    s0: int,
    n_seq: int,
    t_start: float,
    t_end: float,
    cycle: float,
    interval: float,
    omega: float,
    az0: float,
    elevation: FloatArray,
    offset: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.uint8]]:
    n_lines = elevation.shape[0]
    n_max = n_seq * n_lines
    t = np.empty(n_max)
    dirs = np.empty((n_max, 3))
    origins = np.zeros((n_max, 3))
    line = np.empty(n_max, dtype=np.uint8)
    cos_el = np.cos(elevation)
    sin_el = np.sin(elevation)
    k = 0
    for s in range(s0, s0 + n_seq):
        for c in range(n_lines):
            # t = s T_cycle + c T_fire;  az(t) = az0 − ω t
            tk = s * cycle + c * interval
            if tk < t_start or tk >= t_end:
                continue
            az = az0 - omega * tk
            t[k] = tk
            dirs[k, 0] = cos_el[c] * np.cos(az)
            dirs[k, 1] = cos_el[c] * np.sin(az)
            dirs[k, 2] = sin_el[c]
            origins[k, 2] = offset[c]
            line[k] = c
            k += 1
    return t[:k], dirs[:k], origins[:k], line[:k]


def vlp16_pattern(rpm: float = 600.0) -> SpinningPattern:
    """Velodyne VLP-16: 16 lasers, 2.304 µs apart, 55.296 µs firing cycle."""
    return SpinningPattern(
        elevation=np.radians(np.array(VLP16_ELEVATION_DEG, dtype=np.float64)),
        vertical_offset=np.array(VLP16_VERTICAL_OFFSET_MM) * 1e-3,
        firing_interval_s=2.304e-6,
        cycle_s=55.296e-6,
        rpm=rpm,
    )


# ---------------------------------------------------------------------------
# Livox Mid-360 (approximate model)
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class SinusoidalSpinPattern:
    """A 360° head whose lasers also sweep in elevation.

    Laser c: az(t) = 2π f_az t + 2π c / C,
             el(t) = el_mid + el_amp · sin(2π f_el t + 2π c / C).
    The two rates are incommensurate, so the pattern never repeats and fills the
    field of view over time.  An approximation of the Mid-360, whose prism
    parameters are not published; replay Livox's own table with ``TablePattern``
    where fidelity matters.
    """

    rate_hz: float
    n_lines: int
    azimuth_rate_hz: float
    elevation_rate_hz: float
    elevation_min: float
    elevation_max: float

    def pulses(self, t_start: float, t_end: float) -> Pulses:
        k = pulse_indices(t_start, t_end, self.rate_hz)
        t = k / self.rate_hz
        c = k % self.n_lines
        phase = 2.0 * np.pi * c / self.n_lines
        az = 2.0 * np.pi * self.azimuth_rate_hz * t + phase
        mid = 0.5 * (self.elevation_max + self.elevation_min)
        amp = 0.5 * (self.elevation_max - self.elevation_min)
        el = mid + amp * np.sin(2.0 * np.pi * self.elevation_rate_hz * t + phase)
        dirs = direction_from_azimuth_elevation(az, el)
        return Pulses(t=t, dirs=dirs, line=c.astype(np.uint8), origins=np.zeros_like(dirs))


MID360_PATTERN = SinusoidalSpinPattern(
    rate_hz=200_000.0,
    n_lines=4,
    azimuth_rate_hz=10.0 * (1 + 5**0.5) / 3.236,  # ≈ 10 Hz, irrational
    elevation_rate_hz=193.7,
    elevation_min=np.radians(-7.0),
    elevation_max=np.radians(52.0),
)
