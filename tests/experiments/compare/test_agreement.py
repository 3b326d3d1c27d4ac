"""One definition per metric: for the same run, ``simulate``'s metrics.json and
``compare``'s table give every key they share the same value."""

from __future__ import annotations

import math

import pytest

from dronetrack.experiments.compare.runner import case_config, run_suite
from dronetrack.experiments.compare.suites import SUITES
from dronetrack.jobs.simulate import run_simulation

DURATION_S = 3.0  # of flight after the background scan: enough for a lock


@pytest.mark.parametrize(
    ("suite_name", "shared"),
    [
        # Table II/III: coverage and distance, scored with the seed's five-frame rule
        ("seed000-ablation", {"coverage_pct", "max_tracking_distance_m"}),
        # Table IV: both RMSE windows
        ("seed000-indoor", {"rmse_m", "rmse_from_visible_m"}),
    ],
)
def test_simulate_and_compare_agree_on_shared_metric_keys(
    suite_name: str, shared: set[str]
) -> None:
    suite = SUITES[suite_name]
    case = suite.cases[0]
    table = run_suite(suite, runs=1, duration=DURATION_S, methods=["pf-delta"])
    row = next(r.metrics for r in table if r.case == case.label)
    metrics = run_simulation(case_config(case, "pf-delta", suite, 0, DURATION_S)).metrics()
    common = set(row) & set(metrics)
    assert shared <= common
    for key in sorted(common):
        a, b = float(metrics[key]), float(row[key])
        assert (math.isnan(a) and math.isnan(b)) or a == b, key


def test_the_two_rmse_windows_are_different_metrics() -> None:
    """Indoors the drone takes off hidden in the background, so the first visible frame
    comes before the first lock and the two windows differ: two names, two values."""
    suite = SUITES["seed000-indoor"]
    case = suite.cases[0]
    metrics = run_simulation(case_config(case, "pf-delta", suite, 0, DURATION_S)).metrics()
    assert metrics["rmse_from_visible_m"] != metrics["rmse_m"]
