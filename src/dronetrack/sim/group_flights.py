"""Flights for several drones at once (``outdoor-two-drones``, ``outdoor-swarm``),
registered in ``sim/flights.py``'s ``FLIGHTS``.

Each drone flies waypoints with seeded random manoeuvres about them, as
``relative-out-and-back`` does; it waits beyond the Avia's reach for a Phantom 4
(170 m out) until it takes off, so no drone is learnt into the background.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from dronetrack.sim.trajectories import (
    Superposed,
    Trajectory,
    Waypoint,
    fly_waypoints,
    polar,
    random_manoeuvres,
)

__all__ = ["SWARM_OFFSETS", "crossing", "group", "swarm_member"]

Builder = Callable[[float, float, np.random.Generator], Trajectory]

# The manoeuvres about the waypoints: ≤ 2 m/s, ≤ 2 m/s², within ±1.5 × 1.5 × 1 m.
_GROUP_WOBBLE_V = 2.0  # [m/s]
_GROUP_WOBBLE_A = 2.0  # [m/s²]
_GROUP_WOBBLE_BOX = (1.5, 1.5, 1.0)  # half extents [m]


def group(
    start: tuple[float, float, float],
    route: list[Waypoint],
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> Builder:
    """``route`` from ``start``, both moved by ``offset``, with random manoeuvres about it
    from take-off to ``hold + duration``."""

    def moved(p: tuple[float, float, float]) -> tuple[float, float, float]:
        return (p[0] + offset[0], p[1] + offset[1], p[2] + offset[2])

    def build(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
        legs = [Waypoint(moved(w.position), w.speed, w.accel, w.dwell) for w in route]
        path = fly_waypoints(moved(start), legs, hold=hold)
        wobble = random_manoeuvres(
            rng,
            max(duration, 1.0),
            v_max=_GROUP_WOBBLE_V,
            a_max=_GROUP_WOBBLE_A,
            center=(0.0, 0.0, 0.0),
            half_extent=_GROUP_WOBBLE_BOX,
            t0=hold,
        )
        return Superposed(path, wobble)

    return build


def crossing(side: float, z: float) -> Builder:
    """From 170 m out at a bearing of side × 30° in at 12 m/s to 110 m, across at 8 m/s to
    60 m at −side × 30°, and away on that bearing at 10 m/s to 150 m."""
    route = [
        Waypoint(polar(110.0, side * 30.0, z), 12.0, 4.0),
        Waypoint(polar(60.0, -side * 30.0, z), 8.0, 4.0),
        Waypoint(polar(150.0, -side * 30.0, z), 10.0, 4.0),
    ]
    return group(polar(170.0, side * 30.0, z), route)


# The swarm: one route, each drone at its own offset from it (every two 12 m or more
# apart, so at least 7 m with the manoeuvres): in from 170 m at 15° to 60 m on the home
# bearing at 10 m/s, across to 70 m at −45° at 8 m/s, and away to 150 m.
_SWARM_ROUTE = [
    Waypoint(polar(60.0, 0.0, 25.0), 10.0, 4.0),
    Waypoint(polar(70.0, -45.0, 25.0), 8.0, 4.0),
    Waypoint(polar(150.0, -45.0, 30.0), 10.0, 4.0),
]
_SWARM_START = polar(170.0, 15.0, 25.0)
SWARM_OFFSETS: tuple[tuple[float, float, float], ...] = (
    (0.0, 0.0, 0.0),
    (10.0, 6.0, 5.0),
    (-8.0, 8.0, -4.0),
    (4.0, -10.0, 6.0),
)


def swarm_member(offset: tuple[float, float, float]) -> Builder:
    """The swarm's route at ``offset``."""
    return group(_SWARM_START, _SWARM_ROUTE, offset)
