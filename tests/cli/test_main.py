"""The command line: contracts (names, columns, files) and bad input (one line, exit code 2)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.config.scenarios import SCENARIOS


def test_scenarios_lists_one_name_per_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert run(["scenarios"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines == list(SCENARIOS)
    assert "default" in lines


@pytest.mark.parametrize("sensor", ["avia", "mid40", "mid360", "vlp16"])
def test_pattern_writes_the_directions(tmp_path: Path, sensor: str) -> None:
    out = tmp_path / f"{sensor}.csv"
    assert run(["pattern", sensor, "--duration", "0.05", "--out", str(out)]) == 0
    header = out.read_text().splitlines()[0]
    assert header == "t_s,azimuth_deg,elevation_deg,line"
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    assert np.all(np.diff(table[:, 0]) > 0)
    assert np.all(np.abs(table[:, 2]) <= 90)
    assert table[:, 0].max() < 0.05


def test_pattern_replays_a_livox_csv(tmp_path: Path) -> None:
    src = tmp_path / "mid360.csv"
    src.write_text("Time/s,Azimuth/deg,Zenith/deg\n1,10,80\n2,20,95\n")
    out = tmp_path / "out.csv"
    assert run(["pattern", f"file:{src}", "--duration", "1", "--rate", "4", "--out", str(out)]) == 0
    table = np.loadtxt(out, delimiter=",", skiprows=1)
    np.testing.assert_allclose(table[:, 1], [10, 20, 10, 20])
    np.testing.assert_allclose(table[:, 2], [10, -5, 10, -5], atol=1e-9)


def test_render_writes_frames_truth_and_preview(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert run(["render", "indoor-horizontal", "--duration", "0.3", "--out", str(out)]) == 0
    for name in ("frames.npz", "frames.csv", "scenario.toml", "preview.png"):
        assert (out / name).stat().st_size > 0
    data = np.load(out / "frames.npz")
    for key in ("x", "y", "z", "t", "line", "hit_target", "frame", "target_position", "poses"):
        assert key in data
    assert data["target_position"].shape == (3, 3)
    assert len(data["x"]) == len(data["hit_target"]) == len(data["frame"])
    header = (out / "frames.csv").read_text().splitlines()[0].split(",")
    assert header[:5] == ["frame", "t_start", "t_end", "n_points", "n_target_points"]


def _fail(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert run(args) == 2
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    return err


def test_unknown_names_fail_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    err = _fail(["pattern", "hdl64", "--out", str(tmp_path / "x.csv")], capsys)
    assert err.startswith("error: unknown sensor 'hdl64'")
    assert "\n" not in err
    err = _fail(["render", "nowhere", "--out", str(tmp_path / "x")], capsys)
    assert err.startswith("error: unknown scenario 'nowhere'")
    assert "\n" not in err


@pytest.mark.parametrize(
    ("csv", "message"),
    [
        ("t,x,y\n0,0,0\n1,1,1\n", "missing column(s): z"),
        ("t,x,y,z\n1,0,0,0\n0.5,1,1,1\n", "must strictly increase"),
        ("t,x,y,z\n0,0,0,0\n1,nan,1,1\n", "NaN"),
    ],
)
def test_malformed_trajectory_csv(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], csv: str, message: str
) -> None:
    path = tmp_path / "traj.csv"
    path.write_text(csv)
    err = _fail(
        ["render", "default", "--trajectory", str(path), "--out", str(tmp_path / "o")], capsys
    )
    assert message in err
    assert "\n" not in err


def test_toml_with_unknown_key(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "s.toml"
    path.write_text('base = "default"\n[turret]\nspeed = 3\n')
    err = _fail(["render", str(path), "--out", str(tmp_path / "o")], capsys)
    assert "unknown key 'turret.speed'" in err
    assert "\n" not in err


def test_render_keeps_the_scenario_settings_it_was_not_told_to_change(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    toml = tmp_path / "quiet.toml"
    toml.write_text('base = "indoor-vertical"\nduration_s = 2.0\n[sensor]\nnoise = false\n')
    out = tmp_path / "run"
    assert run(["render", str(toml), "--duration", "0.25", "--out", str(out)]) == 0
    written = (out / "scenario.toml").read_text()
    assert "noise = false" in written
    assert "duration_s = 0.25" in written
    # 0.25 s of 0.1 s frames: three frames, the last one partial.
    assert len((out / "frames.csv").read_text().splitlines()) == 1 + 3
    # Noise off: no false alarms, every return on a surface of the room or the drone.
    data = np.load(out / "frames.npz")
    assert np.all(np.linalg.norm(data["world"][:, :2], axis=1) < 12.0)
    # The written scenario renders the same frames again.
    again = tmp_path / "again"
    assert run(["render", str(out / "scenario.toml"), "--out", str(again)]) == 0
    np.testing.assert_array_equal(np.load(again / "frames.npz")["x"], data["x"])


def test_render_of_an_empty_view(tmp_path: Path) -> None:
    toml = tmp_path / "nothing.toml"
    toml.write_text(
        'base = "default"\n[scene]\nname = "sky"\n[sensor]\nnoise = false\n'
        "[turret]\npan_deg = 180.0\n"
    )
    out = tmp_path / "run"
    assert (
        run(["render", str(toml), "--turret", "fixed", "--duration", "0.2", "--out", str(out)]) == 0
    )
    assert (out / "preview.png").stat().st_size > 0


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["render", "default", "--seed", "-3"], "--seed"),
        (["render", "default", "--duration", "inf"], "duration_s"),
        (["render", "default", "--visibility", "-5"], "visibility_m"),
        (["render"], "Missing argument"),
        (["pattern", "avia", "--bogus"], "No such option"),
    ],
)
def test_bad_numbers_and_usage(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    err = _fail(
        [*args, "--out", str(tmp_path / "o")] if args[0] == "render" and len(args) > 1 else args,
        capsys,
    )
    assert err.startswith("error:")
    assert message in err
    assert "\n" not in err


@pytest.mark.slow
def test_console_script_exit_code_and_no_traceback(tmp_path: Path) -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "dronetrack", "pattern", "nosuch", "--out", str(tmp_path / "x.csv")],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 2
    expected = (
        "error: unknown sensor 'nosuch'; "
        "choose one of avia, mid40, mid360, vlp16, vlp16-side, file:PATH"
    )
    assert proc.stderr.strip().splitlines() == [expected]
    usage = subprocess.run(
        [sys.executable, "-m", "dronetrack", "render"], capture_output=True, text=True, check=False
    )
    assert usage.returncode == 2
    assert "Traceback" not in usage.stderr
