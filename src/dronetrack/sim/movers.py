"""Walkers and vehicles: people and cars moving on the ground, labelled in the truth.

A walker is a person 1.75 m tall and 0.5 m across the shoulders (legs, torso and
head), walking between waypoints drawn uniformly in an area on the ground at a
speed drawn per leg from [v_lo, v_hi], pausing a time drawn from [p_lo, p_hi] at
each waypoint (and once before the first).  A vehicle is a car, L × W × H (body,
cabin and four wheels), that drives a path of waypoints and parks at its last
one, where it stays: it enters the world at the path's first point, so that it
parks at ``arrive_s``.  Each leg is rest to rest with a trapezoidal speed profile
(``trajectories.fly_waypoints``: accelerating at 1 m/s² for a walker, 2 m/s² for a
car), so a path's position, velocity and acceleration are exact at any time.
Each body faces the way it moves; at rest it keeps the heading of its last move
(before its first, the heading of that move).

The ground is the plane z = 0 of every scene; a body's position is its centre
(0.875 m up for a walker, H / 2 for a car), the point its truth reports.

Both are cast like birds (``sim/echoes.py``: sub-rays over each pulse's footprint,
each body where it is when the pulse fires, the nearest one's echo on a pulse).
Their diffuse reflectivities at 905 nm are assumptions [A] in the middle of what
is reported: fabrics and skin reflect 30-60 % in the near infrared (the
recommended infrared reflectance of a surrogate pedestrian for automatic braking
tests spans about that range), a car's paint from a few per cent (black) to about
70 % (white), glass little back along the beam, and tyres a few per cent.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray, rot_x, rot_z
from dronetrack.sim.primitives import Primitives
from dronetrack.sim.shapes import box, cylinder, ellipsoid
from dronetrack.sim.trajectories import PiecewiseAcceleration, Waypoint, fly_waypoints

__all__ = [
    "RHO_VEHICLE",
    "VEHICLE_ACCEL_M_S2",
    "VEHICLE_SIZE_M",
    "WALKER_ACCEL_M_S2",
    "WALKER_HEIGHT_M",
    "Mover",
    "Movers",
    "Route",
    "vehicle",
    "vehicle_body",
    "walker",
    "walker_body",
]

WALKER_HEIGHT_M = 1.75
WALKER_ACCEL_M_S2 = 1.0  # to walking speed in about 1.5 s
VEHICLE_ACCEL_M_S2 = 2.0  # a car pulling away and braking gently
VEHICLE_SIZE_M = (4.5, 1.8, 1.5)  # length, width, height
WALK_LEGS = 4  # a walk is drawn on this many legs at a time

# Diffuse reflectivity at 905 nm [A] (see the module's docstring).
RHO_TROUSERS = 0.3
RHO_SHIRT = 0.5
RHO_HEAD = 0.45
RHO_VEHICLE = 0.4  # mid-toned paint
RHO_CABIN = 0.15  # windows, pillars and roof together
RHO_TYRE = 0.05
MOVING_M_S = 1e-6  # slower than this a segment is at rest


def walker_body() -> Primitives:
    """A person in their own frame (x forward, y left, z up, origin at the centre of
    the body, 0.875 m above the feet): two legs 0.85 m long, a torso 0.5 m across and
    0.3 m deep, and a head; 1.75 m tall in all."""
    z0 = -0.5 * WALKER_HEIGHT_M  # the feet
    legs = [cylinder((0.0, y, z0 + 0.425), 0.08, 0.85, RHO_TROUSERS) for y in (-0.1, 0.1)]
    torso = ellipsoid((0.0, 0.0, z0 + 0.85 + 0.32), (0.15, 0.25, 0.32), RHO_SHIRT)
    head = ellipsoid((0.0, 0.0, z0 + WALKER_HEIGHT_M - 0.12), (0.1, 0.09, 0.12), RHO_HEAD)
    return Primitives.concat([*legs, torso, head])


def vehicle_body(
    size: tuple[float, float, float] = VEHICLE_SIZE_M, reflectivity: float = RHO_VEHICLE
) -> Primitives:
    """A car of length L, width W and height H in its own frame (x forward, origin at the
    centre of its L × W × H box): four wheels of radius 0.2 H, the body from 0.2 H to
    0.65 H above the ground and a cabin 0.55 L long on top, up to H."""
    length, width, height = size
    z0 = -0.5 * height  # the ground
    r = 0.2 * height
    axle = rot_x(0.5 * np.pi)  # a cylinder's axis along y
    wheels = [
        cylinder((x, y, z0 + r), r, 0.12 * width, RHO_TYRE, rotation=axle)
        for x in (-0.3 * length, 0.3 * length)
        for y in (-0.4 * width, 0.4 * width)
    ]
    body = box((0.0, 0.0, z0 + 0.425 * height), (length, width, 0.45 * height), reflectivity)
    cabin = box(
        (-0.05 * length, 0.0, z0 + 0.825 * height),
        (0.55 * length, 0.9 * width, 0.35 * height),
        RHO_CABIN,
    )
    return Primitives.concat([*wheels, body, cabin])


def _joined(a: PiecewiseAcceleration, b: PiecewiseAcceleration) -> PiecewiseAcceleration:
    """Path ``a`` followed by ``b``, which starts where and when ``a`` ends."""
    return PiecewiseAcceleration(
        knots=np.concatenate([a.knots, b.knots[1:]]),
        p=np.concatenate([a.p, b.p]),
        v=np.concatenate([a.v, b.v]),
        a=np.concatenate([a.a, b.a]),
    )


def _headings(path: PiecewiseAcceleration) -> FloatArray:
    """The yaw of each segment's motion [rad]: the direction of its mean velocity, or
    for a segment at rest that of the last move before it (of the first move after it
    at the start; 0 if nothing moves)."""
    dt = np.diff(path.knots)
    mean_v = path.v + 0.5 * path.a * dt[:, None]  # v + a τ/2 over a segment of length τ
    moving = np.hypot(mean_v[:, 0], mean_v[:, 1]) > MOVING_M_S
    if not moving.any():
        return np.zeros(len(dt))
    yaw = np.arctan2(mean_v[:, 1], mean_v[:, 0])
    last = np.maximum.accumulate(np.where(moving, np.arange(len(dt)), -1))
    last = np.where(last >= 0, last, int(np.argmax(moving)))
    out: FloatArray = yaw[last]
    return out


class Route:
    """A rest-to-rest path of a body's centre through waypoints on the ground, and its
    heading.  ``more``, if given, gives further waypoints whenever a time past the end
    is asked for (a walker walks on for as long as the run lasts); without it the body
    stays at the last waypoint."""

    def __init__(
        self,
        path: PiecewiseAcceleration,
        more: Callable[[], list[Waypoint]] | None = None,
    ) -> None:
        self._path = path
        self._yaw = _headings(path)
        self._more = more

    @property
    def drawn(self) -> PiecewiseAcceleration:
        """The path drawn so far: its segments, each at constant acceleration."""
        return self._path

    def _reach(self, t: ArrayLike) -> None:
        """Draw the path on past the latest of times ``t``."""
        if self._more is None:
            return
        latest = float(np.max(t))
        while self._path.end <= latest:
            end = self._path.end
            drawn = fly_waypoints(self._path.position(end)[0], self._more(), t0=end)
            if drawn.end <= end:
                raise InputError("a walk's waypoints must take time to walk")
            self._path = _joined(self._path, drawn)
            self._yaw = _headings(self._path)

    def position(self, t: ArrayLike) -> FloatArray:
        """(N, 3) at times t."""
        self._reach(t)
        return self._path.position(t)

    def velocity(self, t: ArrayLike) -> FloatArray:
        """(N, 3) at times t."""
        self._reach(t)
        return self._path.velocity(t)

    def yaw(self, t: float) -> float:
        """The heading at time t [rad]."""
        self._reach(t)
        k = np.searchsorted(self._path.knots, t, side="right") - 1
        return float(self._yaw[int(np.clip(k, 0, len(self._yaw) - 1))])


@dataclass(frozen=True, slots=True)
class Mover:
    """A walker or a vehicle: its kind (``types.OBJECT_KINDS``), its body (in its own
    frame, origin at its centre), its route, and when it enters the world."""

    kind: str
    body: Primitives
    route: Route
    enter_s: float = -math.inf

    @property
    def radius(self) -> float:
        """The radius of a sphere about the body's origin that holds it [m]."""
        reach = np.linalg.norm(self.body.center, axis=1) + self.body.bound_radius
        return float(reach.max())


