"""``[[targets]]``: further drones in a scenario file, their paths, start times and bad
values; the command line's repeated ``--trajectory``; the named scenarios with several
drones."""

from __future__ import annotations

import math
from itertools import combinations
from pathlib import Path

import numpy as np
import pytest

from dronetrack.config.run import (
    ScenarioConfig,
    TargetConfig,
    apply_overrides,
    dump_scenario,
    load_scenario_file,
)
from dronetrack.config.scenarios import SCENARIOS, get_scenario
from dronetrack.errors import ScenarioError
from dronetrack.jobs.run import run_seeds
from dronetrack.jobs.simulate import flight_config
from dronetrack.sim.build import build_world, resolve_scenario
from sim_helpers import assert_same_frames

REACH_M = 130.0  # the Avia's for a Phantom 4 in clear air (config.reach.REACH_M)


def _csv(path: Path, t: np.ndarray, xyz: np.ndarray) -> Path:
    np.savetxt(path, np.column_stack([t, xyz]), delimiter=",", header="t,x,y,z", comments="")
    return path


def _line(path: Path) -> Path:
    """A 4 s straight flight 20-28 m out, 10-12 m up."""
    t = np.linspace(0.0, 4.0, 9)
    return _csv(path, t + 100.0, np.column_stack([20 + 2 * t, np.ones_like(t), 10 + 0.5 * t]))


def _scenario_file(folder: Path, text: str) -> Path:
    """A scenario file ``text`` in ``folder``, beside a flight ``b.csv`` (``_line``)."""
    _line(folder / "b.csv")
    path = folder / "two.toml"
    path.write_text(text)
    return path


def test_targets_in_a_file_load_with_paths_next_to_it_and_defaults(tmp_path: Path) -> None:
    path = _scenario_file(
        tmp_path,
        'base = "default"\n'
        '[[targets]]\nmodel = "f550"\nflight = "aggressive"\nstart_s = 5.0\n'
        '[[targets]]\nfile = "b.csv"\nhold_s = 1.5\nreflectivity_scale = 0.5\n',
    )
    cfg = get_scenario(str(path))
    assert [t.model for t in cfg.targets] == ["f550", "phantom4"]
    assert cfg.targets[0].flight == "aggressive"
    assert cfg.targets[0].start_s == 5.0
    assert Path(cfg.targets[1].file or "") == tmp_path / "b.csv"
    assert (cfg.targets[1].start_s, cfg.targets[1].hold_s) == (0.0, 1.5)
    assert cfg.drone.model == "phantom4"  # the target itself is untouched
    assert cfg.trajectory.name == "horizontal-fast"


def test_a_targets_path_starts_at_its_start_plus_hold(tmp_path: Path) -> None:
    """A file's first row is placed at start_s + hold_s (as [trajectory] file at its
    hold_s); before start_s the drone is not in the world."""
    csv = _line(tmp_path / "b.csv")
    target = TargetConfig(file=str(csv), start_s=3.0, hold_s=1.0)
    cfg = SCENARIOS["default"].model_copy(update={"targets": (target,)})
    drone = build_world(cfg).targets[1]
    assert drone.enter_s == 3.0
    assert not drone.present(2.99)
    assert drone.present(3.0)
    np.testing.assert_allclose(drone.trajectory.position(4.0)[0], [20.0, 1.0, 10.0])
    np.testing.assert_allclose(drone.trajectory.position(6.0)[0], [24.0, 1.0, 11.0], atol=1e-9)


def test_simulate_counts_a_start_from_the_end_of_the_background_scan() -> None:
    cfg = SCENARIOS["outdoor-two-drones"]
    scan_s = cfg.pipeline.background.scan_s
    late = cfg.model_copy(update={"targets": (cfg.targets[0].model_copy(update={"start_s": 4.0}),)})
    flight = flight_config(late)
    assert flight.targets[0].start_s == scan_s + 4.0
    assert flight.trajectory.hold_s == scan_s
    assert late.targets[0].start_s == 4.0  # the configuration itself is not changed


def test_a_scenario_file_with_targets_round_trips(tmp_path: Path) -> None:
    path = _scenario_file(
        tmp_path,
        'base = "outdoor-two-drones"\nduration_s = 6.0\n'
        '[[targets]]\nflight = "crossing-right"\n'
        '[[targets]]\nmodel = "spyder-x4"\nfile = "b.csv"\nstart_s = 2.0\n',
    )
    resolved = resolve_scenario(get_scenario(str(path)))
    assert Path(resolved.targets[1].file or "").is_absolute()
    text = dump_scenario(resolved)
    assert text.count("[[targets]]") == 2
    again = tmp_path / "elsewhere" / "again.toml"
    again.parent.mkdir()
    again.write_text(text)
    reloaded = load_scenario_file(again, SCENARIOS)
    assert reloaded == resolved
    assert_same_frames(resolved, reloaded, 25)


