"""The classify stage's constants measured on the simulator (``experiments.calibrate``)."""

from __future__ import annotations

import numpy as np
import pytest

from dronetrack.classify.rules import ClassRules
from dronetrack.errors import InputError
from dronetrack.experiments.calibrate import (
    fast_stretches,
    flights_steady_flight_s,
    steady_flight_scale,
)


def test_a_fast_stretch_is_the_time_since_the_last_slow_sample() -> None:
    speed = np.array([5.0, 5.0, 1.0, 5.0, 5.0, 5.0, 3.9])
    assert fast_stretches(speed, 0.1, 4.0) == pytest.approx([0.1, 0.2, 0.1, 0.2, 0.3])
    assert len(fast_stretches(np.full(4, 2.0), 0.1, 4.0)) == 0


def test_exponential_runs_give_back_their_mean() -> None:
    # fast runs of exponential length (mean m) between slow samples: by the memoryless
    # property the time since a run began, at a random fast instant, is exponential
    # with the same mean, so the fit returns m
    rng = np.random.default_rng(7)
    dt, m = 0.05, 3.0
    runs = np.maximum(1, np.round(rng.exponential(m / dt, size=4000))).astype(int)
    speed = np.concatenate([np.r_[np.full(n, 10.0), 0.0] for n in runs])
    mu = steady_flight_scale([fast_stretches(speed, dt, 4.0)], horizon_s=3 * m)
    assert mu == pytest.approx(m, rel=0.05)


def test_no_fast_flight_is_refused() -> None:
    with pytest.raises(InputError, match="no fast flight"):
        steady_flight_scale([np.zeros(0)], horizon_s=5.0)


def test_the_rules_steady_flight_is_the_simulators_flights() -> None:
    assert ClassRules().steady_flight_s == pytest.approx(flights_steady_flight_s(), rel=0.05)
