"""The seeds' flights and walks as named trajectories (world frame, turret base at the origin).

Seed 000 (Gazdag et al.), outdoor, DJI Phantom 4 (§III-A to III-D, Fig. 2 and 6):
flights at constant altitude or in a vertical line, reaching about 140-150 m,
beyond the range where points stop coming back.  Their exact paths are not
published; these keep the published speeds (≈15 m/s fast, ≈6 m/s in the field
tests) and shapes (passes across the line of sight, straight runs out and back).

Seed 000, indoor, Crazyflie 2.0 (§III-E, Fig. 9): patterns about 3 m in front of
the sensor; each leg flown in 3 s (max ≈0.6 m/s) or 2.25 s for the fast pattern
(max ≈1.2 m/s), a 2 s wait at every waypoint, repeated 3 times (horizontal,
vertical) or 4 times (fast, lost-and-found).  A trapezoid with a = v gives
exactly those leg times: t = L/v + v/a.

Seed 003 (Cerutti): a walker holding a board above their head, walking straight
towards the sensor and back, across it at 3, 7 and 12 m, and in a square.

Seed 002 (Khosravi et al.): a DJI F550 observer carrying a Mid-360 tracks
another F550 in randomised manoeuvres; tracking broke down when the target went
beyond about 50 m.  ``relative-out-and-back`` flies such manoeuvres about a path
out to 55 m and back; ``observer-hover`` and ``observer-orbit`` are flights for
the observer (``[observer]`` in a scenario), at 10 m altitude.

Every seed 000 and 003 flight starts on the ground below its first waypoint,
where it waits ``hold`` seconds (the background scan) before it takes off; the
random manoeuvres, the observer flights and the busy-site flights
(``sim/site_flights.py``) start in the air and hold there.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dronetrack.errors import TrajectoryError
from dronetrack.sim.group_flights import SWARM_OFFSETS, crossing, swarm_member
from dronetrack.sim.site_flights import close_hover, site_roam, unscanned
from dronetrack.sim.trajectories import (
    PiecewiseAcceleration,
    Superposed,
    Trajectory,
    Waypoint,
    fly_waypoints,
    polar,
    random_manoeuvres,
)

__all__ = ["FLIGHTS", "Flight", "make_flight"]

Builder = Callable[[float, float, np.random.Generator], Trajectory]


@dataclass(frozen=True, slots=True)
class Flight:
    """A named trajectory and the text that describes it."""

    description: str
    build: Builder  # (hold [s], duration [s], rng) -> Trajectory


def _route(
    points: list[tuple[float, float, float]], speed: float, accel: float, dwell: float = 0.0
) -> list[Waypoint]:
    return [Waypoint(p, speed, accel, dwell) for p in points]


def _takeoff_and_fly(
    first: tuple[float, float, float],
    route: list[Waypoint],
    hold: float,
    ground_z: float,
    climb: float,
    climb_accel: float,
    first_dwell: float = 0.0,
) -> Trajectory:
    start = (first[0], first[1], ground_z)
    takeoff = Waypoint(first, climb, climb_accel, first_dwell)
    return fly_waypoints(start, [takeoff, *route], hold=hold)


def _outdoor(
    route: list[tuple[float, float, float]],
    speed: float,
    accel: float,
    far_dwell: dict[int, float] | None = None,
) -> Callable[[float, float, np.random.Generator], Trajectory]:
    def build(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
        wps = [
            Waypoint(p, speed, accel, (far_dwell or {}).get(i, 0.0))
            for i, p in enumerate(route[1:])
        ]
        return _takeoff_and_fly(route[0], wps, hold, 0.15, 3.0, 2.0, 1.0)

    return build


_PASSES = [(15.0, 0.0, 20.0)]
for _i, _x in enumerate((30.0, 55.0, 80.0, 105.0, 135.0)):
    _side = 1.0 if _i % 2 == 0 else -1.0
    _PASSES += [(_x, -40.0 * _side, 20.0), (_x, 40.0 * _side, 20.0)]
_PASSES += [(20.0, 0.0, 20.0)]


def _indoor(
    points: list[tuple[float, float, float]], speed: float, repeats: int, ping_pong: bool = False
) -> Builder:
    def build(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
        cycle = points[1:] + points[:1] if not ping_pong else points[1:] + points[-2::-1]
        route = _route(cycle * repeats, speed, speed, 2.0)
        return _takeoff_and_fly(points[0], route, hold, 0.01, 0.5, 0.5, 2.0)

    return build


def _walk(points: list[tuple[float, float, float]], repeats: int) -> Builder:
    def build(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
        cycle = points[1:] + points[:1]
        start = points[0]
        return fly_waypoints(start, _route(cycle * repeats, 1.2, 1.0, 0.5), hold=hold)

    return build


def _aggressive(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    return random_manoeuvres(
        rng,
        max(duration - hold, 1.0),
        v_max=8.0,
        a_max=6.0,
        center=(15.0, 0.0, 6.0),
        half_extent=(8.0, 8.0, 3.0),
        t0=hold,
    )


# Seed 002's target: a loop out to 55 m and back at 12 m altitude, flown at 5 m/s
# (2.5 m/s² at the corners), with random manoeuvres (≤ 4 m/s, ≤ 4 m/s²) inside a
# ±4 × 4 × 1.5 m box about it: at most 9 m/s and 6.5 m/s² in all.
_RELATIVE_LOOP = [(30.0, 10.0, 12.0), (55.0, 0.0, 12.0), (30.0, -10.0, 12.0), (12.0, 0.0, 12.0)]
_RELATIVE_LOOP_S = 27.0  # one loop at 5 m/s with its corners, a little over


def _relative_out_and_back(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    loops = max(1, math.ceil(max(duration, 1.0) / _RELATIVE_LOOP_S))
    path = fly_waypoints((12.0, 0.0, 12.0), _route(_RELATIVE_LOOP * loops, 5.0, 2.5), hold=hold)
    wobble = random_manoeuvres(
        rng,
        max(duration, 1.0),
        v_max=4.0,
        a_max=4.0,
        center=(0.0, 0.0, 0.0),
        half_extent=(4.0, 4.0, 1.5),
        t0=hold,
    )
    return Superposed(path, wobble)


# The observer flights: at 10 m altitude, 5 m behind the turret-site origin, where a
# target flying ``relative-out-and-back`` or ``aggressive`` never comes within 5 m.
_OBSERVER_CENTER = (-5.0, 0.0, 10.0)
_ORBIT_RADIUS = 8.0  # [m]
_ORBIT_SPEED = 2.5  # [m/s]
_ORBIT_ACCEL = 1.0  # tangential, while it speeds up [m/s²]
_ORBIT_DT = 0.05  # [s]


def _observer_hover(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    # A hovering drone wanders: ≤ 0.3 m/s within ±1 × 1 × 0.3 m, slowly changing course.
    return random_manoeuvres(
        rng,
        max(duration, 1.0) + 10.0,
        v_max=0.3,
        a_max=0.3,
        center=_OBSERVER_CENTER,
        half_extent=(1.0, 1.0, 0.3),
        mean_hold=3.0,
        t0=hold,
    )


def _observer_orbit(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    """A counter-clockwise circle of radius r at speed v, from rest at centre + (r, 0, 0).

    Arc length s(τ) = ½ a τ² until τ_v = v / a, then s(τ_v) + v (τ − τ_v); the
    position c + r (cos s/r, sin s/r, 0) is sampled every dt and joined by constant
    accelerations, each chosen so the segment ends exactly at the next sample.
    """
    r, v, acc, dt = _ORBIT_RADIUS, _ORBIT_SPEED, _ORBIT_ACCEL, _ORBIT_DT
    n = max(2, math.ceil((max(duration, 1.0) + 10.0) / dt))
    tau = dt * np.arange(n + 1, dtype=np.float64)
    t_v = v / acc
    s = np.where(tau < t_v, 0.5 * acc * tau**2, 0.5 * acc * t_v**2 + v * (tau - t_v))
    speed = np.minimum(acc * tau, v)
    theta = s / r
    c = np.asarray(_OBSERVER_CENTER, dtype=np.float64)
    zeros = np.zeros_like(theta)
    p = c + r * np.column_stack([np.cos(theta), np.sin(theta), zeros])
    vel = speed[:, None] * np.column_stack([-np.sin(theta), np.cos(theta), zeros])
    # p_{k+1} = p_k + v_k dt + ½ a_k dt²
    a = 2.0 * (p[1:] - p[:-1] - vel[:-1] * dt) / dt**2
    segments = PiecewiseAcceleration(knots=hold + tau, p=p[:-1], v=vel[:-1], a=a)
    if hold <= 0:
        return segments
    zero = np.zeros((1, 3))
    return PiecewiseAcceleration(
        knots=np.concatenate([[0.0], segments.knots]),
        p=np.concatenate([p[:1], segments.p]),
        v=np.concatenate([zero, segments.v]),
        a=np.concatenate([zero, segments.a]),
    )


def _incoming(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    # Hovers 170 m out (beyond the Avia's reach for a Phantom 4) 25° off the home bearing
    # during the scan, flies in at 15 m/s (entering the reach about 110 m out), then
    # crosses to the other side at 8 m/s.
    route = [
        Waypoint(polar(25.0, 25.0, 12.0), 15.0, 5.0, 3.0),
        Waypoint(polar(40.0, -20.0, 15.0), 8.0, 4.0),
    ]
    return fly_waypoints(polar(170.0, 25.0, 25.0), route, hold=hold)


def _enter(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    # Waits 70 m out at a bearing of 130°, outside a ±90° field of regard and so outside
    # its background scan, then flies in at 15 m/s: it enters the field at 90° within
    # the Avia's reach, sweeps round to the home bearing and on past it.
    route = _route(
        [polar(70.0, 60.0, 20.0), polar(60.0, 0.0, 15.0), polar(50.0, -60.0, 20.0)], 15.0, 5.0
    )
    return fly_waypoints(polar(70.0, 130.0, 20.0), route, hold=hold)


def _escape(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    # Takes off 30 m out, flies away at 12 m/s to 200 m (beyond reach), moves 40° round
    # out there and comes back in on that bearing.
    route = _route(
        [polar(200.0, 0.0, 20.0), polar(200.0, 40.0, 20.0), polar(30.0, 40.0, 15.0)], 12.0, 4.0
    )
    return _takeoff_and_fly((30.0, 0.0, 20.0), route, hold, 0.15, 3.0, 2.0, 1.0)


def _hide(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    # On the outdoor-barn scene: from 35 m out it flies low behind the barn (53-67 m out,
    # 15-45 m left, 12 m high; out of sight from about 80 m, 22 m left), waits, creeps
    # along behind it and reappears past its far end, 25° further left, climbing.
    route = [
        Waypoint((80.0, 22.0, 8.0), 8.0, 3.0, 3.0),
        Waypoint((95.0, 60.0, 8.0), 5.0, 3.0),
        Waypoint((100.0, 95.0, 20.0), 8.0, 3.0),
        Waypoint((50.0, 60.0, 20.0), 8.0, 3.0),
    ]
    return _takeoff_and_fly((35.0, -5.0, 8.0), route, hold, 0.15, 3.0, 2.0, 1.0)


_SIGN_Z = 2.3  # the board held above the walker's head [m]

FLIGHTS: dict[str, Flight] = {
    "simple-distance": Flight(
        "seed 000: straight out along the boresight to 150 m at 8 m/s, hover, and back",
        _outdoor([(10.0, 0.0, 20.0), (150.0, 0.0, 20.0), (15.0, 0.0, 20.0)], 8.0, 4.0, {0: 8.0}),
    ),
    "vertical": Flight(
        "seed 000: out to 150 m in a vertical line, climbing and descending between 10 and 50 m",
        _outdoor(
            [
                (15.0, 0.0, 10.0),
                (65.0, 0.0, 45.0),
                (100.0, 0.0, 12.0),
                (140.0, 0.0, 50.0),
                (20.0, 0.0, 10.0),
            ],
            6.0,
            3.0,
            {2: 6.0},
        ),
    ),
    "horizontal-slow": Flight(
        "seed 000: 80 m passes across the line of sight at 30-135 m, 5 m/s, 20 m altitude",
        _outdoor(_PASSES, 5.0, 3.0),
    ),
    "horizontal-fast": Flight(
        "seed 000: 80 m passes across the line of sight at 30-135 m, 15 m/s, 20 m altitude",
        _outdoor(_PASSES, 15.0, 15.0),
    ),
    "field": Flight(
        "seed 000 field test: out to 150 m and back at up to 6 m/s, varying range and height",
        _outdoor(
            [
                (15.0, 0.0, 15.0),
                (60.0, 20.0, 25.0),
                (100.0, -20.0, 40.0),
                (150.0, 10.0, 30.0),
                (110.0, 25.0, 20.0),
                (40.0, 0.0, 15.0),
            ],
            6.0,
            3.0,
        ),
    ),
    "seed003-field": Flight(
        "seed 003: laps of a 25 × 25 m loop out to 33 m at 4 m/s, 8-14 m altitude",
        _outdoor(
            [
                (8.0, -5.0, 8.0),
                (30.0, -15.0, 12.0),
                (33.0, 10.0, 14.0),
                (12.0, 12.0, 10.0),
                (8.0, -5.0, 8.0),
                (30.0, -15.0, 12.0),
                (33.0, 10.0, 14.0),
                (12.0, 12.0, 10.0),
                (8.0, -5.0, 8.0),
                (30.0, -15.0, 12.0),
                (33.0, 10.0, 14.0),
                (12.0, 12.0, 10.0),
            ],
            4.0,
            2.0,
        ),
    ),
    "incoming": Flight(
        "enters from 170 m out, 25° off the home bearing, at 15 m/s; then crosses at 8 m/s",
        _incoming,
    ),
    "enter": Flight(
        "from 70 m out at 130°, outside a ±90° field, in across it at 15 m/s to 50 m at −60°",
        _enter,
    ),
    "escape": Flight(
        "from 30 m out away at 12 m/s to 200 m, 40° round out there, and back in on that bearing",
        _escape,
    ),
    "hide": Flight(
        "outdoor-barn: behind the barn at 8 m altitude, waits, reappears past its far end",
        _hide,
    ),
    "crossing-left": Flight(
        "from 170 m out at 30°, 25 m up, in at 12 m/s to 110 m, across at 8 m/s to 60 m at "
        "−30° and away to 150 m; seeded manoeuvres (≤ 2 m/s) about it",
        crossing(1.0, 25.0),
    ),
    "crossing-right": Flight(
        "crossing-left mirrored and 10 m lower: from −30° across to 30°; flown together, the "
        "two cross once, 67 m out on the home bearing",
        crossing(-1.0, 15.0),
    ),
    **{
        f"swarm-{k + 1}": Flight(
            f"swarm member {k + 1} of 4: from 170 m out at 15° in at 10 m/s to 60 m, across "
            f"to −45° and away, ({offset[0]:g}, {offset[1]:g}, {offset[2]:g}) m off the swarm's "
            "route; seeded manoeuvres about it",
            swarm_member(offset),
        )
        for k, offset in enumerate(SWARM_OFFSETS)
    },
    "unscanned": Flight(
        "waits 80 m out at 88°, 15 m up, then in at 10 m/s to 60°, to 20°, back out to "
        "70°, across to −50° and away on the home bearing, waiting 2-3 s at each turn",
        unscanned,
    ),
    "site-roam": Flight(
        "in the air 35 m out on the home bearing, 10 m up, from the start; then random "
        "manoeuvres (≤ 5 m/s, ≤ 3 m/s²) within ±12 × 12 × 3 m about there",
        site_roam,
    ),
    "close-hover": Flight(
        "hovers 2.0-2.9 m from a sensor 1.1 m up from the start, wandering ≤ 0.3 m/s",
        close_hover,
    ),
    "indoor-horizontal": Flight(
        "seed 000 indoor: 1.2 m left-right at 3 m, 3 s legs, 2 s waits, 3 times",
        _indoor([(3.0, 0.6, 1.2), (3.0, -0.6, 1.2)], 0.6, 3),
    ),
    "indoor-vertical": Flight(
        "seed 000 indoor: 1.2 m up-down at 3 m, 3 s legs, 2 s waits, 3 times",
        _indoor([(3.0, 0.0, 0.8), (3.0, 0.0, 2.0)], 0.6, 3),
    ),
    "indoor-fast": Flight(
        "seed 000 indoor: a 1.5 m square at 3 m, 2.25 s legs (1.2 m/s), 2 s waits, 4 times",
        _indoor([(3.0, 0.75, 0.8), (3.0, -0.75, 0.8), (3.0, -0.75, 2.3), (3.0, 0.75, 2.3)], 1.2, 4),
    ),
    "indoor-lost-and-found": Flight(
        "seed 000 indoor: three waypoints at 3.5 m, the middle one behind an occluder, 4 times",
        _indoor([(3.5, 1.2, 1.4), (3.5, 0.0, 1.4), (3.5, -1.2, 1.4)], 0.6, 4, ping_pong=True),
    ),
    "walk-line": Flight(
        "seed 003: walk towards the sensor from 15 m to 3 m and back, 3 times",
        _walk([(15.0, 1.0, _SIGN_Z), (3.0, 1.0, _SIGN_Z)], 3),
    ),
    "walk-across-3": Flight(
        "seed 003: walk across the line of sight at 3 m, 3 times",
        _walk([(3.0, 6.0, _SIGN_Z), (3.0, -6.0, _SIGN_Z)], 3),
    ),
    "walk-across-7": Flight(
        "seed 003: walk across the line of sight at 7 m, 3 times",
        _walk([(7.0, 8.0, _SIGN_Z), (7.0, -8.0, _SIGN_Z)], 3),
    ),
    "walk-across-12": Flight(
        "seed 003: walk across the line of sight at 12 m, 3 times",
        _walk([(12.0, 10.0, _SIGN_Z), (12.0, -10.0, _SIGN_Z)], 3),
    ),
    "walk-square": Flight(
        "seed 003: walk a 16 m square around the sensor, 2 laps",
        _walk(
            [
                (8.0, 8.0, _SIGN_Z),
                (-8.0, 8.0, _SIGN_Z),
                (-8.0, -8.0, _SIGN_Z),
                (8.0, -8.0, _SIGN_Z),
            ],
            2,
        ),
    ),
    "aggressive": Flight(
        "random aggressive manoeuvres (≤ 8 m/s, ≤ 6 m/s²) in a 16 × 16 × 6 m box 15 m out",
        _aggressive,
    ),
    "relative-out-and-back": Flight(
        "seed 002: random manoeuvres (≤ 4 m/s, ≤ 4 m/s²) about a loop out to 55 m and back "
        "at 5 m/s, 12 m altitude",
        _relative_out_and_back,
    ),
    "observer-hover": Flight(
        "seed 002 observer: hovering at 10 m, wandering ≤ 0.3 m/s within ±1 m",
        _observer_hover,
    ),
    "observer-orbit": Flight(
        "seed 002 observer: a circle of 8 m radius at 2.5 m/s, 10 m altitude, behind the origin",
        _observer_orbit,
    ),
}


def make_flight(name: str, hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    """Build the named trajectory; ``hold`` seconds on the ground first."""
    key = name.strip().lower()
    if key not in FLIGHTS:
        raise TrajectoryError(f"unknown trajectory {name!r}; choose one of {', '.join(FLIGHTS)}")
    if hold < 0:
        raise TrajectoryError(f"trajectory hold must not be negative, got {hold}")
    return FLIGHTS[key].build(hold, duration, rng)
