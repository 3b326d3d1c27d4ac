"""What the commands print and write for a new user: Markdown tables on standard
output exactly as their files hold them (a pipe gets the file), a bad grid value named
with its grid file, key and value, ``sweep-report`` given the results file itself, and
a config.toml whose numbers read as typed (0.1, not 0.09999999999999999)."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path
from typing import Any

import pytest

from dronetrack.cli.main import run
from dronetrack.config.run import ScenarioConfig, dump_scenario, load_scenario_file
from dronetrack.config.scenarios import SCENARIOS, get_scenario
from dronetrack.experiments.compare.runner import RunMetrics
from dronetrack.experiments.compare.suite import Suite
from dronetrack.experiments.compare.suites import SUITES
from dronetrack.jobs.simulate import resolve_run

WIDTH = "80"  # a terminal's width; the tables' rows are longer


def _fake_suite(suite: Suite, runs: int, **_: Any) -> list[RunMetrics]:
    """Every case, method and run of ``suite`` with made-up metrics (no simulation)."""
    return [
        RunMetrics(case.label, method, r, {m: 10.0 + r for m in suite.metrics})
        for case in suite.cases
        for method in suite.methods
        for r in range(runs)
    ]


def test_compare_prints_table_md_as_written(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("COLUMNS", WIDTH)
    monkeypatch.setattr("dronetrack.experiments.compare.runner.run_suite", _fake_suite)
    out = tmp_path / "cmp"
    assert run(["compare", "--suite", next(iter(SUITES)), "--runs", "2", "--out", str(out)]) == 0
    table = (out / "table.md").read_text()
    assert max(len(line) for line in table.splitlines()) > int(WIDTH)  # wrapping would show
    assert table in capsys.readouterr().out


def _sweep_folder(folder: Path) -> Path:
    """A sweep's folder with two combinations of two runs each in results.jsonl."""
    eq11 = {"sigma_pos": 0.5, "sigma_vel": 0.5, "sigma_acc": 0.0, "sigma_m": 0.2}
    rows = [
        {
            "key": f"k{i}{r}",
            "params": {"particles": 1000 * (i + 1), "track.sigma_pos": 0.4 + 0.1 * i},
            "metrics": {"coverage_pct": 50.0 + 10 * i + r, "max_tracking_distance_m": 90.0 + r},
            "sigma": {**eq11, "sigma_pos": 0.4 + 0.1 * i},
            "eq11": eq11,
        }
        for i in range(2)
        for r in range(2)
    ]
    folder.mkdir(parents=True)
    (folder / "results.jsonl").write_text("".join(json.dumps(row) + "\n" for row in rows))
    return folder


@pytest.mark.parametrize("given", ["folder", "results file"])
def test_sweep_report_takes_the_folder_or_its_results_file(
    given: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.setenv("COLUMNS", WIDTH)
    folder = _sweep_folder(tmp_path / "sweep")
    target = folder if given == "folder" else folder / "results.jsonl"
    assert run(["sweep-report", str(target)]) == 0
    for name in ("report.md", "best.csv", "coverage_vs_distance.png"):
        assert (folder / name).stat().st_size > 0, name
    report = (folder / "report.md").read_text()
    assert max(len(line) for line in report.splitlines()) > int(WIDTH)
    assert report in capsys.readouterr().out


def test_sweep_report_says_what_it_expected(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    assert run(["sweep-report", str(empty)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"error: {empty}: no results.jsonl")
    assert "output folder" in err
    assert run(["sweep-report", str(tmp_path / "nowhere")]) == 2
    assert "not found" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("line", "key", "value"),
    [
        ("particles = [1000, 5]", "particles", "5"),
        ('"track.sigma_pos" = [0.4, -1.5]', "track.sigma_pos", "-1.5"),
        ('visibility = ["far"]', "visibility", '"far"'),
        ('"track.sigma_posx" = [0.25]', "track.sigma_posx", "0.25"),
        ('drone = ["phantom4", "nosuch"]', "drone", '"nosuch"'),
        ('sensor = ["hdl64"]', "sensor", '"hdl64"'),
    ],
)
def test_a_bad_grid_value_names_the_grid_file_the_key_and_the_value(
    line: str, key: str, value: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    grid = tmp_path / "my_grid.toml"
    grid.write_text(f'scenario = "default"\n[grid]\n{line}\n')
    out = tmp_path / "out"
    assert run(["sweep", str(grid), "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith(f"error: {grid}: [grid] {key} = {value}: "), err
    assert "command line" not in err
    assert not out.exists()  # nothing ran


@pytest.mark.slow
def test_track_writes_the_frame_period_as_typed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A recording's period comes from its nanosecond stamps; 0.1 s frames give 0.1 in
    config.toml, and the file, re-read, is the configuration the replay used."""
    bag = tmp_path / "flight.bag"
    assert run(["record", "indoor-horizontal", "--duration", "0.5", "--out", str(bag)]) == 0
    assert run(["track", str(bag), "--out", str(tmp_path / "track")]) == 0
    text = (tmp_path / "track" / "config.toml").read_text()
    assert tomllib.loads(text)["sensor"]["integration_time_s"] == 0.1
    assert "integration_time_s = 0.1\n" in text


def test_written_numbers_drop_arithmetic_noise_only() -> None:
    from dronetrack.config.tomlfile import tidy_float

    noisy = {0.3 - 0.2: 0.1, 0.1 + 0.2: 0.3, 0.2 * 3: 0.6, -(0.3 - 0.2): -0.1}
    for x, typed in noisy.items():
        assert x != typed
        assert tidy_float(x) == typed
    # Digits that are real stay, and so do the values TOML writes as words.
    for x in (2 / 30, 1 / 3, 129.55752193730785, 1e-5, 5e-324, 0.0, math.inf, 12345.678):
        assert tidy_float(x) == x
    assert math.isnan(tidy_float(math.nan))


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_a_written_configuration_re_reads_as_the_one_run(name: str, tmp_path: Path) -> None:
    """What a run resolves and writes (config.toml) resolves, read again, to the very
    same configuration: the same numbers, so the same run."""
    resolved = resolve_run(get_scenario(name))
    path = tmp_path / "config.toml"
    path.write_text(dump_scenario(resolved))
    assert resolve_run(load_scenario_file(path, SCENARIOS)) == resolved


def test_a_period_from_stamps_is_written_and_used_as_typed(tmp_path: Path) -> None:
    from dronetrack.jobs.run import resolve_pipeline

    sensor = get_scenario("default").sensor.model_copy(update={"integration_time_s": 0.3 - 0.2})
    cfg = resolve_pipeline(get_scenario("default").model_copy(update={"sensor": sensor}))
    assert cfg.sensor.integration_time_s == 0.1
    path = tmp_path / "config.toml"
    path.write_text(dump_scenario(cfg))
    again: ScenarioConfig = load_scenario_file(path, SCENARIOS)
    assert resolve_pipeline(again) == cfg


def test_a_note_on_standard_error_is_one_line_in_a_pipe(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # standard error is a pipe here, 80 columns wide: the note is longer than that and
    # must stay one line for a log file or a grep (a terminal wraps it on screen)
    from dronetrack.cli.output import print_kernel_note
    from dronetrack.pipeline.kernels import KernelWarmUp

    monkeypatch.setenv("COLUMNS", WIDTH)
    print_kernel_note(KernelWarmUp(seconds=7.2, compiled=21))
    err = capsys.readouterr().err
    assert len(err.rstrip("\n")) > int(WIDTH)
    assert err.count("\n") == 1
    assert err.startswith("compiled 21 kernel signatures in 7.2 s")
