"""``dronetrack bench``: bench.json's structure on a quick run, the targets, bad input.

Speed is reported by the bench, never asserted here: the quick run only checks
that every measurement is there and sane.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.errors import ConfigError
from dronetrack.experiments.bench import (
    PF_PARTICLES,
    SENSORS,
    STAT_KEYS,
    TARGETS,
    bench,
    best_round,
    evaluate_targets,
    heavy_repeats,
    single_thread,
    thread_counts,
)
from dronetrack.pipeline.trackers import TRACKER_NAMES


def _positive(value: Any) -> bool:
    return isinstance(value, int | float) and math.isfinite(value) and value > 0


def _check_stats(row: dict[str, float], where: str) -> None:
    assert set(STAT_KEYS) <= set(row), where
    for key in ("median", "mean", "max"):
        assert _positive(row[key]), (where, key, row[key])
    assert math.isfinite(row["std"]), where
    assert row["std"] >= 0, where
    assert row["median"] <= row["max"], where
    assert row["mean"] <= row["max"], where


@pytest.mark.slow
def test_quick_bench_writes_every_measurement(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(["bench", "--quick", "--out", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    path = tmp_path / "bench.json"
    assert out.strip().splitlines()[-1] == str(path)
    data = json.loads(path.read_text())

    assert list(data["pf_step_ms"]) == [str(n) for n in PF_PARTICLES]
    assert list(data["pf_step_ms"]) == ["1000", "4000", "5000", "10000", "100000"]
    for n, row in data["pf_step_ms"].items():
        _check_stats(row, f"pf_step_ms {n}")
    multi = data["multi_step_ms"]
    _check_stats(multi, "multi_step_ms")
    assert multi["median"] <= multi["p99"] <= multi["max"]
    assert multi["tracks"] >= 10  # the workload is the issue's: 10 tracks, 50 candidates
    assert multi["clusters"] >= 50
    lm = data["learning_map"]
    assert lm["seconds"] == 20.0
    assert 0 < lm["final_mb"] <= lm["peak_mb"] < lm["rss_peak_mb"]
    assert 0 < lm["learnt_peak"] <= lm["voxels_peak"]  # the map learnt the world it swept
    assert set(data["tracker_step_ms"]) == set(TRACKER_NAMES)
    for kind, row in data["tracker_step_ms"].items():
        _check_stats(row, f"tracker_step_ms {kind}")
    assert set(data["sim_frame_ms"]) == set(SENSORS) == {"avia", "mid40", "mid360", "vlp16"}
    assert all(_positive(v) for v in data["sim_frame_ms"].values())
    assert _positive(data["replay_x_realtime"])
    formats = data["replay_formats"]
    assert len(formats) == 2
    assert data["replay_x_realtime"] == min(f["x_realtime"] for f in formats.values())

    machine = data["machine"]
    for key in ("cpu", "cores", "python", "numpy", "platform"):
        assert machine[key], key
    assert machine["cores"] >= 1
    assert machine["threads"]["numba"] == 1  # measured inside the single-thread block
    assert all(pool["threads"] == 1 for pool in machine["threads"]["blas"])

    targets = data["targets"]
    assert set(targets) == {t.key for t in TARGETS}
    assert set(targets) == {
        "pf_step_ms.5000.median",
        "pf_step_ms.100000.median",
        "sim_frame_ms.avia",
        "multi_step_ms.p99",
        "learning_map.peak_mb",
    }
    assert targets["learning_map.peak_mb"]["value"] == lm["peak_mb"]
    assert targets["multi_step_ms.p99"]["value"] == multi["p99"]
    assert targets["pf_step_ms.5000.median"]["value"] == data["pf_step_ms"]["5000"]["median"]
    assert targets["sim_frame_ms.avia"]["value"] == data["sim_frame_ms"]["avia"]
    for target in targets.values():
        assert target["met"] == (target["value"] <= target["limit"])
    # The table names the machine and marks every target (its title wraps at the
    # terminal's width, so compare with the line breaks taken out).
    flat = " ".join(out.split())
    assert " ".join(machine["cpu"].split()) in flat
    assert f"numpy {machine['numpy']}" in flat
    assert out.count("met") + out.count("MISSED") >= len(TARGETS)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--rounds", "0"], "--rounds"),
        (["--repeats", "0"], "--repeats"),
        (["--rounds", "many"], "--rounds"),
        (["--replay-seconds", "1", "--quick"], "at least 8 s"),
    ],
)
def test_bad_input_exits_2_with_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert run(["bench", "--out", str(tmp_path), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:")
    assert message in err
    assert "\n" not in err
    assert not (tmp_path / "bench.json").exists()


def test_bench_refuses_bad_settings() -> None:
    with pytest.raises(ConfigError, match="at least 1"):
        bench(rounds=0)
    with pytest.raises(ConfigError, match="at least 8 s"):
        bench(quick=True, replay_s=float("nan"))


def test_targets_are_met_at_their_limits_and_missed_above() -> None:
    results = {
        "pf_step_ms": {"5000": {"median": 2.0}, "100000": {"median": 50.5}},
        "sim_frame_ms": {"avia": 9.0},
        "multi_step_ms": {"p99": 10.0},
        "learning_map": {"peak_mb": 200.5},
    }
    verdicts = {k: v["met"] for k, v in evaluate_targets(results).items()}
    assert verdicts == {
        "pf_step_ms.5000.median": True,
        "pf_step_ms.100000.median": False,
        "sim_frame_ms.avia": True,
        "multi_step_ms.p99": True,
        "learning_map.peak_mb": False,
    }


def test_best_round_keeps_the_lowest_median() -> None:
    rounds = iter([np.array([3.0, 3.0, 9.0]), np.array([1.0, 2.0, 50.0]), np.array([4.0])])
    np.testing.assert_array_equal(best_round(lambda: next(rounds), 3), [1.0, 2.0, 50.0])


def test_heavy_repeats() -> None:
    assert heavy_repeats(200) == 40
    assert heavy_repeats(50) == 20
    assert heavy_repeats(5) == 5


def test_single_thread_restores_the_thread_counts() -> None:
    before = thread_counts()
    with single_thread():
        inside = thread_counts()
        assert inside["numba"] == 1
        assert inside["blas"]  # numpy's own BLAS at least
        assert all(pool["threads"] == 1 for pool in inside["blas"])
    assert thread_counts() == before
