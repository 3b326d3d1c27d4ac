"""``dronetrack simulate``: outputs, reproduction from config.toml, bad input."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.eval.log import FRAME_COLUMNS
from dronetrack.eval.tracks import TRACK_COLUMNS
from dronetrack.types import TRACK_CLASSES

METRIC_KEYS = {
    "coverage_pct",
    "max_tracking_distance_m",
    "rmse_m",
    "rmse_ci95_m",
    "rmse_xyz_m",
    "frames",
    "step_ms_mean",
    "step_ms_std",
    "step_ms_max",
}


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_outputs_and_exact_reproduction(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    first = tmp_path / "first"
    assert (
        run(
            [
                "simulate",
                "indoor-vertical",
                "--duration",
                "4",
                "--particles",
                "1000",
                "--seed",
                "3",
                "--out",
                str(first),
            ]
        )
        == 0
    )
    assert "coverage" in capsys.readouterr().out
    for name in (
        "config.toml",
        "frames.csv",
        "metrics.json",
        "top_view.png",
        "error_sigma.png",
        "points_vs_distance.png",
    ):
        assert (first / name).stat().st_size > 0
    header = (first / "frames.csv").read_text().splitlines()[0].split(",")
    assert tuple(header[: len(FRAME_COLUMNS)]) == FRAME_COLUMNS
    header = (first / "tracks.csv").read_text().splitlines()[0].split(",")
    assert tuple(header[: len(TRACK_COLUMNS)]) == TRACK_COLUMNS
    tracks = _rows(first / "tracks.csv")
    assert tracks  # the hovering Crazyflie is a track
    frame_times = {r["t"] for r in _rows(first / "frames.csv")}
    for r in tracks:
        assert r["t"] in frame_times
        assert int(r["id"]) >= 1
        assert r["class"] in TRACK_CLASSES
        assert 0.0 <= float(r["p_drone"]) <= 1.0
        assert r["locked"] in ("0", "1")
    # at most one locked track a frame
    locked = [r["t"] for r in tracks if r["locked"] == "1"]
    assert len(locked) == len(set(locked))
    # a track is born on a cluster it sees: its first row is updated and in view
    first_rows: dict[str, dict[str, str]] = {}
    for r in tracks:
        assert r["updated"] in ("0", "1")
        assert r["in_view"] in ("0", "1")
        first_rows.setdefault(r["id"], r)
    assert all(r["updated"] == r["in_view"] == "1" for r in first_rows.values())
    # the hovering Crazyflie in front of the sensor is seen in most frames of its track
    held = [r for r in tracks if r["locked"] == "1"]
    assert sum(r["updated"] == "1" for r in held) > 0.8 * len(held)
    metrics = json.loads((first / "metrics.json").read_text())
    assert set(metrics) >= METRIC_KEYS
    assert metrics["frames"] == 40
    config = (first / "config.toml").read_text()
    assert "seed = 3" in config
    assert "particles = 1000" in config
    assert "sigma_pos = 0.04" in config  # eq. (11), written out
    # Re-running the written configuration gives the same run (compute time aside).
    second = tmp_path / "second"
    assert run(["simulate", "--config", str(first / "config.toml"), "--out", str(second)]) == 0
    assert _rows(second / "tracks.csv") == tracks
    a, b = _rows(first / "frames.csv"), _rows(second / "frames.csv")
    assert len(a) == len(b) == 40
    for ra, rb in zip(a, b, strict=True):
        ra.pop("step_ms")
        rb.pop("step_ms")
        assert ra == rb
    # A saved background replaces the scan: tracking starts at once.
    toml = first / "reuse.toml"  # next to the map: a relative path names it
    toml.write_text('base = "indoor-vertical"\n[pipeline.background]\nfile = "background.npz"\n')
    third = tmp_path / "third"
    assert run(["simulate", str(toml), "--duration", "4", "--out", str(third)]) == 0
    rows = _rows(third / "frames.csv")
    assert float(rows[0]["t"]) == pytest.approx(0.1)
    assert not (third / "background.npz").exists()
    # Its config.toml names the map by absolute path with the map's own settings, so
    # it reproduces the run from anywhere.
    written = (third / "config.toml").read_text()
    assert f'file = "{(first / "background.npz").resolve()}"' in written
    monkeypatch.chdir(tmp_path)  # where a relative "background.npz" would not exist
    fourth = tmp_path / "fourth"
    assert run(["simulate", "--config", str(third / "config.toml"), "--out", str(fourth)]) == 0
    for ra, rb in zip(rows, _rows(fourth / "frames.csv"), strict=True):
        ra.pop("step_ms")
        rb.pop("step_ms")
        assert ra == rb


def test_no_arguments_runs_the_default_scenario(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    assert run(["simulate"]) == 0
    runs = list((tmp_path / "runs").iterdir())
    assert len(runs) == 1
    metrics = json.loads((runs[0] / "metrics.json").read_text())
    assert metrics["frames"] == 660
    assert 'name = "default"' in (runs[0] / "config.toml").read_text()
    table = np.genfromtxt(
        runs[0] / "frames.csv", delimiter=",", names=True, dtype=None, encoding=None
    )
    assert table["range_m"].max() > 135.0  # seed 000's horizontal fast flight, out to ~140 m


def _fail(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert run(args) == 2
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err
    assert err.startswith("error:")
    assert "\n" not in err
    return err


def test_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad_csv = tmp_path / "t.csv"
    bad_csv.write_text("t,x,y,z\n0,0,0,0\n0,1,1,1\n")
    err = _fail(["simulate", "--trajectory", str(bad_csv), "--out", str(tmp_path / "o")], capsys)
    assert "strictly increase" in err
    bad_toml = tmp_path / "c.toml"
    bad_toml.write_text('base = "default"\n[pipeline.tracker]\nparticels = 10\n')
    err = _fail(["simulate", "--config", str(bad_toml), "--out", str(tmp_path / "o")], capsys)
    assert "unknown key 'pipeline.tracker.particels'" in err
    err = _fail(["simulate", "--config", str(tmp_path / "missing.toml")], capsys)
    assert "not found" in err
    err = _fail(["simulate", "default", "--config", str(bad_toml)], capsys)
    assert "not both" in err
    err = _fail(["simulate", "--tracker", "ekf"], capsys)
    assert "ekf" in err
