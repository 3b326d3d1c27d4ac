"""Ground-truth target trajectories: position, velocity and acceleration at any time.

Two exact representations cover everything:

- ``PiecewiseAcceleration``: constant acceleration between knots.  Waypoint
  flights (trapezoidal speed profiles with dwells) and random manoeuvres
  compile into it, so speed and acceleration limits hold exactly.
- ``SplineTrajectory``: a C² cubic spline through samples (t, x, y, z), for
  trajectories read from CSV files.

Before its start a trajectory holds its first position; after its end it holds
its last position at rest.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import CubicSpline

from dronetrack.errors import TrajectoryError
from dronetrack.formats.tables import read_csv_columns
from dronetrack.geometry.transforms import FloatArray

__all__ = [
    "PiecewiseAcceleration",
    "SplineTrajectory",
    "Superposed",
    "Trajectory",
    "Waypoint",
    "fly_waypoints",
    "load_csv_trajectory",
    "polar",
    "random_manoeuvres",
]


class Trajectory(Protocol):
    """Anything that gives the target's state at arbitrary times [s]."""

    @property
    def start(self) -> float: ...

    @property
    def end(self) -> float: ...

    def position(self, t: ArrayLike) -> FloatArray: ...

    def velocity(self, t: ArrayLike) -> FloatArray: ...

    def acceleration(self, t: ArrayLike) -> FloatArray: ...


@dataclass(frozen=True, slots=True)
class PiecewiseAcceleration:
    """Constant acceleration a_k on [t_k, t_{k+1}):

    p(t) = p_k + v_k τ + ½ a_k τ²,   v(t) = v_k + a_k τ,   τ = t − t_k
    """

    knots: FloatArray  # (K + 1,) increasing times [s]
    p: FloatArray  # (K, 3) position at each segment start [m]
    v: FloatArray  # (K, 3) velocity at each segment start [m/s]
    a: FloatArray  # (K, 3) acceleration over each segment [m/s²]

    @property
    def start(self) -> float:
        return float(self.knots[0])

    @property
    def end(self) -> float:
        return float(self.knots[-1])

    def _locate(self, t: ArrayLike) -> tuple[FloatArray, np.ndarray, FloatArray, np.ndarray]:
        tq = np.atleast_1d(np.asarray(t, dtype=np.float64))
        k = np.clip(np.searchsorted(self.knots, tq, side="right") - 1, 0, len(self.p) - 1)
        tau = np.clip(tq, self.knots[0], self.knots[-1]) - self.knots[k]
        after = tq >= self.knots[-1]
        return tq, k, tau, after

    def position(self, t: ArrayLike) -> FloatArray:
        _, k, tau, _ = self._locate(t)
        tau = tau[:, None]
        p: FloatArray = self.p[k] + self.v[k] * tau + 0.5 * self.a[k] * tau**2
        return p

    def velocity(self, t: ArrayLike) -> FloatArray:
        _, k, tau, after = self._locate(t)
        v: FloatArray = self.v[k] + self.a[k] * tau[:, None]
        v[after] = 0.0
        return v

    def acceleration(self, t: ArrayLike) -> FloatArray:
        tq, k, _, after = self._locate(t)
        a: FloatArray = self.a[k].copy()
        a[after | (tq < self.knots[0])] = 0.0
        return a


@dataclass(frozen=True, slots=True)
class Waypoint:
    """Fly to ``position`` at up to ``speed`` with ``accel``, then hover ``dwell`` seconds."""

    position: tuple[float, float, float]
    speed: float
    accel: float
    dwell: float = 0.0


def _leg(
    p0: FloatArray, p1: FloatArray, speed: float, accel: float
) -> list[tuple[float, FloatArray, FloatArray, FloatArray]]:
    """Segments (duration, p, v, a) of a rest-to-rest straight leg.

    Trapezoid: accelerate at a to v, cruise, brake at a; if L < v²/a the leg
    is a triangle with peak speed √(L a).
    """
    delta = p1 - p0
    L = float(np.linalg.norm(delta))
    if L == 0.0:
        return []
    u = delta / L
    v_peak = min(speed, np.sqrt(L * accel))
    t_acc = v_peak / accel
    t_cruise = (L - v_peak * t_acc) / v_peak
    zero = np.zeros(3)
    p_cruise = p0 + 0.5 * accel * t_acc**2 * u
    p_brake = p_cruise + v_peak * t_cruise * u
    segs = [(t_acc, p0, zero, accel * u)]
    if t_cruise > 1e-12:
        segs.append((t_cruise, p_cruise, v_peak * u, zero))
    segs.append((t_acc, p_brake, v_peak * u, -accel * u))
    return segs


