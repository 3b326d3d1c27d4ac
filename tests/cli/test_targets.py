"""Several drones from the command line: the named scenarios run end to end, a run with
``[[targets]]`` re-runs from its config.toml, ``--trajectory`` repeats, bad entries get
one error line."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run

METRIC_KEYS = {"coverage_pct", "rmse_m", "frames", "lock_on_visible_pct", "false_lock_pct"}


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def _line(path: Path, y: float) -> Path:
    """A 4 s straight flight 20-28 m out, ``y`` to the left, 10-12 m up."""
    t = np.linspace(0.0, 4.0, 9)
    xyz = np.column_stack([20 + 2 * t, np.full_like(t, y), 10 + 0.5 * t])
    np.savetxt(path, np.column_stack([t, xyz]), delimiter=",", header="t,x,y,z", comments="")
    return path


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
    a, b = _rows(first / "frames.csv"), _rows(second / "frames.csv")
    assert len(a) == len(b) == 200
    for ra, rb in zip(a, b, strict=True):
        ra.pop("step_ms")
        rb.pop("step_ms")
        assert ra == rb


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


def _one_error(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert run(args) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return lines[0]


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        ('model = "x-wing"\nflight = "aggressive"\n', "targets.0: unknown drone 'x-wing'"),
        ('file = "missing.csv"\n', "targets.0: trajectory CSV not found"),
        ('file = "bad.csv"\n', "targets.0: trajectory CSV"),
        ('flight = "aggressive"\nstart_s = 8.0\n', "targets.0.start_s = 8 s is not before"),
        ('flight = "aggressive"\nstart_s = 9.0\n', "targets.0.start_s = 9 s is not before"),
        ('flight = "aggressive"\nstart_s = -0.5\n', "targets.0.start_s"),
    ],
)
def test_a_bad_target_entry_is_one_error_line(
    entry: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "bad.csv").write_text("t,x,y,z\n0,0,0,0\n0,1,1,1\n")
    path = tmp_path / "s.toml"
    path.write_text(f'base = "default"\nduration_s = 8.0\n[[targets]]\n{entry}')
    line = _one_error(["simulate", str(path), "--out", str(tmp_path / "o")], capsys)
    assert message in line
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("command", ["simulate", "render", "record"])
def test_a_further_trajectory_that_cannot_be_read_is_one_error_line(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    good = _line(tmp_path / "a.csv", 0.0)
    missing = tmp_path / "nowhere.csv"
    out = tmp_path / ("o.bag" if command == "record" else "o")
    args = [command, "default", "--trajectory", str(good), "--trajectory", str(missing)]
    line = _one_error([*args, "--duration", "1", "--out", str(out)], capsys)
    assert f"targets.0: trajectory CSV not found: {missing}" in line


def test_a_run_shorter_than_a_targets_start_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "s.toml"
    path.write_text('base = "default"\n[[targets]]\nflight = "aggressive"\nstart_s = 30.0\n')
    line = _one_error(["simulate", str(path), "--duration", "10"], capsys)
    assert "targets.0.start_s = 30 s is not before the run ends (duration_s = 10 s)" in line
