"""The ``multi`` suite: its cases, its figures from each run's drones, mot and classes,
table.md's grouped tables, results.jsonl and confusion.md, and a short real run."""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from dronetrack.cli.main import run
from dronetrack.config.run import dump_scenario
from dronetrack.config.scenarios import get_scenario
from dronetrack.experiments.compare.multi_suite import MULTI_METRICS
from dronetrack.experiments.compare.run_files import confusion_markdown, summed_confusion
from dronetrack.experiments.compare.runner import (
    RunMetrics,
    case_config,
    object_run_metrics,
    run_suite,
)
from dronetrack.experiments.compare.suites import get_suite
from dronetrack.experiments.compare.tables import aggregate, table_markdown
from dronetrack.jobs.simulate import run_simulation

MULTI = get_suite("multi")


def test_the_suite_runs_the_named_scenarios_with_their_own_chooser() -> None:
    assert [c.scenario for c in MULTI.cases] == [
        "outdoor-two-drones",
        "outdoor-swarm",
        "outdoor-clutter",
        "default",
        "outdoor-unscanned",
        "site-busy",
        "mid360-static",
    ]
    assert [c.label for c in MULTI.cases] == [c.scenario for c in MULTI.cases]
    chooser = {}
    for case in MULTI.cases:
        cfg = case_config(case, "pf-delta", MULTI, seed=1, duration=5.0)
        assert cfg.pipeline.acquisition.enabled
        # the scenario's own turret: tracking, but for the static Mid-360
        want = "fixed" if case.scenario == "mid360-static" else "tracking"
        assert cfg.pipeline.controller.mode == want
        assert (cfg.seed, cfg.duration_s) == (1, 5.0)
        chooser[case.label] = cfg.pipeline.choose.enabled
        # a shortened run leaves out the vehicles that would park after it
        assert all(v.arrive_s < 5.0 for v in cfg.vehicles)
    # the turret shares itself among several drones; one drone needs no chooser
    assert chooser == {
        "outdoor-two-drones": True,
        "outdoor-swarm": True,
        "outdoor-clutter": False,
        "default": False,
        "outdoor-unscanned": False,
        "site-busy": False,
        "mid360-static": False,
    }
    assert set(MULTI.metrics) == {m for g in MULTI.groups for m in g.metrics}


def _confusion(**rows: dict[str, int]) -> dict[str, dict[str, int]]:
    zero = {"unknown": 0, "drone": 0, "bird": 0, "static": 0}
    return {kind: {**zero, **rows.get(kind, {})} for kind in ("drone", "bird", "none")}


def _objects(drones: list[dict[str, Any]], confusion: dict[str, Any]) -> dict[str, Any]:
    return {
        "drones": drones,
        "mot": {"mota": 0.5, "motp_m": 0.3, "idf1": 0.75, "id_switches": 2},
        "classes": {
            "radius_m": 4.0,
            "min_age_s": 2.0,
            "confusion": confusion,
            "drone_as_drone_pct": 90.0,
            "bird_as_drone_pct": None,
            "none_as_drone_pct": 0.0,
            "static_tracks": 1,
            "static_classed": 1,
            "static_to_class_median_s": 2.0,
            "static_to_class_max_s": 2.0,
            "static_late": 0,
            "static_held_s": 0.5,
        },
    }


def _drone(coverage: float, acquire: float | None, own: float, switches: int) -> dict[str, Any]:
    return {
        "coverage_pct": coverage,
        "acquire_s": acquire,
        "lock_on_visible_pct": coverage + 5.0,
        "own_track_pct": own,
        "id_switches": switches,
        "visible_frames": 100,
    }


TWO = [_drone(40.0, 0.5, 80.0, 0), _drone(80.0, None, 100.0, 1)]


