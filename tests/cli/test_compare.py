"""``dronetrack compare``: suites, lockstep runs, tables and bad input."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.config.scenarios import SCENARIOS
from dronetrack.errors import ConfigError
from dronetrack.experiments.compare.ranking import ranking_differences
from dronetrack.experiments.compare.runner import RunMetrics, case_config, run_suite
from dronetrack.experiments.compare.suite import Case, Suite
from dronetrack.experiments.compare.suites import SUITES, get_suite
from dronetrack.experiments.compare.tables import TABLE_COLUMNS, aggregate
from dronetrack.jobs.simulate import run_lockstep, run_simulation
from dronetrack.pipeline.trackers import TRACKER_NAMES

_SUITE = Suite(
    name="toy",
    title="toy",
    methods=("a", "b", "c"),
    cases=(Case("x", "default", "truth"),),
    metrics=("coverage_pct", "rmse_m"),
    paper={("x", "a", "coverage_pct"): 50.0, ("x", "b", "coverage_pct"): 60.0},
)


def _result(method: str, run: int, coverage: float, err: float) -> RunMetrics:
    return RunMetrics("x", method, run, {"coverage_pct": coverage, "rmse_m": err})


def test_aggregate_takes_mean_and_sample_std_over_runs() -> None:
    results = [_result("a", 0, 40.0, 1.0), _result("a", 1, 50.0, 3.0), _result("b", 0, 70, 2)]
    rows = aggregate(_SUITE, results)
    by_key = {(r.method, r.metric): r for r in rows}
    assert by_key["a", "coverage_pct"].mean == 45.0
    assert by_key["a", "coverage_pct"].std == pytest.approx(np.std([40, 50], ddof=1))
    assert by_key["a", "coverage_pct"].paper == 50.0
    assert math.isnan(by_key["a", "rmse_m"].paper)
    assert math.isnan(by_key["b", "coverage_pct"].std)  # one run: no spread
    assert (by_key["a", "rmse_m"].runs, by_key["a", "rmse_m"].finite) == (2, 2)
    assert ("c", "coverage_pct") not in by_key  # a method that did not run


def test_runs_without_a_number_are_counted_not_hidden() -> None:
    rows = aggregate(_SUITE, [_result("a", 0, 40, math.nan), _result("a", 1, 50, 2.0)])
    (rmse_row,) = [r for r in rows if r.metric == "rmse_m"]
    assert (rmse_row.mean, rmse_row.finite, rmse_row.runs) == (2.0, 1, 2)
    assert math.isnan(rmse_row.std)


def test_ranking_differences_name_the_disagreements() -> None:
    # Ours: a (40) below b (70), as the paper (50 < 60): no difference.
    same = aggregate(_SUITE, [_result("a", 0, 40, 1), _result("b", 0, 70, 1)])
    assert ranking_differences(same) == []
    flipped = aggregate(_SUITE, [_result("a", 0, 80, 1), _result("b", 0, 70, 1)])
    (line,) = ranking_differences(flipped)
    # One run each: the order of the means, with no claim that the gap is real.
    assert line == (
        "x, coverage_pct (higher is better): ours a 80, then b 70; seed b 60, a 50.  "
        "Swapped against the seed: a 80 before b 70 (unjudged)"
    )
    # A tie ranks nothing.
    tie = aggregate(_SUITE, [_result("a", 0, 70, 1), _result("b", 0, 70, 1)])
    assert ranking_differences(tie) == []


def test_every_suite_names_known_methods_scenarios_and_paper_keys() -> None:
    for suite in SUITES.values():
        for case in suite.cases:
            assert case.scenario in SCENARIOS, case.scenario
        if suite.tracker is None:
            assert set(suite.methods) <= set(TRACKER_NAMES)
        for label, method, metric in suite.paper:
            assert label in {c.label for c in suite.cases}
            assert method in suite.methods
            assert metric in suite.metrics


def test_a_case_runs_the_method_the_seed_and_the_turret_mode() -> None:
    suite = get_suite("seed000-ablation")
    cfg = case_config(suite.cases[0], "ekf-dogru", suite, seed=3, duration=2.0)
    assert (cfg.seed, cfg.duration_s) == (3, 2.0)
    assert cfg.pipeline.tracker.kind == "ekf-dogru"
    assert cfg.pipeline.controller.mode == "fixed"


@pytest.mark.slow
def test_lockstep_runs_equal_single_runs() -> None:
    """Sharing the world changes nothing: each tracker's log is the one it gets alone."""
    cfg = case_config(
        get_suite("seed000-outdoor").cases[3], "pf-delta", get_suite("seed000-outdoor"), 1, 3.0
    )
    kinds = ("pf-delta", "ekf-dogru")
    trackers = [cfg.pipeline.tracker.model_copy(update={"kind": k}) for k in kinds]
    assert cfg.pipeline.evaluation.init_on_clean_view  # the suite's start, in the config
    together = run_lockstep(cfg, trackers)
    for kind, shared in zip(kinds, together, strict=True):
        alone = run_simulation(
            cfg.model_copy(
                update={
                    "pipeline": cfg.pipeline.model_copy(
                        update={"tracker": trackers[kinds.index(kind)]}
                    )
                }
            )
        )
        a, b = shared.log.arrays(), alone.log.arrays()
        for col in ("est_x", "est_y", "est_z", "gt_x", "n_points", "pan_rad"):
            np.testing.assert_array_equal(a[col], b[col], err_msg=f"{kind} {col}")


