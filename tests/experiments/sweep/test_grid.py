"""Grid files: validation, expansion into runs, and applying a grid point."""

from __future__ import annotations

from pathlib import Path

import pytest

from dronetrack.config.scenarios import get_scenario
from dronetrack.errors import ConfigError, ScenarioError
from dronetrack.experiments.sweep.grid import (
    GridSpec,
    RunSpec,
    check_keys,
    expand,
    load_grid,
    run_config,
)


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "grid.toml"
    path.write_text(text)
    return path


def test_expansion_is_the_product_times_the_seeds(tmp_path: Path) -> None:
    spec = load_grid(
        _write(
            tmp_path,
            'scenario = "indoor-fast"\nduration = 20\nruns = 3\nseed = 7\n[grid]\n'
            'particles = [1000, 3000]\ntracker = ["pf-delta", "pf-cv"]\n'
            '"track.sigma_pos" = [0.4, 0.5, 0.6]\n',
        )
    )
    runs = expand(spec)
    assert len(runs) == 2 * 2 * 3 * 3
    assert {r.seed for r in runs} == {7, 8, 9}
    assert len({r.key for r in runs}) == len(runs)  # every run has its own name
    assert len({r.combination for r in runs}) == 12
    assert runs[0].params == {"particles": 1000, "tracker": "pf-delta", "track.sigma_pos": 0.4}
    assert runs[0].source == {"scenario": "indoor-fast"}
    # The names are stable: the same grid gives the same keys.
    assert [r.key for r in expand(spec)] == [r.key for r in runs]
    # ... and they depend on everything that defines a run.
    other = RunSpec(runs[0].source, 10.0, runs[0].params, runs[0].seed)
    assert other.key != runs[0].key


def test_a_grid_point_sets_options_and_dotted_keys() -> None:
    base = get_scenario("default")
    run = RunSpec(
        {"scenario": "default"},
        5.0,
        {
            "particles": 1234,
            "tracker": "pf-cv",
            "visibility": 800.0,
            "turret": "fixed",
            "track.sigma_pos": 0.45,
            "pipeline.background.scan_s": 3.0,
        },
        11,
    )
    cfg = run_config(base, run)
    assert cfg.seed == 11
    assert cfg.duration_s == 5.0
    assert cfg.pipeline.tracker.particles == 1234
    assert cfg.pipeline.tracker.kind == "pf-cv"
    assert cfg.weather.visibility_m == 800.0
    assert cfg.pipeline.controller.mode == "fixed"
    assert cfg.pipeline.tracker.sigma_pos == 0.45
    assert cfg.pipeline.background.scan_s == 3.0
    # The base is untouched.
    assert base.pipeline.tracker.sigma_pos is None


def test_bad_grids_are_named(tmp_path: Path) -> None:
    base = get_scenario("default")
    with pytest.raises(ConfigError, match="unknown key 'sigma_posx'"):
        check_keys(GridSpec(grid={"track.sigma_posx": [0.1]}), base)
    with pytest.raises(ConfigError, match="no section 'trackr'"):
        check_keys(GridSpec(grid={"pipeline.trackr.sigma_pos": [0.1]}), base)
    with pytest.raises(ScenarioError, match="sigma_pos"):
        check_keys(GridSpec(grid={"track.sigma_pos": [0.4, -1.0]}), base)
    with pytest.raises(ScenarioError, match="tracker"):
        check_keys(GridSpec(grid={"tracker": ["pf-delta", "kalman"]}), base)
    with pytest.raises(ConfigError, match="scenario or recording, not both"):
        load_grid(_write(tmp_path, 'scenario = "default"\nrecording = "x.bag"\n'))
    with pytest.raises(ConfigError, match="has no values"):
        load_grid(_write(tmp_path, "[grid]\nparticles = []\n"))
    with pytest.raises(ConfigError, match="unknown key 'worker'"):
        load_grid(_write(tmp_path, "worker = 3\n"))
    with pytest.raises(ConfigError, match="invalid TOML"):
        load_grid(_write(tmp_path, "[grid\n"))
    with pytest.raises(ConfigError, match="grid file not found"):
        load_grid(tmp_path / "missing.toml")


def test_a_recording_path_is_relative_to_the_grid_file(tmp_path: Path) -> None:
    spec = load_grid(_write(tmp_path, 'recording = "flights/a.bag"\n'))
    assert spec.source == {"recording": str(tmp_path / "flights" / "a.bag")}
    assert len(expand(spec)) == 1


@pytest.mark.parametrize(("name", "n"), [("grid_eq12.toml", 900), ("grid_small.toml", 12)])
def test_the_example_grids_are_valid(name: str, n: int) -> None:
    spec = load_grid(Path(__file__).parents[3] / "examples" / name)
    check_keys(spec, get_scenario(spec.scenario or "default"))
    assert len(expand(spec)) == n
