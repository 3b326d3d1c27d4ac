"""Test helpers for the VLP-16 link: data packets built by hand with ``struct.pack`` from
the VLP-16 User Manual (63-9243 Rev D, chapter 9), never with dronetrack's encoder, and
the manual's own numbers to check decoded points against.

The manual's layout (§9.3): 12 data blocks of 100 bytes (flag bytes FF EE, azimuth u16
in 0.01°, 32 data points of distance u16 in 2 mm and reflectivity u8), then the
timestamp u32 (µs past the hour) and the two factory bytes (return mode, product ID),
1206 bytes in all, little-endian.

Its coordinates (§9.2, Figure 9-1): a return at distance R, elevation ω (Table 9-1, by
laser ID) and azimuth α (clockwise from the sensor's forward axis Y, X to its right) is
X = R cos ω sin α, Y = R cos ω cos α, Z = R sin ω, and the vertical correction of Table
9-1 is added to Z.  In the REP-103 frame the pipeline uses (x forward, y left, z up):
x = Y, y = −X, z = Z + δ.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence

import numpy as np

# Table 9-1 of the manual, by laser ID: elevation [°] and vertical correction [mm].
MANUAL_ELEVATION_DEG = [-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15]
MANUAL_CORRECTION_MM = [
    11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1, 5.1, -6.6, 3.7, -8.1, 2.2, -9.7, 0.7, -11.2,
]  # fmt: skip
FIRING_SEQUENCE_US = 55.296  # §9.3.1.1: 16 firings and the recharge
FIRING_US = 2.304  # §9.4: between two firings


def vlp16_packet(
    azimuths: Sequence[int],
    points: dict[tuple[int, int], tuple[int, int]] | None = None,
    stamp_us: int = 0,
    return_mode: int = 0x37,
    product: int = 0x22,
    flag: bytes = b"\xff\xee",
) -> bytes:
    """A data packet: block b's azimuth ``azimuths[b]`` [0.01°]; ``points`` maps (block,
    data point) to (distance [2 mm units], reflectivity), every other data point 0."""
    points = points or {}
    assert len(azimuths) == 12
    out = b""
    for b in range(12):
        out += flag + struct.pack("<H", azimuths[b])
        for k in range(32):
            distance, refl = points.get((b, k), (0, 0))
            out += struct.pack("<HB", distance, refl)
    out += struct.pack("<IBB", stamp_us, return_mode, product)
    assert len(out) == 1206
    return out


def point_time_us(stamp_us: float, block: int, k: int) -> float:
    """§9.4, single-return mode: timestamp + 55.296 µs · sequence + 2.304 µs · laser,
    sequence = 2 · block + ⌊k / 16⌋, laser = k mod 16."""
    return stamp_us + FIRING_SEQUENCE_US * (2 * block + k // 16) + FIRING_US * (k % 16)


def manual_xyz(distance_m: float, azimuth_deg: float, laser: int) -> tuple[float, float, float]:
    """The manual's X, Y, Z of a return (module docstring), in x forward, y left, z up."""
    w = math.radians(MANUAL_ELEVATION_DEG[laser])
    a = math.radians(azimuth_deg)
    X = distance_m * math.cos(w) * math.sin(a)
    Y = distance_m * math.cos(w) * math.cos(a)
    Z = distance_m * math.sin(w) + MANUAL_CORRECTION_MM[laser] * 1e-3
    return Y, -X, Z


def steady_azimuths(first_cdeg: int, step_cdeg: int) -> list[int]:
    """Twelve block azimuths from ``first_cdeg``, ``step_cdeg`` apart, wrapping at 360°."""
    return [int((first_cdeg + b * step_cdeg) % 36000) for b in range(12)]


def spin_step_cdeg(rpm: float) -> float:
    """How far [0.01°] the head turns in one block (two firing sequences) at ``rpm``."""
    return rpm / 60.0 * 36000.0 * 2 * FIRING_SEQUENCE_US * 1e-6


def close(a: np.ndarray, b: np.ndarray, atol: float) -> bool:
    return bool(np.allclose(np.asarray(a, float), np.asarray(b, float), rtol=0.0, atol=atol))
