"""The ground's height per horizontal cell (``preprocess.ground``)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import InputError
from dronetrack.preprocess.ground import GroundGrid


def test_the_ground_is_the_lowest_return_around_a_point() -> None:
    g = GroundGrid(cell_m=5.0, stride=1)
    g.insert(np.array([[1.0, 1.0, 0.3], [2.0, 2.0, 0.1], [12.0, 1.0, -0.5], [40.0, 40.0, 3.0]]))
    # cell (0, 0) holds 0.1; (2, 0) holds −0.5, two cells away: not a neighbour of (0, 0)
    assert g.height(np.array([[3.0, 4.0]]))[0] == pytest.approx(0.1)
    # a point in cell (1, 0) sees both neighbours: the lower one
    assert g.height(np.array([[7.0, 1.0]]))[0] == pytest.approx(-0.5)
    assert np.isnan(g.height(np.array([[-20.0, -20.0]]))[0])  # never seen
    g.insert(np.array([[1.5, 1.5, -0.2], [np.nan, 0.0, 0.0]]))  # lower, and a non-finite
    assert g.height(np.array([[3.0, 4.0]]))[0] == pytest.approx(-0.2)
    assert len(g) == 3


def test_the_stride_takes_every_nth_point() -> None:
    g = GroundGrid(cell_m=1.0, stride=2)
    g.insert(np.array([[0.5, 0.5, 1.0], [0.5, 0.5, -9.0], [0.5, 0.5, 2.0]]))
    assert g.height(np.array([[0.5, 0.5]]))[0] == pytest.approx(1.0)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 2**32 - 1), st.integers(1, 5))
def test_more_returns_never_raise_the_ground(seed: int, frames: int) -> None:
    rng = np.random.default_rng(seed)
    g = GroundGrid(cell_m=4.0, stride=1)
    probe = rng.uniform(-30, 30, size=(20, 2))
    before = np.full(20, np.inf)
    for _ in range(frames):
        g.insert(rng.uniform([-30, -30, -2], [30, 30, 5], size=(200, 3)))
        now = np.nan_to_num(g.height(probe), nan=np.inf)
        assert np.all(now <= before)
        before = now


def test_bad_settings_are_refused() -> None:
    with pytest.raises(InputError):
        GroundGrid(cell_m=0.0)
    with pytest.raises(InputError):
        GroundGrid(stride=0)
