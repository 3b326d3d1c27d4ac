"""The learning map in a closed-loop run with no clean scan (``preprocess.learning``)."""

from __future__ import annotations

import numpy as np
import pytest

from dronetrack.config.scenarios import get_scenario
from dronetrack.jobs.simulate import run_simulation


def test_a_run_without_a_scan_learns_the_static_world_and_never_the_drone() -> None:
    """``default`` switched on with no scan: every return is foreground at first.  After
    8 s the map holds most of what the turret sees: measured on seeds 0-2, the
    foreground of the frames after 8 s is 18-35 % of the first 2 s's (79-99 % with
    learning off, as the searching turret shows the static world from new bearings).
    No position the drone flew is in the map."""
    cfg = get_scenario("default")
    background = cfg.pipeline.background.model_copy(update={"scan_s": 0.0})
    pipeline = cfg.pipeline.model_copy(update={"background": background})
    run = run_simulation(
        cfg.model_copy(update={"seed": 0, "duration_s": 12.0, "pipeline": pipeline})
    )
    log = run.log
    early = log.n_points[log.t < 2.0].mean()
    late = log.n_points[log.t >= 8.0].mean()
    assert late < 0.5 * early
    learning = run.pipeline.learning
    assert learning is not None
    assert len(learning) > 100
    flown = log.gt[np.all(np.isfinite(log.gt), axis=1)]
    assert not learning.is_background(flown).any()


@pytest.mark.parametrize(
    "seed",
    [
        0,
        pytest.param(3, marks=pytest.mark.slow),
        pytest.param(4, marks=pytest.mark.slow),
        pytest.param(6, marks=pytest.mark.slow),
    ],
)
@pytest.mark.slow
def test_a_static_mid360_switched_on_with_the_drone_in_view_tracks_it(seed: int) -> None:
    """``mid360-static``: the drone hovers 2-3 m from the sensor through its 1 s scan,
    people walk around.  The scan leaves the free-standing drone out of the map, the
    learning map never takes it, and the walkers are not offered: measured 98.0-99.7 %
    lock-on while visible on seeds 0-4 (0 % before, the scan held the drone).  Seed 3:
    two false alarms joined the drone to the space beside the sensor until single
    returns stopped joining parts; seed 4: the drone hovered in a 2 m lookup cell
    over what the scan saw until the cells near the sensor were made finer; seed 6
    (99.0 %, 0 % false locks): during the scan the drone hovered 1 m beside and 0.5 m
    above a person standing still, one part of the scan with it (0 % until the scan
    left out small parts in the air, and a short scan's cells stopped counting as a
    structure beside a track)."""
    run = run_simulation(get_scenario("mid360-static").model_copy(update={"seed": seed}))
    metrics = run.metrics()
    assert metrics["lock_on_visible_pct"] >= 95.0
    assert metrics["false_lock_pct"] <= 2.0


@pytest.mark.slow
def test_a_busy_site_without_a_clean_scan_tracks_the_drone_not_the_people() -> None:
    """``site-busy`` seed 0: the drone in view from the first frame, a 1 s scan, four
    people walking below it and a car that parks.  Measured 98.0 % lock-on while
    visible and 2.3 % false locks (1.2 % and 99.5 % with the learning map alone: the
    tracker took a walker first)."""
    run = run_simulation(get_scenario("site-busy").model_copy(update={"seed": 0}))
    metrics = run.metrics()
    assert metrics["lock_on_visible_pct"] >= 95.0
    assert metrics["false_lock_pct"] <= 5.0
