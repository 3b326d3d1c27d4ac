"""Every file in ``examples/`` runs as its comments say."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.config.run import load_scenario_file
from dronetrack.config.scenarios import SCENARIOS
from dronetrack.experiments.sweep.grid import expand, load_grid
from dronetrack.sim.trajectories import load_csv_trajectory

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _metrics(folder: Path) -> dict[str, object]:
    data: dict[str, object] = json.loads((folder / "metrics.json").read_text())
    return data


def test_the_trajectory_is_a_flight_a_drone_can_fly() -> None:
    path = load_csv_trajectory(EXAMPLES / "trajectory.csv")
    t = np.linspace(path.start, path.end, 601)
    speed = np.linalg.norm(path.velocity(t), axis=1)
    assert path.end - path.start == pytest.approx(60.0)
    assert speed.max() < 12.0  # a Phantom 4 tops out at 20 m/s
    assert path.position(path.start)[0][2] == pytest.approx(0.0)  # takes off from the ground
    assert np.linalg.norm(path.position(t)[:, :2], axis=1).max() > 100.0  # out beyond 100 m


def test_the_scenario_runs_the_trajectory(tmp_path: Path) -> None:
    cfg = load_scenario_file(EXAMPLES / "scenario.toml", SCENARIOS)
    assert cfg.trajectory.file is not None
    assert Path(cfg.trajectory.file).name == "trajectory.csv"
    out = tmp_path / "run"
    args = ["simulate", str(EXAMPLES / "scenario.toml"), "--duration", "8", "--out", str(out)]
    assert run(args) == 0
    m = _metrics(out)
    assert m["frames"] == 80
    # Measured (seed 7): 72 % of the first 8 s, locked 2.4 s after the scan, while
    # the drone climbs out of the ground's background cells.
    assert float(m["coverage_pct"]) >= 50.0  # type: ignore[arg-type]
    assert "example-circle" in (out / "config.toml").read_text()


def test_the_trajectory_replaces_a_scenarios_flight(tmp_path: Path) -> None:
    out = tmp_path / "run"
    trajectory = str(EXAMPLES / "trajectory.csv")
    args = ["simulate", "--trajectory", trajectory, "--duration", "3", "--out", str(out)]
    assert run(args) == 0
    assert _metrics(out)["frames"] == 30


@pytest.mark.slow
def test_the_site_configuration_replays_a_recording(tmp_path: Path) -> None:
    bag = tmp_path / "flight.bag"
    assert run(["record", "--duration", "4", "--out", str(bag)]) == 0
    out = tmp_path / "track"
    args = ["track", str(bag), "--config", str(EXAMPLES / "site.toml"), "--out", str(out)]
    assert run(args) == 0
    assert "site-example" in (out / "config.toml").read_text()
    m = _metrics(out)
    assert m["frames"] == 40
    assert "coverage_pct" in m  # the recording's ground truth is scored


def test_the_site_configuration_simulates_too(tmp_path: Path) -> None:
    out = tmp_path / "sim"
    args = ["simulate", "--config", str(EXAMPLES / "site.toml"), "--duration", "2"]
    assert run([*args, "--out", str(out)]) == 0
    assert _metrics(out)["frames"] == 20


@pytest.mark.parametrize("name", ["grid_small.toml", "grid_eq12.toml"])
def test_each_grid_runs_as_many_runs_as_its_comment_says(name: str) -> None:
    path = EXAMPLES / name
    spec = load_grid(path)
    comment = " ".join(
        line.lstrip("# ") for line in path.read_text().splitlines() if line.startswith("#")
    )
    stated = re.search(r"= ([0-9,]+) (?:runs|combinations)", comment)
    assert stated is not None, comment
    runs = len(expand(spec))
    count = int(stated.group(1).replace(",", ""))
    if "combinations" in stated.group(0):
        assert count == runs // spec.runs
    else:
        assert count == runs


@pytest.mark.slow
def test_the_three_drones_scenario_adds_two_drones_as_its_comments_say(tmp_path: Path) -> None:
    path = EXAMPLES / "three_drones.toml"
    cfg = load_scenario_file(path, SCENARIOS)
    assert [(t.model, t.start_s) for t in cfg.targets] == [("f550", 5.0), ("phantom4", 20.0)]
    assert Path(cfg.targets[1].file or "").name == "trajectory.csv"
    out = tmp_path / "render"
    assert run(["render", str(path), "--duration", "30", "--out", str(out)]) == 0
    with np.load(out / "frames.npz") as npz:
        data = dict(npz)
    assert data["object_kinds"].tolist() == ["drone"] * 3
    end, present, position = data["frame_end"], data["object_present"], data["object_positions"]
    assert present[:, 0].all()
    np.testing.assert_array_equal(present[:, 1], end >= 5.0 - 1e-9)
    np.testing.assert_array_equal(present[:, 2], end >= 20.0 - 1e-9)
    # The F550's manoeuvres stay in their 16 m box 15 m out.
    assert np.all(np.abs(position[present[:, 1], 1, 0] - 15.0) <= 8.5)
    # The second Phantom 4 flies the target's path 20 s (200 frames) behind it.
    np.testing.assert_allclose(position[200:, 2], position[:-200, 0], atol=1e-9)
    # simulate runs it too, for a flight long enough to see the last drone enter.
    sim = tmp_path / "sim"
    assert run(["simulate", str(path), "--duration", "25", "--out", str(sim)]) == 0
    assert _metrics(sim)["frames"] == 250
    assert (sim / "config.toml").read_text().count("[[targets]]") == 2