def test_a_runs_figures_are_its_drones_worst_and_mean_its_mot_and_its_classes() -> None:
    m = object_run_metrics(_objects(TWO, _confusion()))
    assert set(m) >= set(MULTI_METRICS)
    assert (m["coverage_min_pct"], m["coverage_mean_pct"]) == (40.0, 60.0)
    assert (m["lock_on_visible_min_pct"], m["lock_on_visible_mean_pct"]) == (45.0, 65.0)
    assert (m["own_track_min_pct"], m["own_track_mean_pct"]) == (80.0, 90.0)
    # acquisition over the drones acquired; the other is counted as never acquired
    assert (m["acquire_max_s"], m["acquire_mean_s"], m["never_acquired"]) == (0.5, 0.5, 1.0)
    assert m["id_switches_max"] == 1.0
    assert (m["mota"], m["motp_m"], m["idf1"], m["id_switches"]) == (0.5, 0.3, 0.75, 2.0)
    assert m["drone_as_drone_pct"] == 90.0
    assert math.isnan(m["bird_as_drone_pct"])  # no bird frames: no number, not 0


def _results(runs: int = 2) -> list[RunMetrics]:
    """Every case of the suite, ``runs`` runs, made-up objects (no simulation)."""
    confusions = [
        _confusion(drone={"drone": 9, "bird": 1}),
        _confusion(drone={"drone": 10}, none={"static": 5}),
    ]
    out = []
    for case in MULTI.cases:
        for r in range(runs):
            objects = _objects(TWO, confusions[r % 2])
            out.append(RunMetrics(case.label, "pf-delta", r, object_run_metrics(objects), objects))
    return out


def test_the_figures_within_reach_are_over_the_drones_that_have_them() -> None:
    """``acquire_in_reach_s`` and ``track_acquire_in_reach_s`` are summarised as
    ``acquire_s`` is: the worst and the mean over the drones that have one; a run
    without the sensor's reach has none (NaN)."""
    near = [
        {**TWO[0], "acquire_in_reach_s": 0.25, "track_acquire_in_reach_s": 0.0},
        {**TWO[1], "acquire_in_reach_s": None, "track_acquire_in_reach_s": 0.5},
        {**TWO[0], "acquire_in_reach_s": 0.75, "track_acquire_in_reach_s": 0.25},
    ]
    m = object_run_metrics(_objects(near, _confusion()))
    assert (m["acquire_in_reach_max_s"], m["acquire_in_reach_mean_s"]) == (0.75, 0.5)
    assert (m["track_acquire_in_reach_max_s"], m["track_acquire_in_reach_mean_s"]) == (0.5, 0.25)
    m = object_run_metrics(_objects(TWO, _confusion()))
    assert math.isnan(m["acquire_in_reach_max_s"])
    assert math.isnan(m["track_acquire_in_reach_max_s"])


def test_table_md_has_a_table_per_group_and_a_row_per_scenario() -> None:
    rows = aggregate(MULTI, _results())
    md = table_markdown(MULTI, rows, runs=2, duration=None, methods=MULTI.methods)
    for group in MULTI.groups:
        header = f"## {group.title}\n\n| scenario | " + " | ".join(group.metrics) + " |\n"
        assert header in md
    table = md.split("## Every drone")[1].split("##")[0]
    lines = [line for line in table.splitlines() if line.startswith("| ")]
    assert [line.split(" | ")[0] for line in lines[1:]] == [f"| {c.label}" for c in MULTI.cases]
    # no figure within reach in these runs: n/a
    assert "| outdoor-swarm | 40 ± 0 | 60 ± 0 | 0.5 ± 0 | 0.5 ± 0 | n/a | 1 ± 0 |" in md
    assert "| default | 90 ± 0 | n/a | 0 ± 0 |" in md  # no bird frames: n/a