def fly_waypoints(
    start: ArrayLike, waypoints: Sequence[Waypoint], t0: float = 0.0, hold: float = 0.0
) -> PiecewiseAcceleration:
    """A rest-to-rest flight from ``start`` through ``waypoints``, starting at t0 + hold."""
    p = np.asarray(start, dtype=np.float64)
    zero = np.zeros(3)
    segs: list[tuple[float, FloatArray, FloatArray, FloatArray]] = []
    if hold > 0:
        segs.append((hold, p, zero, zero))
    for wp in waypoints:
        if wp.speed <= 0 or wp.accel <= 0 or wp.dwell < 0:
            raise TrajectoryError(f"waypoint {wp.position} needs positive speed and acceleration")
        target = np.asarray(wp.position, dtype=np.float64)
        segs.extend(_leg(p, target, wp.speed, wp.accel))
        p = target
        if wp.dwell > 0:
            segs.append((wp.dwell, p, zero, zero))
    if not segs:
        segs.append((1e-9, p, zero, zero))
    durations = np.array([s[0] for s in segs])
    return PiecewiseAcceleration(
        knots=t0 + np.concatenate([[0.0], np.cumsum(durations)]),
        p=np.array([s[1] for s in segs]),
        v=np.array([s[2] for s in segs]),
        a=np.array([s[3] for s in segs]),
    )


def random_manoeuvres(
    rng: np.random.Generator,
    duration: float,
    v_max: float,
    a_max: float,
    center: ArrayLike,
    half_extent: ArrayLike,
    dt: float = 0.05,
    mean_hold: float = 1.0,
    t0: float = 0.0,
) -> PiecewiseAcceleration:
    """Aggressive random flight inside a box, within ‖v‖ ≤ v_max and ‖a‖ ≤ a_max.

    A random acceleration (uniform direction, magnitude 30-100 % of a_max) is
    held for an exponentially distributed time (mean ``mean_hold``).  Each axis
    brakes at a_max/√3 as soon as its stopping point p + v|v| / (2 a) would
    leave the box, so the flight stays inside it (up to one step's motion).
    A velocity update that would exceed v_max is projected back onto the ball,
    which never lengthens the step's velocity change, so ‖a‖ ≤ a_max still holds.
    """
    c = np.asarray(center, dtype=np.float64)
    h = np.asarray(half_extent, dtype=np.float64)
    a_axis = a_max / np.sqrt(3.0)
    n = max(1, int(np.ceil(duration / dt)))
    p = c.copy()
    v = np.zeros(3)
    P = np.empty((n, 3))
    V = np.empty((n, 3))
    A = np.empty((n, 3))
    a_cmd = np.zeros(3)
    t_next = 0.0
    for i in range(n):
        if i * dt >= t_next:
            direction = rng.normal(size=3)
            direction /= np.linalg.norm(direction)
            a_cmd = direction * a_max * rng.uniform(0.3, 1.0)
            t_next = i * dt + rng.exponential(mean_hold)
        # Stopping point per axis at a_max/√3 (one step ahead); where it is outside
        # the box, accelerate away from that wall.  The rest of the budget goes to
        # the random command on the other axes.
        stop = p + v * dt + v * np.abs(v) / (2.0 * a_axis)
        outside = np.abs(stop - c) > h
        a_brake = np.where(outside, -np.sign(stop - c) * a_axis, 0.0)
        a_free = np.where(outside, 0.0, a_cmd)
        budget = np.sqrt(max(a_max**2 - float(a_brake @ a_brake), 0.0))
        free_norm = np.linalg.norm(a_free)
        if free_norm > budget:
            a_free *= budget / free_norm
        a = a_brake + a_free
        v_new = v + a * dt
        speed = np.linalg.norm(v_new)
        if speed > v_max:
            v_new *= v_max / speed
        a = (v_new - v) / dt
        P[i], V[i], A[i] = p, v, a
        p = p + v * dt + 0.5 * a * dt**2
        v = v_new
    knots = t0 + dt * np.arange(n + 1, dtype=np.float64)
    return PiecewiseAcceleration(knots=knots, p=P, v=V, a=A)


