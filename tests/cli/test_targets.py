"""Several drones from the command line: the named scenarios run end to end, a run with
``[[targets]]`` re-runs from its config.toml, ``--trajectory`` repeats (bad entries:
``test_errors.py``)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run

METRIC_KEYS = {"coverage_pct", "rmse_m", "frames", "lock_on_visible_pct", "false_lock_pct"}


def _rows(path: Path) -> list[dict[str, str]]:
    """frames.csv's rows without the compute time, which differs from run to run."""
    with path.open() as fh:
        return [{k: v for k, v in row.items() if k != "step_ms"} for row in csv.DictReader(fh)]


def _line(path: Path, y: float) -> Path:
    """A 4 s straight flight 20-28 m out, ``y`` to the left, 10-12 m up."""
    t = np.linspace(0.0, 4.0, 9)
    xyz = np.column_stack([20 + 2 * t, np.full_like(t, y), 10 + 0.5 * t])
    np.savetxt(path, np.column_stack([t, xyz]), delimiter=",", header="t,x,y,z", comments="")
    return path


@pytest.mark.slow
def test_two_drones_run_end_to_end_and_rerun_from_their_config(tmp_path: Path) -> None:
    first = tmp_path / "first"
    args = ["simulate", "outdoor-two-drones", "--duration", "20", "--out", str(first)]
    assert run(args) == 0
    metrics = json.loads((first / "metrics.json").read_text())
    assert set(metrics) >= METRIC_KEYS
    assert metrics["frames"] == 200
    config = (first / "config.toml").read_text()
    assert config.count("[[targets]]") == 1
    assert 'flight = "crossing-right"' in config
    second = tmp_path / "second"
    assert run(["simulate", "--config", str(first / "config.toml"), "--out", str(second)]) == 0
    a, b = (_rows(run_dir / "frames.csv") for run_dir in (first, second))
    assert len(a) == 200
    assert a == b


def test_render_adds_a_drone_for_each_further_trajectory(tmp_path: Path) -> None:
    a, b = _line(tmp_path / "a.csv", -2.0), _line(tmp_path / "b.csv", 2.0)
    out = tmp_path / "render"
    args = ["render", "default", "--duration", "1", "--trajectory", str(a)]
    assert run([*args, "--trajectory", str(b), "--drone", "f550", "--out", str(out)]) == 0
    with np.load(out / "frames.npz") as npz:
        data = dict(npz)
    assert data["object_kinds"].tolist() == ["drone", "drone"]
    assert data["object_present"].all()
    np.testing.assert_allclose(data["object_positions"][0, :, 1], [-2.0, 2.0], atol=0.1)
    # Both 20 m ahead within the Avia's view: both return, each marked as its own.
    index = data["object_index"]
    assert np.count_nonzero(index == 0) > 0
    assert np.count_nonzero(index == 1) > 0
    np.testing.assert_array_equal(data["hit_target"], index == 0)
    scenario = (out / "scenario.toml").read_text()
    assert scenario.count("[[targets]]") == 1
    assert 'model = "f550"' in scenario.split("[[targets]]")[1]
