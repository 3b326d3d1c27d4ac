"""A target's ground truth beside a LiDAR's frames, recorded or live: its sampled
positions, and each frame's truth (``types.Truth``) with the returns near it."""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import ArrayLike

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Frame

__all__ = ["TIME_TOL_S", "GroundTruth", "RecordedTruth", "target_point_count"]

TIME_TOL_S = 1e-6


@dataclass(frozen=True, slots=True)
class GroundTruth:
    """The target's true position sampled at times ``t`` (M,) [s]: ``position`` (M, 3) [m]."""

    t: FloatArray
    position: FloatArray
    max_gap_s: float = 1.0  # no truth between samples further apart than this

    def __post_init__(self) -> None:
        m = len(self.t)
        if self.position.shape != (m, 3) or m == 0:
            raise InputError(f"ground truth must be (M, 3) with M >= 1, got {self.position.shape}")
        if np.any(np.diff(self.t) < 0):
            raise InputError("ground-truth times must not decrease")

    def at(self, t: ArrayLike) -> FloatArray:
        """Linearly interpolated positions (n, 3) at times ``t``; NaN outside the samples
        or inside a gap longer than ``max_gap_s``."""
        tq = np.atleast_1d(np.asarray(t, dtype=np.float64))
        out = np.full((len(tq), 3), np.nan)
        if len(self.t) == 1:
            near = np.abs(tq - self.t[0]) <= 0.5 * self.max_gap_s
            out[near] = self.position[0]
            return out
        for k in range(3):
            out[:, k] = np.interp(tq, self.t, self.position[:, k])
        i = np.clip(np.searchsorted(self.t, tq, side="right"), 1, len(self.t) - 1)
        gap = self.t[i] - self.t[i - 1]
        # Times within TIME_TOL of the ends hold the end values (stamps' rounding).
        outside = (tq < self.t[0] - TIME_TOL_S) | (tq > self.t[-1] + TIME_TOL_S)
        bad = outside | (gap > self.max_gap_s)
        out[bad] = np.nan
        return out


class RecordedTruth:
    """A recorded frame's truth (``types.Truth``): the position at the frame's end, and the
    returns within ``radius`` of the track during the frame."""

    __slots__ = ("radius", "target_position", "track")

    def __init__(self, track: GroundTruth, position: FloatArray, radius: float) -> None:
        self.track = track
        self.target_position = position
        self.radius = radius

    def target_returns(self, frame: Frame, world: FloatArray) -> int:
        """-1 (unknown) where the truth is, or the frame could not be placed in the world."""
        known = bool(np.all(np.isfinite(self.target_position)))
        if not known or len(world) != len(frame):
            return -1
        return target_point_count(frame, world, self.track, self.radius)


def target_point_count(frame: Frame, world: FloatArray, truth: GroundTruth, radius: float) -> int:
    """Returns of the frame within ``radius`` of the true position at each return's time;
    ``world`` (N, 3) are the frame's points in the world frame.

    The truth is taken as moving linearly between its values at the frame's start
    and end (exact when its samples are the frame ends, as in our recordings).
    """
    if len(frame) == 0:
        return 0
    g0, g1 = truth.at([frame.stamp, frame.end])
    return int(_count_near(world, frame.t, frame.stamp, frame.duration, g0, g1, radius))


@nb.njit(cache=True)
def _count_near(
    W: FloatArray, t: FloatArray, t0: float, T: float, g0: FloatArray, g1: FloatArray, r: float
) -> int:
    """Points of W (N, 3) within r of g(t_i) = g0 + u_i (g1 − g0), u_i = (t_i − t0) / T ∈ [0, 1]."""
    n = 0
    r2 = r * r
    for i in range(W.shape[0]):
        u = min(max((t[i] - t0) / T, 0.0), 1.0)
        d2 = 0.0
        for k in range(3):
            d = W[i, k] - (g0[k] + u * (g1[k] - g0[k]))
            d2 += d * d
        if d2 <= r2:
            n += 1
    return n