@dataclass(frozen=True, slots=True)
class SplineTrajectory:
    """A C² cubic spline through samples; derivatives give velocity and acceleration."""

    spline: CubicSpline

    @property
    def start(self) -> float:
        return float(self.spline.x[0])

    @property
    def end(self) -> float:
        return float(self.spline.x[-1])

    def _clamped(self, t: ArrayLike) -> FloatArray:
        return np.clip(np.atleast_1d(np.asarray(t, dtype=np.float64)), self.start, self.end)

    def _held(self, t: ArrayLike, values: FloatArray) -> FloatArray:
        tq = np.atleast_1d(np.asarray(t, dtype=np.float64))
        values[(tq < self.start) | (tq > self.end)] = 0.0
        return values

    def position(self, t: ArrayLike) -> FloatArray:
        return np.asarray(self.spline(self._clamped(t)), dtype=np.float64)

    def velocity(self, t: ArrayLike) -> FloatArray:
        return self._held(t, np.asarray(self.spline(self._clamped(t), 1), dtype=np.float64))

    def acceleration(self, t: ArrayLike) -> FloatArray:
        return self._held(t, np.asarray(self.spline(self._clamped(t), 2), dtype=np.float64))


@dataclass(frozen=True, slots=True)
class Superposed:
    """A path plus a motion about zero:  p(t) = p_path(t) + p_wobble(t), and so for v and a.

    Speeds and accelerations add at most: |v| ≤ |v_path| + |v_wobble|.
    """

    path: Trajectory
    wobble: Trajectory

    @property
    def start(self) -> float:
        return min(self.path.start, self.wobble.start)

    @property
    def end(self) -> float:
        return max(self.path.end, self.wobble.end)

    def position(self, t: ArrayLike) -> FloatArray:
        p: FloatArray = self.path.position(t) + self.wobble.position(t)
        return p

    def velocity(self, t: ArrayLike) -> FloatArray:
        v: FloatArray = self.path.velocity(t) + self.wobble.velocity(t)
        return v

    def acceleration(self, t: ArrayLike) -> FloatArray:
        a: FloatArray = self.path.acceleration(t) + self.wobble.acceleration(t)
        return a


def polar(r: float, bearing_deg: float, z: float) -> tuple[float, float, float]:
    """The point ``r`` metres out at ``bearing_deg`` (counter-clockwise from +x), height z."""
    b = math.radians(bearing_deg)
    return (r * math.cos(b), r * math.sin(b), z)


MAX_CSV_SPEED = 100.0  # [m/s] faster than any multirotor; more means wrong units


def load_csv_trajectory(path: Path, t0: float = 0.0) -> SplineTrajectory:
    """A trajectory from a CSV with columns ``t,x,y,z`` [s, m], shifted to start at t0.

    Raises TrajectoryError for a missing file or column, fewer than two rows,
    non-numeric or non-finite values, times that do not strictly increase, or a
    speed between samples above MAX_CSV_SPEED (positions in millimetres, say).
    """
    data = read_csv_columns(path, ("t", "x", "y", "z"), TrajectoryError, "trajectory CSV")
    if len(data) < 2:
        raise TrajectoryError(f"trajectory CSV {path} needs at least 2 rows, got {len(data)}")
    bad = ~np.all(np.isfinite(data), axis=1)
    if np.any(bad):
        row = int(np.argmax(bad)) + 2
        raise TrajectoryError(f"trajectory CSV {path} has NaN or infinite values (line {row})")
    dt = np.diff(data[:, 0])
    if np.any(dt <= 0):
        row = int(np.argmax(dt <= 0)) + 3
        raise TrajectoryError(f"trajectory CSV {path}: time t must strictly increase (line {row})")
    # Mean speed between samples: |p_{k+1} − p_k| / (t_{k+1} − t_k)
    with np.errstate(over="ignore"):  # absurd values give inf, caught below
        speed = np.linalg.norm(np.diff(data[:, 1:], axis=0), axis=1) / dt
    if np.any(speed > MAX_CSV_SPEED):
        row = int(np.argmax(speed > MAX_CSV_SPEED)) + 3
        raise TrajectoryError(
            f"trajectory CSV {path}: {speed.max():.0f} m/s between samples (line {row}) exceeds "
            f"{MAX_CSV_SPEED:.0f} m/s; times must be in seconds and positions in metres"
        )
    t = data[:, 0] - data[0, 0] + t0
    bc = "not-a-knot" if len(t) >= 4 else "natural"
    try:
        spline = CubicSpline(t, data[:, 1:], axis=0, bc_type=bc)
    except ValueError as exc:
        raise TrajectoryError(f"trajectory CSV {path}: cannot fit a spline: {exc}") from exc
    return SplineTrajectory(spline)