def test_a_scenario_without_targets_writes_none() -> None:
    assert "targets" not in dump_scenario(resolve_scenario(SCENARIOS["default"]))


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ('start_s = -1.0\nflight = "aggressive"\n', r"targets\.0\.start_s.*greater than or equal"),
        ('start_s = 66.0\nflight = "aggressive"\n', r"targets\.0\.start_s = 66 s is not before"),
        ('start_s = 70.0\nflight = "aggressive"\n', r"run ends \(duration_s = 66 s\)"),
        ('flight = "aggressive"\nfile = "b.csv"\n', "either a flight"),
        ('model = "f550"\n', "either a flight"),
        ('flight = "aggressive"\ncolour = 1\n', "unknown key 'targets.0.colour'"),
    ],
)
def test_bad_target_entries_name_the_entry(tmp_path: Path, entry: str, message: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(f'base = "default"\n[[targets]]\n{entry}')
    with pytest.raises(ScenarioError, match=message):
        get_scenario(str(path))


@pytest.mark.parametrize(
    ("target", "message"),
    [
        ({"model": "x-wing", "flight": "aggressive"}, "targets.0: unknown drone 'x-wing'"),
        ({"flight": "loop-the-loop"}, "targets.0: unknown trajectory 'loop-the-loop'"),
        ({"file": "/nowhere/b.csv"}, "targets.0: trajectory CSV not found: /nowhere/b.csv"),
    ],
)
def test_a_target_that_cannot_be_built_is_a_scenario_error(
    target: dict[str, str], message: str
) -> None:
    cfg = SCENARIOS["default"].model_copy(update={"targets": (TargetConfig(**target),)})
    with pytest.raises(ScenarioError, match=message):
        build_world(cfg)


def test_an_unreadable_target_file_is_a_scenario_error(tmp_path: Path) -> None:
    bad = tmp_path / "b.csv"
    bad.write_text("t,x,y\n0,1,2\n1,2,3\n")
    cfg = SCENARIOS["default"].model_copy(update={"targets": (TargetConfig(file=str(bad)),)})
    with pytest.raises(ScenarioError, match=r"targets\.0: .*b\.csv.*z"):
        build_world(cfg)


def test_a_shorter_run_than_a_targets_start_is_refused() -> None:
    cfg = SCENARIOS["default"].model_copy(
        update={"targets": (TargetConfig(flight="aggressive", start_s=30.0),)}
    )
    assert apply_overrides(cfg, duration=31.0).duration_s == 31.0
    with pytest.raises(ScenarioError, match=r"command line: targets\.0\.start_s = 30 s"):
        apply_overrides(cfg, duration=20.0)


def test_each_further_trajectory_adds_a_drone_of_the_scenarios_model(tmp_path: Path) -> None:
    a, b, c = (_line(tmp_path / f"{n}.csv") for n in "abc")
    base = SCENARIOS["outdoor-two-drones"]
    one = apply_overrides(base, trajectory=a)
    assert one.trajectory.file == str(a)
    assert one.targets == base.targets
    three = apply_overrides(base, trajectory=[a, b, c], drone="f550")
    assert three.trajectory.file == str(a)
    assert three.drone.model == "f550"
    assert three.targets[: len(base.targets)] == base.targets
    added = three.targets[len(base.targets) :]
    assert [(t.model, t.file, t.start_s) for t in added] == [
        ("f550", str(b), 0.0),
        ("f550", str(c), 0.0),
    ]


def _paths(name: str, seed: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """A named scenario's flight times after the scan, and every drone's path then."""
    cfg = SCENARIOS[name].model_copy(update={"seed": seed})
    world = build_world(flight_config(cfg), np.random.default_rng(run_seeds(seed)[0]))
    scan_s = cfg.pipeline.background.scan_s
    t = scan_s + np.arange(0.0, cfg.duration_s, 0.05)
    return t, [d.trajectory.position(t) for d in world.targets]


def _bearing(p: np.ndarray) -> np.ndarray:
    return np.degrees(np.arctan2(p[:, 1], p[:, 0]))


@pytest.mark.parametrize("seed", range(10))
def test_the_two_drones_come_from_60_degrees_apart_and_cross_once_within_reach(
    seed: int,
) -> None:
    _, (a, b) = _paths("outdoor-two-drones", seed)
    assert _bearing(a[:1]) - _bearing(b[:1]) == pytest.approx(60.0, abs=2.0)
    side = np.sign(_bearing(a) - _bearing(b))
    swaps = np.flatnonzero(side[1:] != side[:-1])
    assert len(swaps) == 1
    at = swaps[0]
    for p in (a, b):
        assert np.linalg.norm(p[at, :2]) < REACH_M
        assert abs(_bearing(p[at : at + 1])[0]) < 90.0  # in the ±90° field of regard
    # They pass each other, not through each other.
    assert np.linalg.norm(a - b, axis=1).min() > 5.0
    cfg = SCENARIOS["outdoor-two-drones"]
    fov = cfg.pipeline.field_of_regard
    assert fov is not None
    assert fov.pan_deg == (-90.0, 90.0)


@pytest.mark.parametrize("seed", range(10))
def test_the_swarms_four_drones_stay_apart_and_come_within_reach(seed: int) -> None:
    _, paths = _paths("outdoor-swarm", seed)
    assert len(paths) == 4
    for p, q in combinations(paths, 2):
        assert np.linalg.norm(p - q, axis=1).min() > 5.0
    for p in paths:
        # In from 130 m to 60 m at 10 m/s, across at 8 m/s, out again: about 20 s in reach.
        assert np.count_nonzero(np.linalg.norm(p[:, :2], axis=1) < REACH_M) * 0.05 > 15.0
        assert np.all(np.abs(_bearing(p)) < 90.0)


def test_the_named_scenarios_with_several_drones_are_phantom4s_on_the_acquisition_rig() -> None:
    for name, count in (("outdoor-two-drones", 2), ("outdoor-swarm", 4)):
        cfg: ScenarioConfig = SCENARIOS[name]
        assert 1 + len(cfg.targets) == count
        assert {t.model for t in cfg.targets} == {cfg.drone.model} == {"phantom4"}
        # the acquisition rig's pipeline, the turret shared among the drones
        assert cfg.pipeline.choose.enabled
        rig = SCENARIOS["outdoor-incoming"].pipeline
        assert cfg.pipeline.model_copy(update={"choose": rig.choose}) == rig
        assert all(t.start_s < cfg.duration_s for t in cfg.targets)
        assert math.isinf(cfg.weather.visibility_m)
