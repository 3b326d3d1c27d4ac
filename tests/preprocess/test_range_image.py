"""The scan's range image: direction bins, the 3 × 3 minimum, and "clearly in front"."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.errors import InputError
from dronetrack.preprocess.range_image import (
    RangeImage,
    direction_bins,
    grid_shape,
    neighbourhood_min,
)

STEP = np.radians(1.0)
ORIGIN = np.array([0.0, 0.0, 1.0])


def test_bins_of_known_directions() -> None:
    # +x level with the origin: α = 0, ε = 0, so i = π/step, j = (π/2)/step.
    # Straight up: ε = π/2, the top bin (α = atan2(0, 0) = 0).  −x: α = −π, bin 0.
    pts = np.array([[10.0, 0.0, 1.0], [0.0, 0.0, 6.0], [-3.0, -1e-9, 1.0]])
    i, j, r = direction_bins(pts, ORIGIN, STEP)
    n_az, n_el = grid_shape(STEP)
    assert (n_az, n_el) == (360, 181)
    np.testing.assert_array_equal(i, [180, 180, 0])
    np.testing.assert_array_equal(j, [90, 180, 90])
    np.testing.assert_allclose(r, [10.0, 5.0, 3.0])


@given(st.floats(-179.0, 179.0), st.floats(-89.0, 89.0), st.floats(1.0, 300.0))
def test_a_point_is_in_its_own_bin(az_deg: float, el_deg: float, r: float) -> None:
    az, el = np.radians(az_deg), np.radians(el_deg)
    p = ORIGIN + r * np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
    i, j, rr = direction_bins(p[None, :], ORIGIN, STEP)
    assert abs(-np.pi + (i[0] + 0.5) * STEP - az) <= 0.5 * STEP + 1e-9
    assert abs(-0.5 * np.pi + (j[0] + 0.5) * STEP - el) <= 0.5 * STEP + 1e-9
    assert rr[0] == pytest.approx(r)


def test_the_neighbourhood_minimum_wraps_in_azimuth_only() -> None:
    g = np.full((6, 5), np.inf, dtype=np.float32)
    g[0, 0] = 7.0  # azimuth bin 0 at the bottom pole
    out = neighbourhood_min(g)
    near = {(0, 0), (0, 1), (1, 0), (1, 1), (5, 0), (5, 1)}  # bin 5 is next to bin 0
    for a in range(6):
        for e in range(5):
            assert out[a, e] == (7.0 if (a, e) in near else np.inf)


def test_in_front_of_a_wall_behind_it_and_in_the_open_sky() -> None:
    """A wall 20 m out across ±10° of azimuth, scanned; the margin is 1 m."""
    image = RangeImage(ORIGIN, STEP)
    az = np.radians(np.linspace(-10.0, 10.0, 200))
    wall = np.column_stack([np.full_like(az, 20.0), 20.0 * np.tan(az), np.full_like(az, 3.0)])
    image.insert(wall)
    with pytest.raises(InputError, match="not been built"):
        image.in_front(wall, 1.0)
    image.build()
    with pytest.raises(InputError, match="already built"):
        image.insert(wall)
    probe = np.array(
        [
            [18.0, 1.0, 3.0],  # 2 m in front of the wall: kept
            [19.5, 1.0, 3.0],  # within the margin: the wall's
            [25.0, 1.0, 3.0],  # behind it
            [20.0, 2.0, 30.0],  # above it, where the scan saw nothing
            [np.nan, 0.0, 0.0],
        ]
    )
    np.testing.assert_array_equal(image.in_front(probe, 1.0), [True, False, False, True, False])
    assert image.ready