def test_confusion_md_sums_each_scenarios_runs_with_row_shares() -> None:
    results = _results()
    summed = summed_confusion([r for r in results if r.case == "default"])
    assert summed is not None
    kinds, classes, counts = summed
    assert kinds == ["drone", "bird", "none"]
    assert classes == ["unknown", "drone", "bird", "static"]
    assert counts.tolist() == [[0, 19, 1, 0], [0, 0, 0, 0], [0, 0, 0, 5]]
    md = confusion_markdown(MULTI, results, runs=2, duration=None, methods=MULTI.methods)
    assert md is not None
    section = md.split("## default\n")[1]
    assert "| drone | 0 (0.0 %) | 19 (95.0 %) | 1 (5.0 %) | 0 (0.0 %) | 20 |" in section
    assert "| none | 0 (0.0 %) | 0 (0.0 %) | 0 (0.0 %) | 5 (100.0 %) | 5 |" in section
    assert "\n| bird |" not in section  # a row without frames is left out
    assert md.count("| truth \\ class | unknown | drone | bird | static | frames |") == len(
        {r.case for r in results}
    )
    # suites whose runs have no classes write none
    plain = [replace(r, objects={}) for r in results]
    assert confusion_markdown(MULTI, plain, runs=2, duration=None, methods=MULTI.methods) is None


def test_compare_multi_writes_table_results_and_confusion(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(
        "dronetrack.experiments.compare.runner.run_suite", lambda *_, **__: _results()
    )
    out = tmp_path / "multi"
    assert run(["compare", "--suite", "multi", "--runs", "2", "--out", str(out)]) == 0
    lines = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert len(lines) == 2 * len(MULTI.cases)
    first = lines[0]
    assert (first["suite"], first["case"], first["method"], first["seed"]) == (
        "multi",
        "outdoor-two-drones",
        "pf-delta",
        0,
    )
    assert set(first["metrics"]) >= set(MULTI_METRICS)
    assert first["metrics"]["bird_as_drone_pct"] is None  # JSON has no NaN
    assert first["classes"]["confusion"]["drone"]["drone"] == 9
    assert len(first["drones"]) == 2
    assert "## Classes" in (out / "table.md").read_text()
    assert "## outdoor-swarm" in (out / "confusion.md").read_text()


def test_shortened_runs_of_a_suite_without_paper_figures_name_no_seed() -> None:
    md = table_markdown(MULTI, [], runs=1, duration=5.0, methods=MULTI.methods)
    warning = next(line for line in md.splitlines() if line.startswith("**Shortened"))
    assert "outdoor-swarm 40 s" in warning
    assert "seed" not in warning


@pytest.mark.slow
def test_a_short_run_of_a_case_scores_as_simulate_does() -> None:
    """``default`` seed 0, 14 s of flight: the runner's figures are metrics.json's of the
    same run, and the drone's track after 2 s of life is classed drone (over the whole
    flight 100 % on seed 0 and 96.5 % on seed 1; the issue's target is 95 %)."""
    suite = replace(MULTI, cases=tuple(c for c in MULTI.cases if c.scenario == "default"))
    (result,) = run_suite(suite, runs=1, duration=14.0)
    assert result.case == "default"
    metrics = run_simulation(case_config(suite.cases[0], "pf-delta", suite, 0, 14.0)).metrics()
    assert result.objects["classes"] == metrics["classes"]
    assert result.objects["mot"] == metrics["mot"]
    assert result.objects["drones"] == metrics["drones"]
    m = result.metrics
    assert set(m) == set(MULTI_METRICS)
    assert m["drone_as_drone_pct"] >= 95.0
    assert m["never_acquired"] == 0.0
    assert m["acquire_max_s"] <= 1.0  # the "acquired ≤ 1 s after it is in view"


@pytest.mark.parametrize("seed", [0, 3])
def test_each_case_is_its_scenario_as_named(seed: int) -> None:
    """A row of the multi suite is ``simulate SCENARIO --seed r``: the configuration of
    each case is the named scenario's, its turret mode included (the static Mid-360
    of mid360-static stays still)."""
    for case in MULTI.cases:
        ours = case_config(case, "pf-delta", MULTI, seed, None)
        named = get_scenario(case.scenario).model_copy(update={"seed": seed})
        assert dump_scenario(ours) == dump_scenario(named), case.label
    static = case_config(MULTI.cases[-1], "pf-delta", MULTI, seed, None)
    assert (static.name, static.pipeline.controller.mode) == ("mid360-static", "fixed")
