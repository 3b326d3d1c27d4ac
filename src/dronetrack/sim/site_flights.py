"""Flights of the busy-site scenarios (``outdoor-unscanned``, ``site-busy``,
``mid360-static``), registered in ``sim/flights.py``'s ``FLIGHTS``.

Unlike seed 000's flights these start in the air, where they wait ``hold`` seconds
(the background scan): ``unscanned`` off the scanned sector, ``site-roam`` and
``close-hover`` in the sensor's view from the first frame.
"""

from __future__ import annotations

import numpy as np

from dronetrack.sim.trajectories import (
    Trajectory,
    Waypoint,
    fly_waypoints,
    polar,
    random_manoeuvres,
)

__all__ = [
    "CLOSE_HOVER_BOX_M",
    "CLOSE_HOVER_CENTER_M",
    "UNSCANNED_START",
    "close_hover",
    "site_roam",
    "unscanned",
]

# unscanned: (range [m], bearing [deg], height [m]) of its waypoints, and of its start.
UNSCANNED_START = (80.0, 88.0, 15.0)
_UNSCANNED_ROUTE = (
    ((70.0, 60.0, 12.0), 3.0),  # waypoint, dwell [s]
    ((55.0, 20.0, 15.0), 2.0),
    ((80.0, 70.0, 18.0), 3.0),
    ((60.0, -50.0, 15.0), 3.0),
    ((100.0, 0.0, 20.0), 0.0),
)


def unscanned(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    """Waits 80 m out at 88°, 15 m up, then flies in at up to 10 m/s (4 m/s²): to 60°,
    in to the home bearing's side (20°), back out to 70°, across to −50° and away to
    100 m on the home bearing, waiting 2-3 s at each turn."""
    route = [Waypoint(polar(*point), 10.0, 4.0, dwell) for point, dwell in _UNSCANNED_ROUTE]
    return fly_waypoints(polar(*UNSCANNED_START), route, hold=hold)


def site_roam(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    """Hovers 35 m out on the home bearing, 10 m up, for 3 s after ``hold``, then flies
    seeded random manoeuvres (≤ 5 m/s, ≤ 3 m/s²) within ±12 × 12 × 3 m about there."""
    return random_manoeuvres(
        rng,
        max(duration, 1.0),
        v_max=5.0,
        a_max=3.0,
        center=(35.0, 0.0, 10.0),
        half_extent=(12.0, 12.0, 3.0),
        mean_hold=2.0,
        t0=hold + 3.0,
    )


# close-hover: a hovering drone's wander, ≤ 0.3 m/s within this box about its centre;
# 2.0-2.9 m from a sensor 1.14 m up at the origin (a Mid-360 on a WidowX on a 1 m stand).
CLOSE_HOVER_CENTER_M = (2.1, 0.8, 2.2)
CLOSE_HOVER_BOX_M = (0.3, 0.3, 0.2)


def close_hover(hold: float, duration: float, rng: np.random.Generator) -> Trajectory:
    """Hovers 2.4 m from the sensor, wandering ≤ 0.3 m/s (≤ 0.3 m/s²) within ±0.3 × 0.3 ×
    0.2 m and slowly changing course, from the start (``hold`` included)."""
    return random_manoeuvres(
        rng,
        max(duration, 1.0) + 10.0,
        v_max=0.3,
        a_max=0.3,
        center=CLOSE_HOVER_CENTER_M,
        half_extent=CLOSE_HOVER_BOX_M,
        mean_hold=3.0,
        t0=hold,
    )
