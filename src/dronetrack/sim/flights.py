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

Every flight starts on the ground below its first waypoint, where it waits
``hold`` seconds (the background scan) before it takes off.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dronetrack.errors import TrajectoryError
from dronetrack.sim.trajectories import Trajectory, Waypoint, fly_waypoints, random_manoeuvres

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
}


def make_flight(name: str, hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    """Build the named trajectory; ``hold`` seconds on the ground first."""
    key = name.strip().lower()
    if key not in FLIGHTS:
        raise TrajectoryError(f"unknown trajectory {name!r}; choose one of {', '.join(FLIGHTS)}")
    if hold < 0:
        raise TrajectoryError(f"trajectory hold must not be negative, got {hold}")
    return FLIGHTS[key].build(hold, duration, rng)
