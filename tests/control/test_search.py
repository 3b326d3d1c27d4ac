"""The search pattern: lanes, expanding sweeps, the raster and its revisit period."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.control.search import revisit_period, search_path, tilt_lanes

DEG = math.radians


def test_lanes_tile_the_tilt_range() -> None:
    np.testing.assert_allclose(
        tilt_lanes((DEG(-40), DEG(5)), DEG(20)), np.radians([-32.5, -17.5, -2.5])
    )
    assert tilt_lanes((0.0, DEG(10)), DEG(20)) == pytest.approx([DEG(5)])


def test_revisit_period_known_answer() -> None:
    # 3 lanes of 180° at 40°/s: 13.5 s.
    assert revisit_period(
        (DEG(-90), DEG(90)), (DEG(-40), DEG(5)), DEG(20), DEG(40)
    ) == pytest.approx(13.5)


def test_sweeps_grow_around_the_start_then_raster_repeats() -> None:
    path = search_path(
        (DEG(10), DEG(-5)), (DEG(-90), DEG(90)), (DEG(-40), DEG(5)), DEG(20), DEG(30), DEG(40)
    )
    pans = np.degrees(path.waypoints[: path.cycle_start, 0])
    # c ± (30 + 20k), on alternate sides, clipped to the range.
    np.testing.assert_allclose(pans, [10, 40, -40, 80, -80, 90, -90])
    # The first sweep is on the lane nearest the start's tilt.
    assert math.degrees(path.waypoints[1, 1]) == pytest.approx(-2.5)
    # The raster: 2·3 traversals end to end, then it repeats.
    cycle = np.degrees(path.waypoints[path.cycle_start :, 0])
    np.testing.assert_allclose(np.abs(cycle), 90.0)
    assert path.cycle_s == pytest.approx(2 * 13.5)
    s = path.times[path.cycle_start] + 3.0
    assert path.at(s) == pytest.approx(path.at(s + path.cycle_s))


@settings(max_examples=100)
@given(
    start=st.tuples(st.floats(-3.0, 3.0), st.floats(-1.0, 0.5)),
    lo=st.floats(-3.1, 0.0),
    span=st.floats(0.2, 6.2),
    lane=st.floats(0.1, 0.8),
    rate=st.floats(0.2, 3.0),
)
def test_the_path_stays_in_the_field_and_covers_it(
    start: tuple[float, float], lo: float, span: float, lane: float, rate: float
) -> None:
    pan, tilt = (lo, lo + span), (-0.7, 0.1)
    path = search_path(start, pan, tilt, lane, 0.5, rate)
    wp = path.waypoints[1:]
    assert np.all((wp[:, 0] >= pan[0] - 1e-12) & (wp[:, 0] <= pan[1] + 1e-12))
    assert np.all((wp[:, 1] >= tilt[0]) & (wp[:, 1] <= tilt[1]))
    # Every lane is swept end to end within one cycle.
    lanes = tilt_lanes(tilt, lane)
    cyc = path.waypoints[path.cycle_start :]
    for c in lanes:
        on = cyc[np.isclose(cyc[:, 1], c)]
        assert len(on) >= 1
    # Consecutive samples move at most rate·dt on either axis.
    s = np.linspace(0.0, path.times[-1] + path.cycle_s, 500)
    angles = np.array([path.at(x) for x in s])
    steps = np.abs(np.diff(angles, axis=0)).max(axis=1)
    assert np.all(steps <= rate * (s[1] - s[0]) * (1 + 1e-6) + 1e-9)
