"""The path the emulated rig's simulated turret took, kept for a while: where it pointed
and how fast it turned at any moment the emulated servos are asked (``TurretTimeline``)."""

from __future__ import annotations

import numpy as np

from dronetrack.geometry.transforms import FloatArray

__all__ = ["KEEP_PATH_S", "RATE_HALF_WINDOW_S", "TurretTimeline"]

RATE_HALF_WINDOW_S = 0.01  # present velocity: slope of the path over ±10 ms
KEEP_PATH_S = 2.0  # how much of the turret's path the timeline keeps [s]


class TurretTimeline:
    """The path the simulated turret took: sample times s [s] and pan/tilt pointing [rad],
    the last ``keep_s`` seconds of it.  Not thread-safe: the rig's lock guards it."""

    def __init__(self, keep_s: float = KEEP_PATH_S) -> None:
        self.keep_s = keep_s
        self.t = np.zeros(1)
        self.q = np.zeros((1, 2))

    def reset(self, t: float, pan: float, tilt: float) -> None:
        """One sample: the turret at (pan, tilt) at time t."""
        self.t = np.array([t], np.float64)
        self.q = np.array([[pan, tilt]], np.float64)

    def add(self, times: FloatArray, pan: FloatArray, tilt: FloatArray) -> None:
        """Append a stretch of path (times increasing, past the last sample's)."""
        new = np.asarray(times, np.float64) > self.t[-1]
        t = np.concatenate([self.t, np.asarray(times, np.float64)[new]])
        q = np.concatenate([self.q, np.column_stack([pan, tilt])[new]])
        keep = t >= t[-1] - self.keep_s
        self.t, self.q = t[keep], q[keep]

    @property
    def end(self) -> float:
        return float(self.t[-1])

    def at(self, s: float) -> tuple[float, float]:
        """(pan, tilt) at time s, linear between samples, held outside them."""
        return (
            float(np.interp(s, self.t, self.q[:, 0])),
            float(np.interp(s, self.t, self.q[:, 1])),
        )

    def rate(self, s: float, h: float = RATE_HALF_WINDOW_S) -> tuple[float, float]:
        """(pan, tilt) rates at s: ω ≈ (q(b) − q(a)) / (b − a), a = s − h, b = s + h,
        both clipped to the samples; 0 where the path has no length."""
        a, b = max(s - h, float(self.t[0])), min(s + h, self.end)
        if not b - a > 1e-9:
            return 0.0, 0.0
        pa, ta = self.at(a)
        pb, tb = self.at(b)
        return (pb - pa) / (b - a), (tb - ta) / (b - a)