def walker(
    area: tuple[float, float, float, float],
    speed: tuple[float, float],
    pause: tuple[float, float],
    rng: np.random.Generator,
    t0: float = 0.0,
) -> Mover:
    """A walker in ``area`` (x0, y0, x1, y1) [m] from time t0, on waypoints, speeds
    (uniform in ``speed`` [m/s], per leg) and pauses (uniform in ``pause`` [s]) drawn from
    ``rng``: it starts at a random point, pauses up to ``pause[1]``, then walks on."""
    x0, y0, x1, y1 = area
    z = 0.5 * WALKER_HEIGHT_M

    def point() -> tuple[float, float, float]:
        return (float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)), z)

    def more() -> list[Waypoint]:
        # Each leg drawn in turn: its end point, its speed, the pause there.
        out: list[Waypoint] = []
        for _ in range(WALK_LEGS):
            p = point()
            s = float(rng.uniform(*speed))
            out.append(Waypoint(p, s, WALKER_ACCEL_M_S2, float(rng.uniform(*pause))))
        return out

    start = point()
    first = fly_waypoints(start, [], t0=t0, hold=float(rng.uniform(0.0, pause[1])) + 1e-3)
    return Mover("walker", walker_body(), Route(first, more))


def vehicle(
    path: Sequence[tuple[float, float]],
    speed: float,
    arrive_s: float,
    size: tuple[float, float, float] = VEHICLE_SIZE_M,
    reflectivity: float = RHO_VEHICLE,
) -> Mover:
    """A car that drives ``path`` (x, y) [m] at up to ``speed`` [m/s], stopping at each
    point, and parks at the last one at ``arrive_s`` [s]; it enters the world at the
    first point, as late as that allows."""
    if len(path) < 2:
        raise InputError("a vehicle's path needs at least two points")
    z = 0.5 * size[2]
    points = [(float(x), float(y), z) for x, y in path]
    legs = [Waypoint(p, speed, VEHICLE_ACCEL_M_S2) for p in points[1:]]
    drive = fly_waypoints(points[0], legs)
    shift = arrive_s - drive.end
    route = PiecewiseAcceleration(drive.knots + shift, drive.p, drive.v, drive.a)
    return Mover("vehicle", vehicle_body(size, reflectivity), Route(route), route.start)


