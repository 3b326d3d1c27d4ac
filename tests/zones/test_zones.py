"""Protected zones: containment, margins, the time to enter at the present velocity, and
the alerts a drone-class track raises and clears (birds and static objects none)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from shapely import Polygon

from dronetrack.types import TRACK_CLASSES, Tracks
from dronetrack.zones import AlertMonitor, Zone, circle, entry_time, zone_level

SQUARE = Polygon([(100.0, -10.0), (120.0, -10.0), (120.0, 10.0), (100.0, 10.0)])


def _tracks(positions: list[list[float]], velocities: list[list[float]], cls: str) -> Tracks:
    k = len(positions)
    return Tracks(
        ids=np.arange(1, k + 1),
        positions=np.array(positions, dtype=np.float64).reshape(-1, 3),
        velocities=np.array(velocities, dtype=np.float64).reshape(-1, 3),
        covariances=np.tile(np.eye(6), (k, 1, 1)),
        born=np.zeros(k),
        updated=np.ones(k, dtype=bool),
        hovered=np.zeros(k, dtype=bool),
        locked=np.zeros(k, dtype=bool),
        classes=np.full(k, TRACK_CLASSES.index(cls)),
        p_drone=np.full(k, 0.9 if cls == "drone" else 0.1),
    )


def test_a_path_along_x_enters_the_square_when_it_reaches_its_edge() -> None:
    zone = Zone("square", SQUARE, floor=0.0, ceiling=50.0)
    # 80 m short of the edge at 10 m/s: 8 s
    assert entry_time(zone, [20.0, 0.0, 10.0], [10.0, 0.0, 0.0], 30.0) == pytest.approx(8.0)
    assert entry_time(zone, [20.0, 0.0, 10.0], [10.0, 0.0, 0.0], 5.0) == math.inf  # too far
    assert entry_time(zone, [20.0, 0.0, 10.0], [-10.0, 0.0, 0.0], 30.0) == math.inf  # away
    assert entry_time(zone, [110.0, 0.0, 10.0], [0.0, 0.0, 0.0], 30.0) == 0.0  # inside
    # Above the ceiling and climbing: over the zone, never in it.
    assert entry_time(zone, [20.0, 0.0, 60.0], [10.0, 0.0, 1.0], 30.0) == math.inf
    # Above the ceiling and descending at 2 m/s: in the plane at 8 s, under 50 m at 5 s,
    # so it enters at 8 s; descending at 1 m/s it is under the ceiling only at 10 s.
    assert entry_time(zone, [20.0, 0.0, 60.0], [10.0, 0.0, -2.0], 30.0) == pytest.approx(8.0)
    assert entry_time(zone, [20.0, 0.0, 60.0], [10.0, 0.0, -1.0], 30.0) == pytest.approx(10.0)


@given(st.floats(-300, 300), st.floats(-300, 300), st.floats(0.5, 40), st.floats(0, 2 * math.pi))
def test_entry_time_agrees_with_stepping_the_path(
    x: float, y: float, speed: float, a: float
) -> None:
    zone = circle("round", (50.0, 20.0), 30.0, floor=-math.inf, ceiling=math.inf)
    p = np.array([x, y, 5.0])
    v = speed * np.array([math.cos(a), math.sin(a), 0.0])
    t_in = entry_time(zone, p, v, 20.0)
    ts = np.linspace(0.0, 20.0, 4001)
    inside = [zone.contains(p + v * t) for t in ts]
    if not any(inside):
        # a chord shorter than the grid's step may be missed by stepping, never the reverse
        assert t_in == math.inf or speed * 0.005 > 1e-3
    else:
        first = ts[int(np.argmax(inside))]
        assert first - 0.005 - 1e-9 <= t_in <= first + 1e-9


def test_zone_level_orders_inside_margin_and_prediction() -> None:
    zone = Zone("square", SQUARE, floor=0.0, ceiling=50.0, margin_m=15.0, margin_s=10.0)
    assert zone_level(zone, np.array([110.0, 0.0, 10.0]), np.zeros(3))[0] == 3
    assert zone_level(zone, np.array([90.0, 0.0, 10.0]), np.zeros(3))[0] == 2
    # 40 m out at 5 m/s toward it: 8 s to the zone
    level, t_in = zone_level(zone, np.array([60.0, 0.0, 10.0]), np.array([5.0, 0.0, 0.0]))
    assert (level, t_in) == (1, pytest.approx(8.0))
    assert zone_level(zone, np.array([60.0, 0.0, 10.0]), np.array([-5.0, 0.0, 0.0]))[0] == 0
    # the margin grows the band in height too: 10 m over the ceiling is within 15 m
    assert zone_level(zone, np.array([110.0, 0.0, 60.0]), np.zeros(3))[0] == 2
    assert zone.distance(np.array([110.0, 0.0, 60.0])) == pytest.approx(10.0)


def test_a_drone_flying_through_raises_each_alert_once_then_clears_after_the_hold() -> None:
    zone = Zone("square", SQUARE, floor=0.0, ceiling=50.0, margin_m=15.0, margin_s=10.0)
    monitor = AlertMonitor([zone], hold_s=1.0)
    kinds: list[tuple[float, str]] = []
    # 10 m/s along x from x = 0 to 200 m, 10 frames a second
    for i in range(201):
        t = 0.1 * i
        x = 10.0 * t
        for e in monitor.update(t, _tracks([[x, 0.0, 10.0]], [[10.0, 0.0, 0.0]], "drone")):
            kinds.append((round(e.t, 1), e.kind))
    # predicted 10 s before the edge at x = 100 (t = 0), margin at x = 85 (t = 8.5),
    # inside at t = 10, out at t = 12 into the margin (after the 1 s hold: t = 13),
    # out of the margin at x = 135 (t = 13.5, reported at 14.5): clear.
    assert kinds == [
        (0.0, "predicted"),
        (8.5, "margin"),
        (10.0, "inside"),
        (13.1, "margin"),
        (14.6, "clear"),
    ]
    assert monitor.active == 0


def test_birds_and_static_objects_raise_nothing_and_an_ended_track_clears() -> None:
    zone = Zone("square", SQUARE, floor=0.0, ceiling=50.0, margin_m=15.0)
    monitor = AlertMonitor([zone], hold_s=1.0)
    for cls in ("bird", "static", "unknown"):
        assert monitor.update(0.0, _tracks([[110.0, 0.0, 10.0]], [[0.0, 0.0, 0.0]], cls)) == []
    raised = monitor.update(1.0, _tracks([[110.0, 0.0, 10.0]], [[0.0, 0.0, 0.0]], "drone"))
    assert [e.kind for e in raised] == ["inside"]
    gone = monitor.update(1.1, _tracks([], [], "drone"))
    assert [(e.kind, e.detail) for e in gone] == [("clear", "track ended")]
    # a drone reclassed bird clears after the hold, saying why
    monitor.update(2.0, _tracks([[110.0, 0.0, 10.0]], [[0.0, 0.0, 0.0]], "drone"))
    assert monitor.update(2.1, _tracks([[110.0, 0.0, 10.0]], [[0.0, 0.0, 0.0]], "bird")) == []
    late = monitor.update(3.1, _tracks([[110.0, 0.0, 10.0]], [[0.0, 0.0, 0.0]], "bird"))
    assert [(e.kind, e.detail) for e in late] == [("clear", "no longer a drone")]


def test_a_track_on_the_margin_edge_does_not_chatter() -> None:
    zone = Zone("square", SQUARE, margin_m=15.0)
    monitor = AlertMonitor([zone], hold_s=1.0)
    events = []
    for i in range(100):  # in and out of the band every other frame
        x = 84.5 if i % 2 else 85.5
        events += monitor.update(0.1 * i, _tracks([[x, 0.0, 10.0]], [[0.0, 0.0, 0.0]], "drone"))
    assert [e.kind for e in events] == ["margin"]
