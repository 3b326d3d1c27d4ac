"""Seed 003's scan motions: pure pan profiles of the time since they started.

``sweep`` is an endless triangle wave between two pan angles.  ``Plan`` is a
finite piecewise-linear pan profile, built by ``sweep_plan``, ``swing_plan``,
``slowdown_plan`` and ``stop_plan`` for the three reactions to a detection
(seed 003 §4.2, §5.3):

- ``swing``: oscillate ±5° about the detection's bearing for N swings;
- ``slowdown``: go on at a quarter of the sweep rate for 10° of pan;
- ``stop``: hold on the detection's bearing for 5 s.

``choose_strategy`` picks one of the three from the target's range and speed
(``adaptive``, the thesis's future work, §8.1.1), and ``swing_time_bound`` bounds
a swing cycle's length for it.  ``dronetrack.control.strategies`` strings these
motions together into a turret controller.  Angles are radians, rates rad/s.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from typing import Literal

from dronetrack.errors import ConfigError

__all__ = [
    "BEAM_GAP",
    "FAN_HALF_WIDTH",
    "SLOWDOWN_FACTOR",
    "SLOWDOWN_SPAN",
    "STOP_HOLD_S",
    "SWEEP_LIMITS",
    "SWEEP_RATE",
    "SWING_AMPLITUDE",
    "SWING_COUNT",
    "TARGET_SIZE_M",
    "Plan",
    "Strategy",
    "choose_strategy",
    "slowdown_plan",
    "stop_plan",
    "sweep",
    "sweep_plan",
    "swing_plan",
    "swing_time_bound",
]

Strategy = Literal["swing", "slowdown", "stop"]

# The side-mounted VLP-16's fan: lasers at ±15°, 2° apart (seed 003 §3.1.3, §3.3).
FAN_HALF_WIDTH = math.radians(15.0)
BEAM_GAP = math.radians(2.0)

# The thesis gives no sweep rate.  30°/s: at the VLP-16's 600 rpm the fan moves 3°
# per revolution, 1.5 beam gaps, so successive revolutions interleave their beams
# 1° apart, halving the gap a target can hide in; a bearing stays in the 30° fan
# for 1 s (10 revolutions) per pass; and a ±90° sweep (12 s period) comes back to
# a bearing after 6 s on average (up to 12 s near the ends), like the 8.2 s
# "maximum time between detections" the thesis measured for Sweeping (Table 1).
# The PTU-E46 turns at over 300°/s.
SWEEP_RATE = math.radians(30.0)
SWEEP_LIMITS = (math.radians(-90.0), math.radians(90.0))
SWING_AMPLITUDE = math.radians(5.0)  # §5.3: "5° to the left and 5° to the right"
SWING_COUNT = 3  # [A] the thesis counts swings but does not give the number
SLOWDOWN_FACTOR = 0.25  # §5.3: "one-quarter of its original rate"
SLOWDOWN_SPAN = math.radians(10.0)  # §5.3: "for a 10° angular span"
STOP_HOLD_S = 5.0  # §5.3: "a fixed duration of 5 seconds"
TARGET_SIZE_M = 0.5  # [A] a small multirotor across its motors


def _sign(direction: float) -> int:
    return 1 if direction >= 0 else -1


def _check_range(lo: float, hi: float, rate: float) -> None:
    if not (math.isfinite(lo) and math.isfinite(hi) and lo <= hi):
        raise ConfigError(f"pan range must be finite with lo ≤ hi, got ({lo}, {hi})")
    if not (math.isfinite(rate) and rate > 0.0):
        raise ConfigError(f"pan rate must be > 0, got {rate}")


def sweep(
    elapsed: float,
    start: float,
    direction: int,
    lo: float = SWEEP_LIMITS[0],
    hi: float = SWEEP_LIMITS[1],
    rate: float = SWEEP_RATE,
) -> tuple[float, int]:
    """Pan and direction ``elapsed`` seconds into a sweep between ``lo`` and ``hi``.

    The sweep leaves ``start`` (clipped into [lo, hi]) in ``direction`` (+1 towards
    ``hi``, −1 towards ``lo``) at ``rate`` and bounces off the limits: a triangle
    wave of period 2 (hi − lo) / rate.  Sweeping a then b equals sweeping a + b, so
    a sweep resumed from where another left off continues it.  At a limit the
    direction returned is the one away from it.
    """
    _check_range(lo, hi, rate)
    d = _sign(direction)
    pan = min(max(start, lo), hi)
    span = hi - lo
    if span == 0.0:
        return pan, d
    # Unfold the triangle onto a circle of length 2·span: s in [0, span) on the way
    # up, in [span, 2·span) on the way down.
    s = pan - lo if d > 0 else 2.0 * span - (pan - lo)
    s = (s + rate * max(elapsed, 0.0)) % (2.0 * span)
    if s < span:
        return lo + s, 1
    return lo + 2.0 * span - s, -1


@dataclass(frozen=True, slots=True)
class Plan:
    """A finite pan profile: straight lines between knots, then ``direction``.

    times: knot times from the start [s], strictly increasing from 0.
    pans: pan at each knot [rad].
    direction: the direction of travel once the plan is over (and while it holds
        still): the sweep that follows leaves in it.
    """

    times: tuple[float, ...]
    pans: tuple[float, ...]
    direction: int

    @property
    def duration(self) -> float:
        return self.times[-1]

    def at(self, elapsed: float) -> tuple[float, int]:
        """Pan and direction of travel ``elapsed`` seconds into the plan."""
        if elapsed >= self.times[-1]:
            return self.pans[-1], self.direction
        e = max(elapsed, 0.0)
        i = bisect_right(self.times, e) - 1
        t0, t1 = self.times[i], self.times[i + 1]
        p0, p1 = self.pans[i], self.pans[i + 1]
        pan = p0 + (p1 - p0) * (e - t0) / (t1 - t0)
        return pan, (self.direction if p1 == p0 else _sign(p1 - p0))


class _Knots:
    """Builds a Plan, dropping knots that take no time."""

    def __init__(self, pan: float) -> None:
        self.times = [0.0]
        self.pans = [pan]

    def go(self, pan: float, rate: float) -> None:
        dt = abs(pan - self.pans[-1]) / rate
        if dt > 0.0:
            self.times.append(self.times[-1] + dt)
            self.pans.append(pan)

    def hold(self, dt: float) -> None:
        if dt > 0.0:
            self.times.append(self.times[-1] + dt)
            self.pans.append(self.pans[-1])

    def plan(self, direction: int) -> Plan:
        return Plan(tuple(self.times), tuple(self.pans), _sign(direction))


def sweep_plan(
    start: float, direction: int, lo: float, hi: float, rate: float, duration: float
) -> Plan:
    """``sweep`` for ``duration`` seconds as a Plan (knots at the bounces)."""
    _check_range(lo, hi, rate)
    pan = min(max(start, lo), hi)
    d = _sign(direction)
    knots = _Knots(pan)
    left = max(duration, 0.0) * rate  # pan still to travel
    if hi == lo:
        knots.hold(max(duration, 0.0))
        return knots.plan(d)
    while left > 0.0:
        room = hi - pan if d > 0 else pan - lo
        if room >= left:
            pan += d * left
            knots.go(pan, rate)
            break
        pan = hi if d > 0 else lo
        knots.go(pan, rate)
        left -= room
        d = -d
    # Ending on a limit the way it was going: the sweep that follows bounces.
    return knots.plan(d)


def swing_plan(
    start: float,
    direction: int,
    bearing: float,
    lo: float = SWEEP_LIMITS[0],
    hi: float = SWEEP_LIMITS[1],
    amplitude: float = SWING_AMPLITUDE,
    rate: float = SWEEP_RATE,
    n_swings: int = SWING_COUNT,
) -> Plan:
    """Oscillate ±``amplitude`` about ``bearing`` for ``n_swings`` edge-to-edge swings.

    The window [bearing − a, bearing + a] is shifted, if need be, to lie within
    [lo, hi].  From ``start`` the turret first goes at ``rate`` to an edge of the
    window: the one ahead if it is inside the window, else the nearer one.  Each
    swing then crosses the window once, 2a; the plan ends on an edge, moving the
    way the last swing went.
    """
    _check_range(lo, hi, rate)
    a = min(max(amplitude, 0.0), 0.5 * (hi - lo))
    c = min(max(bearing, lo + a), hi - a)
    w0, w1 = c - a, c + a
    pan = min(max(start, lo), hi)
    d = _sign(direction)
    if pan < w0:
        first, swing_dir = w0, 1
    elif pan > w1:
        first, swing_dir = w1, -1
    else:
        first, swing_dir = (w1, -1) if d > 0 else (w0, 1)
    knots = _Knots(pan)
    knots.go(first, rate)
    end_dir = d if first == pan else _sign(first - pan)
    for _ in range(max(n_swings, 0)):
        knots.go(w1 if swing_dir > 0 else w0, rate)
        end_dir, swing_dir = swing_dir, -swing_dir
    return knots.plan(end_dir)


def slowdown_plan(
    start: float,
    direction: int,
    lo: float = SWEEP_LIMITS[0],
    hi: float = SWEEP_LIMITS[1],
    rate: float = SWEEP_RATE,
    factor: float = SLOWDOWN_FACTOR,
    span: float = SLOWDOWN_SPAN,
) -> Plan:
    """Sweep on at ``factor`` × ``rate`` until ``span`` of pan has been covered."""
    if not (math.isfinite(factor) and 0.0 < factor <= 1.0):
        raise ConfigError(f"slowdown factor must be in (0, 1], got {factor}")
    slow = factor * rate
    return sweep_plan(start, direction, lo, hi, slow, max(span, 0.0) / slow)


def stop_plan(
    bearing: float,
    direction: int,
    lo: float = SWEEP_LIMITS[0],
    hi: float = SWEEP_LIMITS[1],
    hold_s: float = STOP_HOLD_S,
) -> Plan:
    """Point at ``bearing`` (clipped into [lo, hi]) for ``hold_s``, then sweep on in ``direction``.

    The goal jumps to the bearing: the turret's own rate limit shapes the move.
    """
    knots = _Knots(min(max(bearing, lo), hi))
    knots.hold(hold_s)
    return knots.plan(direction)


def swing_time_bound(
    amplitude: float = SWING_AMPLITUDE,
    n_swings: int = SWING_COUNT,
    rate: float = SWEEP_RATE,
    fan_half_width: float = FAN_HALF_WIDTH,
) -> float:
    """The longest a swing cycle lasts [s]: the approach plus N swings of 2a.

    A detection lies within the fan, so at most ``fan_half_width`` from the pan; the
    approach to the window's edge is at most max(2a, half width − a).
    """
    approach = max(2.0 * amplitude, fan_half_width - amplitude)
    return (approach + max(n_swings, 0) * 2.0 * amplitude) / rate


def choose_strategy(
    range_m: float,
    speed_m_s: float | None,
    *,
    fan_half_width: float = FAN_HALF_WIDTH,
    beam_gap: float = BEAM_GAP,
    target_size_m: float = TARGET_SIZE_M,
    swing_amplitude: float = SWING_AMPLITUDE,
    swing_duration_s: float = swing_time_bound(),
    stop_hold_s: float = STOP_HOLD_S,
) -> Strategy:
    """Swing, slow down or stop for a detection at ``range_m`` moving at ``speed_m_s``.

    ``speed_m_s`` is the target's speed across the line of sight in azimuth (the
    speed itself if that is all there is: an upper bound), None if unknown.

    Reasoning.  The side-mounted fan is 2W = 30° wide in azimuth with beams every
    g = 2°.  A target at range r moving at v across the line of sight drifts
    through the fan at ω = v / r.  (For a target at elevation φ the fan's angles
    are azimuths times cos φ, and so are the target's size and drift: both
    scale alike, so slant range and azimuthal speed give the fan's own angles.)

    - A target wider than a gap, D ≥ g r, i.e. r ≤ r_gap = D / g (14 m for 0.5 m),
      is hit whenever it is in the fan, even by a still fan.  Farther out it can
      sit between two beams, and pointing the fan's centre at it is the worst
      case: the VLP-16's lasers are at odd degrees, so the centre is in a gap.
    - ``stop`` holds the fan still on the target for T_hold: it keeps it in view
      while ω T_hold ≤ W (3°/s by default) and sees it every revolution only if
      it spans a gap.  So: stop when r ≤ r_gap and ω ≤ W / T_hold.  It gives the
      most detections (the thesis's Table 1 and §5.3, for slow targets).
    - ``swing`` keeps [bearing − (W − a), bearing + (W − a)] in the fan all the
      time, and its motion slides the beams across the target (3° per
      revolution at 30°/s: successive revolutions interleave 1° apart, and each
      turn-around shifts the grid again), so a far target does not stay hidden
      in one gap.  It keeps the target while ω T_swing ≤ W − a (7.5°/s by
      default).  So: swing when the target is too far or a little too fast for
      a stop, and slow enough to stay in the window.  The thesis finds it the
      most accurate (Table 1), and it is the choice when the speed is unknown.
    - ``slowdown`` when ω > (W − a) / T_swing: no held window keeps such a target
      for the whole cycle, its own drift already carries it across the gaps (one
      gap in g / ω < 0.3 s), and slowing down costs the scan least (a quarter
      rate for 10°, then on).  A bearing jump beyond the re-trigger threshold
      restarts the slowdown where the target went, so repeated slowdowns follow
      it in steps (§5.3: slowdown suits "objects moving at higher speeds", §8.1.1).

    Boundaries are inclusive on the calmer side: ω = W / T_hold still stops,
    ω = (W − a) / T_swing still swings, r = r_gap may still stop.
    """
    r = max(range_m, 1e-9) if math.isfinite(range_m) else math.inf
    if speed_m_s is None or not math.isfinite(speed_m_s):
        return "swing"
    omega = abs(speed_m_s) / r
    if omega > max(fan_half_width - swing_amplitude, 0.0) / swing_duration_s:
        return "slowdown"
    r_gap = target_size_m / beam_gap
    if r <= r_gap and omega * stop_hold_s <= fan_half_width:
        return "stop"
    return "swing"
