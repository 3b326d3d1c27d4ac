"""The field of regard: membership and bounding box."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.geometry.field import FieldOfRegard, in_field_of_view
from dronetrack.geometry.transforms import make_pose, rot_z

DEG = math.radians


def test_membership_known_answers() -> None:
    f = FieldOfRegard((DEG(-90), DEG(90)), (DEG(-40), DEG(5)), 200.0, (0.0, 0.0, 1.0))
    pts = np.array(
        [
            [100.0, 0.0, 20.0],  # ahead, 11° up
            [-10.0, 0.0, 1.0],  # behind
            [100.0, 0.0, 150.0],  # 56° up
            [250.0, 0.0, 20.0],  # too far
            [0.0, 150.0, 1.0],  # at the pan end
            [np.nan, 0.0, 0.0],
        ]
    )
    assert f.contains(pts).tolist() == [True, False, False, False, True, False]
    # A range across ±180°: from 150° round to −150°.
    back = FieldOfRegard((DEG(150), DEG(210)), (DEG(-40), DEG(5)), 200.0)
    assert back.contains(np.array([[-50.0, 1.0, 5.0], [50.0, 0.0, 5.0]])).tolist() == [True, False]
    with pytest.raises(ValueError, match="pan range"):
        FieldOfRegard((1.0, 0.0), (0.0, 0.1), 1.0)


@settings(max_examples=100)
@given(
    lo=st.floats(-3.1, 3.0),
    span=st.floats(0.1, 2 * math.pi),
    tilt=st.tuples(st.floats(-1.5, 0.0), st.floats(0.01, 1.5)),
    seed=st.integers(0, 2**32 - 1),
)
def test_the_bounding_box_holds_every_point_of_the_field(
    lo: float, span: float, tilt: tuple[float, float], seed: int
) -> None:
    f = FieldOfRegard((lo, lo + span), (tilt[0], tilt[0] + tilt[1]), 100.0, (5.0, -3.0, 1.0))
    pts = np.random.default_rng(seed).uniform(-110.0, 110.0, (4000, 3)) + np.array(f.base)
    inside = pts[f.contains(pts)]
    low, high = f.bounding_box(-1e9)
    assert np.all(inside >= low - 1e-9)
    assert np.all(inside <= high + 1e-9)
    # and is tight: every face is within a few metres of a point of the field
    if len(inside) > 500:
        assert np.all(inside.min(axis=0) - low < 25.0)


def test_the_field_of_view_is_the_ellipse_of_its_half_widths_about_the_sensor_axis() -> None:
    """An Avia (70.4° × 77.2°) at (1, 2, 3), panned 90° left: its axis is +y."""
    fov = (math.radians(70.4), math.radians(77.2))
    pose = make_pose(rot_z(math.pi / 2), [1.0, 2.0, 3.0])
    o = np.array([1.0, 2.0, 3.0])

    def at(az_deg: float, el_deg: float) -> np.ndarray:
        a, e = math.radians(az_deg + 90.0), math.radians(el_deg)
        return o + 50.0 * np.array(
            [math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)]
        )

    points = np.array(
        [at(0, 0), at(35, 0), at(36, 0), at(0, 38), at(0, 39), at(25, 27), at(-30, -25)]
    )
    # (25/35.2)² + (27/38.6)² = 0.99; (30/35.2)² + (25/38.6)² = 1.15
    expect = [True, True, False, True, False, True, False]
    assert in_field_of_view(points, pose, fov).tolist() == expect
    behind = o - np.array([[0.0, 50.0, 0.0]])  # straight behind it
    assert not in_field_of_view(behind, pose, fov)[0]
