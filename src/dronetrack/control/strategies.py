"""Seed 003's scan strategies for a pan-only turret carrying a side-mounted VLP-16.

The VLP-16 lies on its side on the PTU-E46: its spin sweeps elevation and its 16
beams fan out ±15° in azimuth, 2° apart.  Panning sweeps that thin vertical fan
across the sky, and a small target far away can hide in the gaps between beams
(seed 003 §3.3).  The turret therefore sweeps between two pan angles and, when a
frame's foreground is not empty, focuses on the detection for a while (§4.2):

- ``swing``: oscillate ±5° about the detection's bearing for N swings;
- ``slowdown``: go on at a quarter of the sweep rate for 10° of pan;
- ``stop``: hold on the detection's bearing for 5 s;

and then sweeps again from where it is, in the direction it is moving.  A
detection whose bearing differs from the running cycle's by more than a threshold
("significant movement ... between consecutive centroids") restarts the cycle on
the new bearing.  ``adaptive`` (the thesis's future work, §8.1.1) picks one of the
three per detection from the target's range and speed (``choose_strategy``).

The motions are small pure functions of the time since they started, in
``dronetrack.control.plans``: ``sweep`` (an endless triangle wave) and ``Plan`` (a
finite piecewise-linear pan profile, built by ``swing_plan``, ``slowdown_plan`` and
``stop_plan``); they are re-exported here.  ``ScanStrategyController`` strings them
together and duck-types the interface of ``TurretController`` the pipeline drives.
Angles are radians, rates rad/s.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Literal, NamedTuple, get_args

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.control.plans import (
    BEAM_GAP,
    FAN_HALF_WIDTH,
    SLOWDOWN_FACTOR,
    SLOWDOWN_SPAN,
    STOP_HOLD_S,
    SWEEP_LIMITS,
    SWEEP_RATE,
    SWING_AMPLITUDE,
    SWING_COUNT,
    TARGET_SIZE_M,
    Plan,
    Strategy,
    choose_strategy,
    slowdown_plan,
    stop_plan,
    sweep,
    swing_plan,
    swing_time_bound,
)
from dronetrack.errors import ConfigError
from dronetrack.geometry.mount import MountGeometry
from dronetrack.geometry.transforms import FloatArray, wrap_angle
from dronetrack.types import Candidates, TrackEstimate, TurretCommand

__all__ = ["MODES", "Mode", "ScanStrategyController", "State", "Transition"]

State = Literal["sweep", "swing", "slowdown", "stop"]
# "sweep" never reacts (the thesis's Sweeping benchmark); "adaptive" chooses per detection.
Mode = Literal["sweep", "swing", "slowdown", "stop", "adaptive"]
MODES: tuple[str, ...] = get_args(Mode)

RETRIGGER_ANGLE = math.radians(5.0)  # [A] "significant movement" between centroids


class Transition(NamedTuple):
    """A change of state: a row of seed 003's "state" log."""

    t: float  # [s]
    from_state: str
    to_state: str
    strategy: str  # the controller's mode


