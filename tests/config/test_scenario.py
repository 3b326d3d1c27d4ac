"""Scenarios: every named one builds and runs; TOML files load, override and round-trip."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dronetrack.config.reach import RETURN_SHARE
from dronetrack.config.run import apply_overrides, dump_scenario, load_scenario_file
from dronetrack.config.scenarios import SCENARIOS, get_scenario
from dronetrack.errors import ScenarioError, SensorError
from dronetrack.sim.build import build_world, resolve_scenario


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_every_named_scenario_runs(name: str) -> None:
    world = build_world(SCENARIOS[name])
    frame, truth = world.step()
    assert len(frame) > 0
    assert truth.n_pulses > 0
    assert np.all(np.isfinite(frame.points))


def test_default_scenario_is_seed_000_horizontal_fast() -> None:
    cfg = SCENARIOS["default"]
    assert (cfg.drone.model, cfg.sensor.model, cfg.turret.model) == ("phantom4", "avia", "widowx")
    assert cfg.trajectory.name == "horizontal-fast"
    assert cfg.weather.visibility_m == float("inf")


def test_toml_with_base_and_overrides(tmp_path: Path) -> None:
    path = tmp_path / "foggy_f550.toml"
    path.write_text(
        'base = "default"\nseed = 9\n[drone]\nmodel = "f550"\n[weather]\nvisibility_m = 80.0\n'
    )
    cfg = get_scenario(str(path))
    assert cfg.name == "foggy_f550"
    assert (cfg.seed, cfg.drone.model, cfg.weather.visibility_m) == (9, "f550", 80.0)
    assert cfg.sensor.model == "avia"  # from the base


def test_the_reach_follows_the_sensor_the_drone_and_the_air(tmp_path: Path) -> None:
    """acquire_in_reach_s counts from the Avia's 130 m reach for a Phantom 4 in clear
    air; another drone, sensor or fog has no measured reach, from the command line or
    from a file on a base, unless the file sets one."""
    default = SCENARIOS["default"]
    assert default.pipeline.evaluation.reach_m == 130.0
    assert SCENARIOS["outdoor-incoming"].pipeline.evaluation.reach_m == 130.0
    assert SCENARIOS["field-foggy"].pipeline.evaluation.reach_m is None
    assert SCENARIOS["indoor-horizontal"].pipeline.evaluation.reach_m is None
    # beyond this the drone returns no point: what returns there is no drone
    limits = {n: SCENARIOS[n].pipeline.evaluation.limit_m for n in ("default", "mid360-static")}
    assert limits == {"default": 195.0, "mid360-static": 50.0}
    assert SCENARIOS["field-foggy"].pipeline.evaluation.limit_m is None
    assert apply_overrides(default, seed=4).pipeline.evaluation.reach_m == 130.0
    for change in ({"visibility": 100.0}, {"drone": "f550"}, {"sensor": "mid360"}):
        assert apply_overrides(default, **change).pipeline.evaluation.reach_m is None
    assert apply_overrides(default, drone="phantom4").pipeline.evaluation.reach_m == 130.0
    path = tmp_path / "f550.toml"
    path.write_text('base = "default"\n[drone]\nmodel = "f550"\n')
    assert get_scenario(str(path)).pipeline.evaluation.reach_m is None
    path.write_text(
        'base = "default"\n[drone]\nmodel = "f550"\n[pipeline.evaluation]\nreach_m = 90.0\n'
    )
    assert get_scenario(str(path)).pipeline.evaluation.reach_m == 90.0
    path.write_text('base = "default"\nseed = 3\n')
    assert get_scenario(str(path)).pipeline.evaluation.reach_m == 130.0


def test_the_drones_return_share_follows_the_sensor_the_drone_and_the_air(
    tmp_path: Path,
) -> None:
    """The share of frames the drone returns a point by range is measured for the Avia
    and a Phantom 4 in clear air; the Mid-360, another drone or fog leave it out, and a
    file may set it."""
    default = SCENARIOS["default"].pipeline.evaluation.return_share_m
    assert default == RETURN_SHARE[("avia", "phantom4")]
    for name in ("mid360-static", "field-foggy", "indoor-horizontal"):
        assert SCENARIOS[name].pipeline.evaluation.return_share_m is None, name
    for change in ({"visibility": 100.0}, {"drone": "f550"}, {"sensor": "mid360"}):
        assert (
            apply_overrides(SCENARIOS["default"], **change).pipeline.evaluation.return_share_m
            is None
        )
    path = tmp_path / "f550.toml"
    path.write_text(
        'base = "default"\n[drone]\nmodel = "f550"\n'
        "[pipeline.evaluation]\nreturn_share_m = [160.0, 9.0]\n"
    )
    assert get_scenario(str(path)).pipeline.evaluation.return_share_m == (160.0, 9.0)
    path.write_text('base = "default"\n[pipeline.evaluation]\nreturn_share_m = [160.0, 0.0]\n')
    with pytest.raises(ScenarioError, match="return_share_m"):
        get_scenario(str(path))


def test_resolved_scenario_reproduces_the_run(tmp_path: Path) -> None:
    resolved = resolve_scenario(SCENARIOS["indoor-horizontal"])
    path = tmp_path / "resolved.toml"
    path.write_text(dump_scenario(resolved))
    reloaded = load_scenario_file(path, SCENARIOS)
    assert reloaded == resolved
    a, b = build_world(SCENARIOS["indoor-horizontal"]), build_world(reloaded)
    for _ in range(2):
        np.testing.assert_array_equal(a.step()[0].points, b.step()[0].points)


def test_trajectory_file_relative_to_the_toml_and_reproducible(tmp_path: Path) -> None:
    folder = tmp_path / "site"
    folder.mkdir()
    t = np.linspace(0.0, 4.0, 9)
    xyz = np.column_stack([20 + 2 * t, np.zeros_like(t), 10 + 0.5 * t])
    np.savetxt(
        folder / "flight.csv",
        np.column_stack([t, xyz]),
        delimiter=",",
        header="t,x,y,z",
        comments="",
    )
    path = folder / "mine.toml"
    path.write_text(
        'base = "default"\n[trajectory]\nfile = "flight.csv"\n[sensor]\nnoise = false\n'
    )
    cfg = get_scenario(str(path))
    assert cfg.trajectory.name is None
    assert Path(cfg.trajectory.file or "") == folder / "flight.csv"
    resolved = resolve_scenario(cfg)
    again = tmp_path / "again.toml"
    again.write_text(dump_scenario(resolved))
    reloaded = load_scenario_file(again, SCENARIOS)
    assert reloaded == resolved
    assert reloaded.sensor.noise is False
    a, b = build_world(cfg), build_world(reloaded)
    for _ in range(3):
        np.testing.assert_array_equal(a.step()[0].points, b.step()[0].points)
    np.testing.assert_allclose(a.target_position(2.0), [24.0, 0.0, 11.0], atol=1e-9)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ('base = "default"\n[sensor]\nmodle = "avia"\n', "unknown key 'sensor.modle'"),
        ("seed = -1\n", "seed"),
        ("duration_s = inf\n", "duration_s"),
        ("[turret]\ntilt_to_sensor_m = [0.0, 0.0, nan]\n", "tilt_to_sensor_m"),
        ("[sensor]\nintegration_time_s = 1e-9\n", "integration_time_s"),
        ('[sensor]\nmodel = "file:x.npy"\nlines = 300\n', "lines"),
        ("[weather]\nvisibility_m = nan\n", "visibility_m"),
        ('base = ["default"]\n', "unknown base scenario"),
        ("colour = 3\n", "unknown key 'colour'"),
        ('base = "nothing"\n', "unknown base scenario"),
        ("duration_s = -1\n", "duration_s"),
        ("duration_s = [\n", "invalid TOML"),
        ('[trajectory]\nname = "default"\nfile = "x.csv"\n', "not both"),
    ],
)
def test_bad_scenario_files(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(content)
    with pytest.raises(ScenarioError, match=message):
        get_scenario(str(path))


def test_unknown_names() -> None:
    with pytest.raises(ScenarioError, match="unknown scenario"):
        get_scenario("no-such-scenario")
    with pytest.raises(SensorError, match="unknown sensor"):
        build_world(
            SCENARIOS["default"].model_copy(
                update={"sensor": SCENARIOS["default"].sensor.model_copy(update={"model": "hdl64"})}
            )
        )
