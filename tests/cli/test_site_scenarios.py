"""The busy-site scenarios end to end, as a user runs them: ``dronetrack simulate NAME
--seed 0`` at their whole duration writes every frame, and the truth shows the drone
in view (the tracker's figures are whatever today's pipeline makes of them)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from dronetrack.cli.main import run
from dronetrack.config.scenarios import SCENARIOS

METRIC_KEYS = {"coverage_pct", "lock_on_visible_pct", "false_lock_pct", "drones", "mot"}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "visible_at_least"),
    [
        # the drone enters the view once the turret searches its way round (not before 10 s)
        ("outdoor-unscanned", 1),
        # in view from the first frame; the turret may look away later
        ("site-busy", 1),
        # 2-3 m from a sensor that never moves: in view in every frame
        ("mid360-static", 300),
    ],
)
def test_a_busy_site_scenario_runs_whole(name: str, visible_at_least: int, tmp_path: Path) -> None:
    out = tmp_path / name
    assert run(["simulate", name, "--seed", "0", "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert set(metrics) >= METRIC_KEYS
    assert metrics["frames"] == round(SCENARIOS[name].duration_s / 0.1)
    (drone,) = metrics["drones"]
    assert drone["visible_frames"] >= visible_at_least


@pytest.mark.slow
def test_a_lock_on_a_far_object_gives_way_to_the_drone(tmp_path: Path) -> None:
    """``outdoor-unscanned`` seed 6: the turret locks on a far tree's crown the scan never
    saw (190-200 m out, classed unknown) while the drone flies 55-70 m out in view, its
    track classed drone.  The lock then moves to the drone's track
    (``control.choose.drone_instead``): lock-on-visible 84.8 % and false locks 5.8 %
    (measured), where it held the crown for the whole run before (0 % and 100 %)."""
    out = tmp_path / "unscanned"
    assert run(["simulate", "outdoor-unscanned", "--seed", "6", "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    (drone,) = metrics["drones"]
    assert drone["lock_on_visible_pct"] >= 80.0
    assert metrics["false_lock_pct"] <= 10.0