class ScanStrategyController:
    """Seed 003's pan-only turret: sweep, and swing, slow down or stop on detections.

    Drop-in for ``TurretController``: ``mode``, ``home``, ``scanning(t)`` and
    ``tracking(t, estimate, points)``.  Commands are position goals for time t; the
    tilt stays at ``tilt``.  The state changes are kept in ``transitions``.

    A cycle starts on a detection (a non-empty foreground) while sweeping if it is
    the first, or its bearing is more than ``retrigger_angle`` from the last
    cycle's, or the sweep has since turned more than ``fan_half_width`` away from
    that bearing (the target left the fan, so seeing it again is news).  During a
    cycle a detection more than ``retrigger_angle`` from the cycle's bearing
    restarts it there; nearer ones leave it running.
    """

    def __init__(
        self,
        mount: MountGeometry,
        pan_limits: tuple[float, float],
        tilt_limits: tuple[float, float],
        mode: Mode = "swing",
        *,
        sweep_limits: tuple[float, float] = SWEEP_LIMITS,
        sweep_rate: float = SWEEP_RATE,
        tilt: float = 0.0,
        start_pan: float = 0.0,
        swing_amplitude: float = SWING_AMPLITUDE,
        swing_count: int = SWING_COUNT,
        swing_rate: float | None = None,
        slowdown_factor: float = SLOWDOWN_FACTOR,
        slowdown_span: float = SLOWDOWN_SPAN,
        stop_hold_s: float = STOP_HOLD_S,
        retrigger_angle: float = RETRIGGER_ANGLE,
        fan_half_width: float = FAN_HALF_WIDTH,
        beam_gap: float = BEAM_GAP,
        target_size_m: float = TARGET_SIZE_M,
        speed_gap_s: float = 1.0,
    ) -> None:
        if mode not in MODES:
            raise ConfigError(f"unknown scan strategy {mode!r}; choose one of {', '.join(MODES)}")
        lo = max(sweep_limits[0], pan_limits[0])
        hi = min(sweep_limits[1], pan_limits[1])
        if not lo < hi:
            raise ConfigError(
                f"sweep limits {sweep_limits} leave no range within the pan limits {pan_limits}"
            )
        rate = sweep_rate if swing_rate is None else swing_rate
        for name, value in (("sweep_rate", sweep_rate), ("swing_rate", rate)):
            if not (math.isfinite(value) and value > 0.0):
                raise ConfigError(f"{name} must be > 0, got {value}")
        if not 0.0 < slowdown_factor <= 1.0:
            raise ConfigError(f"slowdown_factor must be in (0, 1], got {slowdown_factor}")
        checks = {
            "swing_amplitude": swing_amplitude,
            "swing_count": swing_count,
            "slowdown_span": slowdown_span,
            "stop_hold_s": stop_hold_s,
            "retrigger_angle": retrigger_angle,
            "fan_half_width": fan_half_width,
            "speed_gap_s": speed_gap_s,
        }
        for name, value in checks.items():
            if not (math.isfinite(value) and value >= 0.0):
                raise ConfigError(f"{name} must be ≥ 0, got {value}")
        if not (beam_gap > 0.0 and target_size_m > 0.0):
            raise ConfigError("beam_gap and target_size_m must be > 0")
        self.mount = mount
        self.pan_limits = pan_limits
        self.tilt_limits = tilt_limits
        self.mode: Mode = mode
        self.sweep_limits = (lo, hi)
        self.sweep_rate = sweep_rate
        self.tilt = tilt
        self.home = (min(max(start_pan, lo), hi), tilt)
        self.swing = (swing_amplitude, int(swing_count), rate)
        self.slowdown = (slowdown_factor, slowdown_span)
        self.stop_hold_s = stop_hold_s
        self.retrigger_angle = retrigger_angle
        self.fan_half_width = fan_half_width
        self.beam_gap = beam_gap
        self.target_size_m = target_size_m
        self.speed_gap_s = speed_gap_s
        self.transitions: list[Transition] = []
        # The running segment: a sweep from (t0, pan, direction), or a cycle's plan.
        self._state: State = "sweep"
        self._t0: float | None = None
        self._sweep_from: tuple[float, int] = (self.home[0], 1)
        self._plan: Plan | None = None
        self._bearing: float | None = None  # of the running or last cycle
        self._left_fan = False  # the sweep turned away from that bearing since
        # Recent detections' (time, centroid), for a speed when the tracker has none.
        self._centroids: deque[tuple[float, FloatArray]] = deque()

    @property
    def state(self) -> State:
        """What the turret is doing: sweep, swing, slowdown or stop."""
        return self._state

    def scanning(self, t: float) -> TurretCommand:
        """The background scan at time t: the sweep."""
        self._advance(t)
        return self._command(t)

    def tracking(
        self,
        t: float,
        estimate: TrackEstimate | None,
        points: ArrayLike | None = None,
        candidates: Candidates | None = None,
        cues: Candidates | None = None,
    ) -> TurretCommand | None:
        """The command for time t after a frame with foreground ``points`` (M, 3), world [m].

        ``estimate`` gives the target's velocity for ``adaptive`` when it is tracked.
        Seed 003's strategies react to the foreground as published: ``candidates`` and
        ``cues`` are not used.
        """
        self._advance(t)
        pts = np.asarray(points if points is not None else (), dtype=np.float64).reshape(-1, 3)
        pts = pts[np.all(np.isfinite(pts), axis=1)]
        if len(pts) and self.mode != "sweep":
            while self._centroids and t - self._centroids[0][0] > self.speed_gap_s:
                self._centroids.popleft()
            centroid = pts.mean(axis=0)
            rel = centroid - self.mount.base_vec
            bearing = math.atan2(float(rel[1]), float(rel[0]))
            moved = self._bearing is None or abs(float(wrap_angle(bearing - self._bearing))) > (
                self.retrigger_angle
            )
            if moved or (self._state == "sweep" and self._left_fan):
                speed = self._cross_speed(t, centroid, bearing, estimate)
                self._start_cycle(t, bearing, float(np.linalg.norm(rel)), speed)
            self._centroids.append((t, centroid))
        return self._command(t)

    # -- internals -----------------------------------------------------------

    def _position(self, t: float) -> tuple[float, int]:
        assert self._t0 is not None
        elapsed = t - self._t0
        if self._plan is not None:
            return self._plan.at(elapsed)
        lo, hi = self.sweep_limits
        return sweep(elapsed, *self._sweep_from, lo, hi, self.sweep_rate)

    def _advance(self, t: float) -> None:
        """Start the clock on the first call; end a cycle whose time is up."""
        if self._t0 is None:
            self._t0 = t
        if self._plan is not None and t - self._t0 >= self._plan.duration:
            end = self._t0 + self._plan.duration
            self._sweep_from = self._plan.at(self._plan.duration)
            self.transitions.append(Transition(end, self._state, "sweep", self.mode))
            self._state, self._t0, self._plan = "sweep", end, None
            self._left_fan = False
        if self._state == "sweep" and self._bearing is not None and not self._left_fan:
            pan = self._position(t)[0]
            self._left_fan = abs(float(wrap_angle(pan - self._bearing))) > self.fan_half_width

    def _start_cycle(self, t: float, bearing: float, range_m: float, speed: float | None) -> None:
        pan, direction = self._position(t)
        lo, hi = self.sweep_limits
        amplitude, count, rate = self.swing
        strategy: Strategy
        if self.mode == "adaptive":
            strategy = choose_strategy(
                range_m,
                speed,
                fan_half_width=self.fan_half_width,
                beam_gap=self.beam_gap,
                target_size_m=self.target_size_m,
                swing_amplitude=amplitude,
                swing_duration_s=swing_time_bound(amplitude, count, rate, self.fan_half_width),
                stop_hold_s=self.stop_hold_s,
            )
        elif self.mode in ("swing", "slowdown", "stop"):
            strategy = self.mode
        else:  # pragma: no cover - "sweep" never starts a cycle
            raise AssertionError(self.mode)
        if strategy == "swing":
            plan = swing_plan(pan, direction, bearing, lo, hi, amplitude, rate, count)
        elif strategy == "slowdown":
            plan = slowdown_plan(pan, direction, lo, hi, self.sweep_rate, *self.slowdown)
        else:
            plan = stop_plan(bearing, direction, lo, hi, self.stop_hold_s)
        self.transitions.append(Transition(t, self._state, strategy, self.mode))
        self._state, self._t0, self._plan = strategy, t, plan
        self._bearing = bearing
        self._left_fan = False
        # A plan that takes no time (a zero hold, say) is over at once.
        self._advance(t)

    def _cross_speed(
        self, t: float, centroid: FloatArray, bearing: float, estimate: TrackEstimate | None
    ) -> float | None:
        """The target's horizontal speed across the line of sight [m/s], None if unknown.

        The tracker's velocity when it holds the target.  Else the centroids': from
        the oldest earlier detection at most ``speed_gap_s`` old to this one.  The
        longest baseline, because a frame's centroid is wherever the thin fan cut
        the drone: from one frame to the next it jumps by a fraction of the
        drone's size, which over 0.1 s reads as metres per second.
        """
        velocity: FloatArray | None = None
        if estimate is not None and estimate.tracked and np.all(np.isfinite(estimate.velocity)):
            velocity = np.asarray(estimate.velocity, dtype=np.float64)
        elif self._centroids:
            t_prev, c_prev = self._centroids[0]
            if t > t_prev:
                velocity = (centroid - c_prev) / (t - t_prev)
        if velocity is None:
            return None
        across = -math.sin(bearing) * float(velocity[0]) + math.cos(bearing) * float(velocity[1])
        return abs(across)

    def _command(self, t: float) -> TurretCommand:
        pan = min(max(self._position(t)[0], self.pan_limits[0]), self.pan_limits[1])
        tilt = min(max(self.tilt, self.tilt_limits[0]), self.tilt_limits[1])
        return TurretCommand(t, pan, tilt)
