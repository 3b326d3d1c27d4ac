"""One definition per metric: for the same run, ``simulate``'s metrics.json and
``compare``'s table give every key they share the same value."""

from __future__ import annotations

import dataclasses
import json
import math
import shlex
import tomllib
from pathlib import Path

import pytest

from dronetrack.cli.main import run
from dronetrack.experiments.compare.run_files import RESULTS_FILE, write_run_files
from dronetrack.experiments.compare.runner import case_config, run_suite
from dronetrack.experiments.compare.suites import SUITES
from dronetrack.jobs.simulate import run_simulation

DURATION_S = 3.0  # of flight after the background scan: enough for a lock
# A table's number where metrics.json keeps a list: the acquisition table's
# reacquire_s is the run's longest re-acquisition (the suite's note says so).
TABLE_NAMES = {"reacquire_s": "reacquire_max_s"}
# metrics.json's figures of the machine, not of the run
WALL_CLOCK = {"wall_s", "realtime_factor", "step_ms_mean", "step_ms_std", "step_ms_max"}


@pytest.mark.parametrize(
    ("suite_name", "shared"),
    [
        # Table II/III: coverage and distance, scored with the seed's five-frame rule
        ("seed000-ablation", {"coverage_pct", "max_tracking_distance_m"}),
        # Table IV: both RMSE windows
        ("seed000-indoor", {"rmse_m", "rmse_from_visible_m"}),
    ],
)
@pytest.mark.slow
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


@pytest.mark.slow
def test_every_row_reruns_from_its_configuration(tmp_path: Path) -> None:
    """Each run of ``compare`` writes its configuration and the command that reruns it;
    ``simulate --config`` of it gives the row's figures exactly, for a Kalman filter
    started on the clean view as seed 000's were (a setting the named scenario lacks)."""
    out = tmp_path / "cmp"
    argv = ["compare", "--suite", "seed000-indoor", "--runs", "1", "--duration", "3"]
    assert run([*argv, "--methods", "ekf-dogru", "--out", str(out)]) == 0
    lines = [json.loads(x) for x in (out / "results.jsonl").read_text().splitlines()]
    assert len(lines) == len(SUITES["seed000-indoor"].cases)
    line = lines[0]
    config = Path(line["config"])
    assert config == out / "runs" / line["case"] / "ekf-dogru" / "seed-0" / "config.toml"
    assert json.loads((config.parent / "metrics.json").read_text())["rmse_m"] == pytest.approx(
        line["metrics"]["rmse_m"], nan_ok=True
    )
    assert shlex.split(line["command"]) == ["dronetrack", "simulate", "--config", str(config)]
    saved = tomllib.loads(config.read_text())
    assert saved["pipeline"]["evaluation"]["init_on_clean_view"] is True
    assert saved["pipeline"]["controller"]["mode"] == "truth"  # the case's turret
    rerun = tmp_path / "rerun"
    assert run([*shlex.split(line["command"])[1:], "--out", str(rerun)]) == 0
    metrics = json.loads((rerun / "metrics.json").read_text())
    common = set(metrics) & set(line["metrics"])
    assert {"rmse_m", "rmse_from_visible_m"} <= common
    for key in sorted(common):
        assert metrics[key] == line["metrics"][key], key


@pytest.mark.parametrize("suite_name", sorted(SUITES))
@pytest.mark.slow
def test_a_run_of_every_suite_reruns_from_its_folder(suite_name: str, tmp_path: Path) -> None:
    """One case of each suite, its first method: the run's folder holds its
    configuration and metrics, and ``simulate --config`` of it gives every metric the
    run reported, exactly."""
    full = SUITES[suite_name]
    suite = dataclasses.replace(full, cases=full.cases[:1])
    method = suite.methods[0]
    results = run_suite(suite, runs=1, duration=DURATION_S, methods=[method])
    out = tmp_path / "cmp"
    write_run_files(suite, results, out, runs=1, duration=DURATION_S, methods=[method])
    line = json.loads((out / RESULTS_FILE).read_text().splitlines()[0])
    folder = out / "runs" / line["case"] / method / "seed-0"
    assert Path(line["config"]) == folder / "config.toml"
    saved = json.loads((folder / "metrics.json").read_text())
    rerun = tmp_path / "rerun"
    assert run([*shlex.split(line["command"])[1:], "--out", str(rerun)]) == 0
    metrics = json.loads((rerun / "metrics.json").read_text())
    assert {k: v for k, v in metrics.items() if k not in WALL_CLOCK} == {
        k: v for k, v in saved.items() if k not in WALL_CLOCK
    }
    for key, value in line["metrics"].items():  # the table's numbers come from that run
        name = TABLE_NAMES.get(key, key)
        if name in saved and key != "memory_mb":
            assert value == pytest.approx(saved[name], nan_ok=True), key