class Movers:
    """A group of walkers and vehicles, as ``sim/echoes.py`` casts a group of bodies."""

    def __init__(self, movers: Sequence[Mover]) -> None:
        self.movers = tuple(movers)
        self.kinds = [m.kind for m in self.movers]
        self.bodies = [m.body for m in self.movers]
        self.radius = np.array([m.radius for m in self.movers])
        self.enter_s = np.array([m.enter_s for m in self.movers], dtype=np.float64)

    def __len__(self) -> int:
        return len(self.movers)

    def present(self, t: float) -> NDArray[np.bool_]:
        """(M,) which are in the world at time t."""
        out: NDArray[np.bool_] = t >= self.enter_s
        return out

    def positions(self, t: float) -> FloatArray:
        """Every body's centre at time t, (M, 3) (where it will enter, before it does)."""
        return np.array([m.route.position(t)[0] for m in self.movers]).reshape(-1, 3)

    def velocities(self, t: float) -> FloatArray:
        """Every body's velocity at time t, (M, 3)."""
        return np.array([m.route.velocity(t)[0] for m in self.movers]).reshape(-1, 3)

    def path(self, k: int, times: FloatArray) -> FloatArray:
        """Body k's centre at ``times`` (N,), (N, 3)."""
        return self.movers[k].route.position(times)

    def attitude(self, k: int, t: float) -> FloatArray:
        """world_R_body of body k at time t: turned to its heading about z."""
        R: FloatArray = rot_z(self.movers[k].route.yaw(t))
        return R
