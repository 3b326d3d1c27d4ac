"""The shared base of the Kalman-family trackers (maths in ``track.kalman``).

Each takes the frame's foreground points (M, 3) in the world frame [m] and the
number of periods to predict (0: a repeated frame, nothing changes).  Until its
first fix (or after ``reset()``) it reports its ``home`` point, velocity 0 and
``tracked=False``; ``initialize(position)`` starts it at a known position.

How a track starts: with ``self_start`` (the seeds' way) on the first non-empty
frame after a reset or a loss, which needs the drone alone in view.  Without it
(the pipeline's acquisition on) only on the detect stage's confirmed candidates
(``acquire``): when the filter is not tracked and the best candidate lies outside
its 3σ position gate |c − p̂| > 3 √max(P_xx, P_yy, P_zz) (inside it the filter's own
update is already on the candidate), the next step starts the track there, at the
frame's end, with the candidate's velocity where the state holds a Cartesian
velocity (the constant-velocity and -acceleration models; the CTRV models start at
rest, as they do on their own) and P = P0.  P0's velocity variances (16-25 (m/s)²)
already cover the candidate's velocity error of a few frames of centroids (σ_pos/T,
about 1-2 m/s), so P is not reduced.
Estimates carry spread = √max(P_xx, P_yy, P_zz), the diagonal ``variance`` of the
position and velocity covariance, and the ``measurement`` z that set the position
this frame (an update or a (re-)initialisation), None if none did.

The filters: ``track.sphere_kalman`` (DogruEKF, CatalanoEKF) and ``track.cluster_kalman``
(CentroidEKF, ConstantAccelerationKF, AdaptiveEKF, on ``detect.candidates``' detections).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.errors import ConfigError, InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.track.kalman import position_selector
from dronetrack.types import Candidates, TrackEstimate


def _vector3(value: ArrayLike, name: str) -> FloatArray:
    v = np.asarray(value, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)):
        raise ConfigError(f"{name} must be three finite numbers, got {value!r}")
    return v.copy()


def _positive(**values: float) -> None:
    for name, value in values.items():
        if not value > 0.0:
            raise ConfigError(f"{name} must be positive, got {value}")


def _points(points: FloatArray) -> FloatArray:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise InputError(f"points must have shape (M, 3), got {pts.shape}")
    return pts


class _KalmanTracker:
    """State x, covariance P and the bookkeeping every tracker here shares."""

    def __init__(self, period: float, home: ArrayLike, P0: FloatArray) -> None:
        _positive(period=period)
        self._period = float(period)
        self.home = _vector3(home, "home")
        self.P0 = P0
        self.H = position_selector(len(P0))
        self.self_start = True  # start on the first non-empty frame (see the module doc)
        self.reset()

    @property
    def period(self) -> float:
        return self._period

    def reset(self) -> None:
        """Back to uninitialised: the next non-empty frame (or ``initialize``) starts it."""
        self.x = np.zeros(len(self.P0))
        self.P = self.P0.copy()
        self.initialised = False
        self._z: FloatArray | None = None
        self._pending: tuple[FloatArray, FloatArray] | None = None  # a start from acquire

    def initialize(self, position: ArrayLike) -> None:
        """Start at ``position``; every other state entry and P take their initial values."""
        self.reset()
        self._start(_vector3(position, "position"))

    def _start(self, position: FloatArray) -> None:
        self.x = np.zeros(len(self.P0))
        self.x[0:3] = position
        self.P = self.P0.copy()
        self.initialised = True

    def acquire(self, candidates: Candidates) -> None:
        """Start on the best confirmed candidate at the next step, unless tracked or
        already on it (inside the 3σ position gate)."""
        if not len(candidates) or self.tracked:
            return
        c = candidates.positions[0]
        if self.initialised:
            # |c − p̂| ≤ 3 √max(P_xx, P_yy, P_zz): the filter's own update has it
            sigma = float(np.sqrt(np.diag(self.P)[0:3].max()))
            if float(np.linalg.norm(c - self.x[0:3])) <= 3.0 * sigma:
                return
        self._pending = (c.copy(), candidates.velocities[0].copy())

    def step(self, t: float, points: FloatArray, steps: int) -> TrackEstimate:
        if steps < 0:
            raise InputError(f"steps must be ≥ 0, got {steps}")
        self._z = None
        if steps > 0 and self._pending is not None:
            # The candidate is at the frame's end: the start is not predicted forward.
            position, velocity = self._pending
            self._pending = None
            self._start(position)
            self._set_velocity(velocity)
            self._z = position.copy()
            self._fixed(t)
        elif steps > 0:
            self._advance(t, _points(points), steps)
        return self._estimate(t)

    def _set_velocity(self, velocity: FloatArray) -> None:
        """Write a start's velocity [m/s] into the state (states [p, v, …])."""
        self.x[3:6] = velocity

    def _fixed(self, t: float) -> None:
        """Bookkeeping after a start from a candidate at ``t``."""

    def _advance(self, t: float, points: FloatArray, steps: int) -> None:
        raise NotImplementedError

    @property
    def tracked(self) -> bool:
        raise NotImplementedError

    def _velocity(self) -> tuple[FloatArray, FloatArray]:
        """Velocity (3,) [m/s] and its variances (3,) [(m/s)²]."""
        return self.x[3:6].copy(), np.diag(self.P)[3:6].copy()

    def _estimate(self, t: float) -> TrackEstimate:
        position = self.x[0:3].copy() if self.initialised else self.home.copy()
        velocity, var_v = self._velocity()
        var_p = np.diag(self.P)[0:3]
        return TrackEstimate(
            t,
            position,
            velocity,
            self.tracked,
            float(np.sqrt(var_p.max())),
            None,
            np.concatenate([var_p, var_v]),
            None if self._z is None else self._z.copy(),
        )