def test_lockstep_needs_a_turret_that_ignores_the_trackers() -> None:
    cfg = SCENARIOS["default"]
    t = cfg.pipeline.tracker
    with pytest.raises(ConfigError, match="truth"):
        run_lockstep(cfg, [t, t])


def test_unknown_method_in_a_suite_is_an_error() -> None:
    with pytest.raises(ConfigError, match="pf-nope"):
        run_suite(get_suite("seed000-outdoor"), 1, methods=["pf-nope"])


@pytest.mark.slow
def test_compare_writes_the_table_contract(tmp_path: Path) -> None:
    out = tmp_path / "cmp"
    code = run(
        [
            "compare",
            "--suite",
            "seed000-ablation",
            "--runs",
            "2",
            "--duration",
            "4",
            "--methods",
            "pf-delta,ekf-dogru",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    with (out / "table.csv").open() as fh:
        rows = list(csv.reader(fh))
    assert tuple(rows[0]) == TABLE_COLUMNS
    body = rows[1:]
    # 2 cases × 2 methods × 2 metrics, in suite order (ekf-dogru before pf-delta).
    assert [(r[0], r[1], r[2]) for r in body] == [
        (case, method, metric)
        for case in ("fixed", "moving")
        for method in ("ekf-dogru", "pf-delta")
        for metric in ("coverage_pct", "max_tracking_distance_m")
    ]
    paper = {(r[0], r[1], r[2]): r[5] for r in body}
    assert paper["moving", "pf-delta", "coverage_pct"] == "71.35"
    assert paper["fixed", "ekf-dogru", "max_tracking_distance_m"] == "80.3"
    assert all(math.isfinite(float(r[3])) for r in body)
    md = (out / "table.md").read_text()
    assert "| pf-delta |" in md
    # The options the table was run with, and the warning for the cut flights.
    assert "- `--runs 2`: seeds 0 and 1 " in md
    assert "- `--duration 4` s: shortened" in md
    assert "- methods: ekf-dogru, pf-delta (`--methods`; not run: pf-cv)" in md
    assert "**Shortened runs.**  These flights were cut to 4 s" in md


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["compare", "--suite", "seed999"], "unknown suite 'seed999'"),
        (["compare", "--suite", "seed002", "--methods", "pf-delta"], "'pf-delta' is not in"),
        (["simulate", "--tracker", "ekf-nope"], "ekf-nope"),
    ],
)
def test_bad_names_give_one_line_and_exit_2(
    args: list[str], message: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert run([*args, "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:")
    assert message in err
    assert len(err.splitlines()) == 1


def test_strategy_suite_writes_the_seed003_logs(tmp_path: Path) -> None:
    suite = get_suite("seed003")
    (result,) = run_suite(suite, 1, duration=12.0, methods=["swing"], log_dir=tmp_path)
    assert result.method == "swing"
    assert result.metrics["n_detections"] > 0
    folder = tmp_path / "field" / "swing" / "run0"
    headers = {
        "filtered_points.csv": "t,x,y,z,seq",
        "centroids.csv": "t,x,y,z",
        "states.csv": "t,from_state,to_state,strategy",
        "ekf.csv": "t,x,y,z,vx,vy,vz,P11,P22,P33,P44,P55,P66",
    }
    for name, header in headers.items():
        lines = (folder / name).read_text().splitlines()
        assert lines[0] == header
        assert len(lines) > 1, name  # the swing started, points and centroids arrived
    # Every detection frame put its points in filtered_points.csv.
    with (folder / "filtered_points.csv").open() as fh:
        frames = {row["seq"] for row in csv.DictReader(fh)}
    assert len(frames) == result.metrics["n_detections"]


def test_seed002_suite_measures_memory_and_load() -> None:
    (result,) = run_suite(get_suite("seed002"), 1, duration=3.0, methods=["aekf-ca"])
    m = result.metrics
    assert set(m) == set(get_suite("seed002").metrics)
    assert m["memory_mb"] > 0
    assert 0 < m["cpu_pct"] < 100  # a 10 Hz pipeline well inside its period
    assert m["update_hz"] == pytest.approx(10.0)
