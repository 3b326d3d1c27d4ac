"""The convex-hull crop (seed 003's filter node) against known answers, and the ball."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from dronetrack.errors import ConfigError
from dronetrack.preprocess.crop import HullCrop, ball_mask


@settings(max_examples=50, deadline=None)
@given(seed=st.integers(0, 2**32 - 1))
def test_hull_crop_of_a_box_is_the_box(seed: int) -> None:
    """The hull of a box's 8 corners keeps exactly the points the box keeps."""
    rng = np.random.default_rng(seed)
    lo = rng.uniform(-10, 0, 3)
    hi = lo + rng.uniform(0.5, 10, 3)
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    pts = rng.uniform(lo - 2, hi + 2, size=(500, 3))
    inside = np.all((pts > lo) & (pts < hi), axis=1)
    np.testing.assert_array_equal(HullCrop(corners).mask(pts), inside)


def test_hull_crop_of_a_tetrahedron_and_its_interior_points() -> None:
    # Extra points inside the hull do not change it.
    tet = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.1, 0.1, 0.1]], float)
    crop = HullCrop(tet)
    assert len(crop.vertices) == 4
    pts = np.array([[0.2, 0.2, 0.2], [0.4, 0.4, 0.4], [0.5, 0.5, 0.0], [-0.01, 0.1, 0.1]])
    # x + y + z ≤ 1 and all coordinates ≥ 0
    np.testing.assert_array_equal(crop.mask(pts), [True, False, True, False])


@pytest.mark.parametrize(
    "vertices",
    [np.zeros((3, 3)), [[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], [[0, 0, np.nan]] * 4],
)
def test_hull_crop_rejects_too_few_flat_or_bad_vertices(vertices: object) -> None:
    with pytest.raises(ConfigError, match="hull"):
        HullCrop(vertices)  # type: ignore[arg-type]


@given(
    arrays(np.float64, (30, 3), elements=st.floats(-50, 50)),
    arrays(np.float64, 3, elements=st.floats(-50, 50)),
    st.floats(0.0, 40.0),
)
def test_ball_mask_is_the_distance_test(points: np.ndarray, centre: np.ndarray, r: float) -> None:
    d = np.linalg.norm(points - centre, axis=1)
    inside = ball_mask(points, centre, r)
    assert np.all(inside[d < r * (1 - 1e-9)])
    assert not np.any(inside[d > r * (1 + 1e-9) + 1e-12])


def test_ball_mask_leaves_non_finite_rows_out() -> None:
    pts = np.array([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0], [np.inf, 0.0, 0.0]])
    np.testing.assert_array_equal(ball_mask(pts, np.zeros(3), 1.0), [True, False, False])
