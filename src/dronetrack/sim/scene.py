"""Static scenes: the ground, buildings, trees, hedges and walls.

World frame: origin at the turret base on the ground, x forward, y left, z up.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError
from dronetrack.sim.primitives import Primitives
from dronetrack.sim.shapes import box, cylinder, ellipsoid, ground
from dronetrack.sim.trajectories import polar

__all__ = ["SCENE_NAMES", "Scene", "make_scene"]

# Diffuse reflectivity at 905 nm [A]: vegetation is bright in the near infrared.
RHO_GRASS = 0.35
RHO_BUILDING = 0.30
RHO_CROWN = 0.50
RHO_TRUNK = 0.20
RHO_HEDGE = 0.45
RHO_WALL = 0.30
RHO_INDOOR_WALL = 0.60
RHO_FLOOR = 0.25
RHO_METAL = 0.35  # weathered galvanised steel and painted poles [A]


@dataclass(frozen=True, slots=True)
class Scene:
    """A named set of static primitives and the area it covers (x0, y0, x1, y1) [m].

    ``swaying`` lists the primitives the wind can move (tree crowns and hedges), for
    the clutter of ``sim/clutter.py``; without clutter every primitive stands still.
    """

    name: str
    prims: Primitives
    extent: tuple[float, float, float, float]
    swaying: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, dtype=np.int64))


def _tree(x: float, y: float, height: float, crown_radius: float) -> list[Primitives]:
    """A trunk and its crown, in that order (one primitive each)."""
    trunk_h = 0.45 * height
    return [
        cylinder((x, y, 0.5 * trunk_h), 0.15 + 0.02 * height, trunk_h, RHO_TRUNK),
        ellipsoid(
            (x, y, height - crown_radius),
            (crown_radius, crown_radius, 1.15 * crown_radius),
            RHO_CROWN,
        ),
    ]


def outdoor_field(layout_seed: int = 0) -> Scene:
    """An open field about 300 m across, with the flight corridor along +x kept clear.

    Buildings stand behind and beside the turret, tree lines mark the field's
    edges, a hedge and a wall give low occluders, and a few single trees stand
    inside the field.  ``layout_seed`` jitters the trees reproducibly.
    """
    rng = np.random.default_rng(layout_seed)
    parts = [ground(RHO_GRASS)]
    swaying: list[int] = []  # every part is one primitive: its index is its place in parts
    for center, size, yaw in (
        ((-45.0, 55.0, 5.0), (24.0, 16.0, 10.0), 0.1),
        ((-60.0, -40.0, 6.0), (30.0, 14.0, 12.0), -0.05),
        ((-30.0, -95.0, 4.0), (18.0, 18.0, 8.0), 0.3),
        ((175.0, 110.0, 7.0), (26.0, 20.0, 14.0), 0.2),
        ((190.0, -115.0, 5.0), (34.0, 16.0, 10.0), -0.15),
        ((240.0, 5.0, 9.0), (20.0, 40.0, 18.0), 0.0),
    ):
        parts.append(box(center, size, RHO_BUILDING, yaw=yaw))
    # Tree lines along the side edges and the far end.
    for y_edge in (-145.0, 145.0):
        for x in np.arange(-20.0, 221.0, 16.0):
            jitter = rng.uniform(-3.0, 3.0, size=2)
            parts += _tree(
                x + jitter[0], y_edge + jitter[1], rng.uniform(9.0, 16.0), rng.uniform(2.5, 4.5)
            )
            swaying.append(len(parts) - 1)
    for y in np.arange(-120.0, 121.0, 20.0):
        parts += _tree(
            215.0 + rng.uniform(-3, 3),
            y + rng.uniform(-3, 3),
            rng.uniform(10.0, 18.0),
            rng.uniform(3.0, 5.0),
        )
        swaying.append(len(parts) - 1)
    # Single trees inside the field, away from the corridor |y| < 50 m.
    for x, y in ((45.0, 75.0), (80.0, -70.0), (120.0, 85.0), (150.0, -65.0), (25.0, -60.0)):
        parts += _tree(x, y, rng.uniform(8.0, 14.0), rng.uniform(2.5, 4.0))
        swaying.append(len(parts) - 1)
    # A hedge and a wall.
    parts.append(box((70.0, -55.0, 0.8), (60.0, 1.5, 1.6), RHO_HEDGE))
    swaying.append(len(parts) - 1)
    parts.append(box((205.0, 60.0, 1.25), (0.4, 40.0, 2.5), RHO_WALL))
    return Scene(
        "outdoor",
        Primitives.concat(parts),
        (-50.0, -150.0, 250.0, 150.0),
        np.array(swaying, dtype=np.int64),
    )


def indoor_room(partition: bool = False) -> Scene:
    """Seed 000's motion-capture arena: 7 × 8 m, 3.5 m high.

    The turret stands 1 m in from the short wall behind it, looking down the
    8 m length (x from -1 to 7 m, y from -3.5 to 3.5 m).  With ``partition``, a
    0.35 m wide, 2.2 m tall pillar at x = 2 m hides what is straight ahead 3-4 m
    away: the lost-and-found pattern's middle waypoint.
    """
    t = 0.2  # wall thickness
    x0, x1, y0, y1, h = -1.0, 7.0, -3.5, 3.5, 3.5
    parts = [
        ground(RHO_FLOOR),
        box((x0 - t / 2, 0.0, h / 2), (t, y1 - y0 + 2 * t, h), RHO_INDOOR_WALL),
        box((x1 + t / 2, 0.0, h / 2), (t, y1 - y0 + 2 * t, h), RHO_INDOOR_WALL),
        box((0.5 * (x0 + x1), y0 - t / 2, h / 2), (x1 - x0, t, h), RHO_INDOOR_WALL),
        box((0.5 * (x0 + x1), y1 + t / 2, h / 2), (x1 - x0, t, h), RHO_INDOOR_WALL),
        box(
            (0.5 * (x0 + x1), 0.0, h + t / 2),
            (x1 - x0 + 2 * t, y1 - y0 + 2 * t, t),
            RHO_INDOOR_WALL,
        ),
        # Furniture along the walls and the occluding partition.
        box((5.5, 3.0, 0.4), (2.0, 0.8, 0.8), 0.4),
        box((5.5, -3.0, 0.9), (1.2, 0.6, 1.8), 0.3),
    ]
    if partition:
        parts.append(box((2.0, 0.0, 1.1), (0.3, 0.35, 2.2), 0.5))
    name = "indoor-occluded" if partition else "indoor"
    return Scene(name, Primitives.concat(parts), (x0, y0, x1, y1))


# outdoor-barn's barn: 14 × 30 m, 12 m high, 53-67 m out and 15-45 m to the left.  From
# the turret it hides bearings of about 13° to 40° below 12 m at 53 m (the hide flight).
BARN_CENTER = (60.0, 30.0, 6.0)
BARN_SIZE = (14.0, 30.0, 12.0)


def outdoor_barn(layout_seed: int = 0) -> Scene:
    """``outdoor_field`` with a barn in the field to hide behind (``BARN_*``)."""
    base = outdoor_field(layout_seed)
    barn = box(BARN_CENTER, BARN_SIZE, RHO_BUILDING)  # appended: the swaying indices hold
    return Scene("outdoor-barn", Primitives.concat([base.prims, barn]), base.extent, base.swaying)


# outdoor-masts' structures, off the home bearing on both sides: (range [m], bearing
# [deg], height [m]) of each one's foot, nearer than the tree lines behind them.
MASTS = (
    (95.0, 66.0, 6.0),  # a lamp post
    (125.0, 70.0, 12.0),  # a lattice mast, as a 0.4 m pole
    (100.0, 78.0, 4.0),  # a pole with a sign board at its top
    (110.0, 50.0, 2.5),  # a cabinet
    (115.0, -62.0, 10.0),  # a mast
    (85.0, -72.0, 5.0),  # a pole
)
SHED = (150.0, 57.0, 5.0)  # a shed 10 × 8 m whose corner stands out: range, bearing, height
MASTS_MIN_BEARING_DEG = 50.0  # no structure stands nearer the home bearing


def outdoor_masts(layout_seed: int = 0) -> Scene:
    """``outdoor_field`` with a site's structures a few metres tall (``MASTS``, ``SHED``)
    beyond 50° either side of the home bearing: poles and masts, a cabinet and a shed."""
    base = outdoor_field(layout_seed)
    parts = [base.prims]
    lamp, mast, sign, cabinet, mast_2, pole = MASTS
    for (r, bearing, h), radius in ((lamp, 0.1), (mast, 0.2), (mast_2, 0.2), (pole, 0.1)):
        x, y, _ = polar(r, bearing, 0.0)
        parts.append(cylinder((x, y, 0.5 * h), radius, h, RHO_METAL))
    x, y, _ = polar(sign[0], sign[1], 0.0)
    parts.append(cylinder((x, y, 0.5 * sign[2]), 0.08, sign[2], RHO_METAL))
    parts.append(box((x, y, sign[2] - 0.6), (0.1, 1.2, 0.8), 0.6, yaw=np.radians(sign[1])))
    x, y, _ = polar(cabinet[0], cabinet[1], 0.0)
    parts.append(box((x, y, 0.5 * cabinet[2]), (0.6, 0.8, cabinet[2]), RHO_WALL))
    x, y, _ = polar(SHED[0], SHED[1], 0.0)
    parts.append(box((x, y, 0.5 * SHED[2]), (10.0, 8.0, SHED[2]), RHO_BUILDING))
    # appended after the field's parts: the swaying indices hold
    return Scene("outdoor-masts", Primitives.concat(parts), base.extent, base.swaying)


def empty_field() -> Scene:
    """Only the ground: for tests and range studies."""
    return Scene("empty", ground(RHO_GRASS), (-50.0, -150.0, 250.0, 150.0))


def sky() -> Scene:
    """Nothing at all: every pulse that misses the target is lost."""
    return Scene("sky", Primitives.empty(), (-50.0, -150.0, 250.0, 150.0))


SCENE_NAMES = (
    "outdoor",
    "outdoor-barn",
    "outdoor-masts",
    "indoor",
    "indoor-occluded",
    "empty",
    "sky",
)


def make_scene(name: str, layout_seed: int = 0) -> Scene:
    """Build a scene by name: ``outdoor``, ``outdoor-barn``, ``outdoor-masts``, ``indoor``,
    ``indoor-occluded``, ``empty`` or ``sky``."""
    key = name.strip().lower()
    if key == "outdoor":
        return outdoor_field(layout_seed)
    if key == "outdoor-barn":
        return outdoor_barn(layout_seed)
    if key == "outdoor-masts":
        return outdoor_masts(layout_seed)
    if key in ("indoor", "indoor-occluded"):
        return indoor_room(partition=key == "indoor-occluded")
    if key == "empty":
        return empty_field()
    if key == "sky":
        return sky()
    raise ConfigError(f"unknown scene {name!r}; choose one of {', '.join(SCENE_NAMES)}")
