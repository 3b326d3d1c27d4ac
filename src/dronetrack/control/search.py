"""The turret's search pattern over the field of regard, after the prediction is spent.

A path of (pan, tilt) waypoints [rad] the turret follows at a constant angular rate:

1. **Expanding sweeps** around the bearing c where the drone most likely is (its last
   predicted position): sweep k reaches c ± a_k with a_k = a₀ + k·w (w: the lane
   width, the sensor's dense centre), on alternate sides, each on the next tilt lane
   nearest the drone's last tilt.  The dense centre goes first where the drone can
   have got to soonest.
2. **A raster** of the whole field once the sweeps reach both pan ends: the pan runs
   end to end on one tilt lane after another, and repeats.  Every direction then
   comes under the dense centre once per revisit period

       T_revisit = n_lanes · (pan_hi − pan_lo) / ω      (``revisit_period``)

   with n_lanes = ⌈(tilt_hi − tilt_lo) / w⌉ and ω the search rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dronetrack.geometry.transforms import FloatArray

__all__ = ["SearchPath", "revisit_period", "search_path", "tilt_lanes"]


def tilt_lanes(tilt: tuple[float, float], lane: float) -> FloatArray:
    """Centres [rad] of the ⌈span / w⌉ lanes that tile the tilt range, evenly spaced;
    one lane at the range's middle when it is narrower than a lane."""
    lo, hi = tilt
    n = max(1, math.ceil((hi - lo) / lane - 1e-9))
    # c_j = lo + (j + ½)·(hi − lo)/n
    lanes: FloatArray = lo + (np.arange(n) + 0.5) * (hi - lo) / n
    return lanes


def revisit_period(
    pan: tuple[float, float], tilt: tuple[float, float], lane: float, rate: float
) -> float:
    """T_revisit = n_lanes · (pan_hi − pan_lo) / ω [s] of the raster phase."""
    return len(tilt_lanes(tilt, lane)) * (pan[1] - pan[0]) / rate


@dataclass(frozen=True, slots=True)
class SearchPath:
    """Waypoints (K, 2) [rad], the time [s] each is reached, and where the raster's
    repeating cycle starts (index) and how long it lasts [s]."""

    waypoints: FloatArray
    times: FloatArray
    cycle_start: int
    cycle_s: float

    def at(self, s: float) -> tuple[float, float]:
        """(pan, tilt) [rad] at ``s`` seconds into the search."""
        t0 = float(self.times[self.cycle_start])
        if s > t0 and self.cycle_s > 0.0:
            s = t0 + (s - t0) % self.cycle_s  # the raster repeats
        pan = float(np.interp(s, self.times, self.waypoints[:, 0]))
        tilt = float(np.interp(s, self.times, self.waypoints[:, 1]))
        return pan, tilt


def search_path(
    start: tuple[float, float],
    pan: tuple[float, float],
    tilt: tuple[float, float],
    lane: float,
    first: float,
    rate: float,
) -> SearchPath:
    """The search from ``start`` = (pan, tilt) [rad] over the ranges ``pan`` and ``tilt``
    [rad]: expanding sweeps of half-width ``first`` + k·``lane``, then the raster;
    waypoints are joined at ``rate`` [rad/s] (both axes move together, the slower sets
    the time)."""
    lo, hi = pan
    c = min(max(start[0], lo), hi)
    lanes = tilt_lanes(tilt, lane)
    # Lanes nearest the start's tilt first.
    near = lanes[np.argsort(np.abs(lanes - start[1]), kind="stable")]
    points = [(start[0], start[1])]
    k = 0
    reached = {1: c >= hi, -1: c <= lo}
    while not (reached[1] and reached[-1]):
        side = 1 if k % 2 == 0 else -1
        a = first + k * lane
        target = min(max(c + side * a, lo), hi)
        reached[side] = reached[side] or target in (lo, hi)
        points.append((target, float(near[k % len(near)])))
        k += 1
    # The raster: from the end the sweeps stopped at, end to end, a lane a traversal;
    # 2·n_lanes traversals bring it back to its first waypoint.
    end = points[-1][0]
    toward_hi = end <= lo
    cycle_start = len(points)
    n = len(lanes)
    for j in range(2 * n):
        target = hi if (j % 2 == 0) == toward_hi else lo
        points.append((target, float(lanes[j % n])))
    points.append(points[cycle_start])
    wp = np.asarray(points, dtype=np.float64)
    # Δt_i = max(|Δpan_i|, |Δtilt_i|) / ω
    steps = np.max(np.abs(np.diff(wp, axis=0)), axis=1) / rate
    times = np.concatenate([[0.0], np.cumsum(steps)])
    return SearchPath(wp, times, cycle_start, float(times[-1] - times[cycle_start]))
