"""Bad input a new user gives: one ``error:`` line that names the problem, exit code 2.

Each case here was a traceback, a confusing message or a silent empty result once.
"""

from __future__ import annotations

import re
import zipfile
from pathlib import Path
from typing import get_args

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.config.pipeline import TrackerKind

LATIN1_DEGREE = b"\xb0"  # "°" in Latin-1: not UTF-8


def _one_error(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Run ``args``; check exit code 2 and a single ``error:`` line; return it."""
    assert run(args) == 2
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("error: "), err
    assert "Traceback" not in err
    return lines[0]


def _latin1(path: Path, text_before: str, text_after: str) -> tuple[Path, int]:
    """A TOML file with a Latin-1 degree sign in a comment; and that byte's offset."""
    head = text_before.encode()
    path.write_bytes(head + b"# 20" + LATIN1_DEGREE + b" C\n" + text_after.encode())
    return path, len(head) + 4


@pytest.mark.parametrize("how", ["scenario", "config", "grid"])
def test_a_toml_file_that_is_not_utf8_names_the_file_and_the_byte(
    how: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    if how == "grid":
        path, offset = _latin1(
            tmp_path / "grid.toml", 'scenario = "default"\n', "[grid]\nparticles = [100]\n"
        )
        args = ["sweep", str(path), "--out", str(tmp_path / "out")]
    else:
        path, offset = _latin1(tmp_path / "s.toml", 'base = "default"\n', "seed = 3\n")
        args = ["simulate", str(path)] if how == "scenario" else ["simulate", "--config", str(path)]
    line = _one_error(args, capsys)
    assert str(path) in line
    assert f"byte offset {offset}" in line
    assert "0xb0" in line
    assert "UTF-8" in line


@pytest.mark.parametrize("option", ["--rerun", "--foxglove"])
def test_a_viewer_file_that_cannot_be_written_names_its_path(
    option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    target = blocker / "view.out"  # its "folder" is a file
    line = _one_error(
        ["simulate", "--duration", "1", option, str(target), "--out", str(tmp_path / "r")],
        capsys,
    )
    assert option in line
    assert str(target) in line
    assert not (tmp_path / "r").exists()  # refused before the run


def test_a_viewer_file_in_an_unwritable_place_names_its_path(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # /proc refuses new files even to root, which ignores folder permissions.
    target = Path("/proc/dronetrack-test/view.rrd")
    line = _one_error(
        ["simulate", "--duration", "1", "--rerun", str(target), "--out", str(tmp_path / "r")],
        capsys,
    )
    assert str(target) in line


@pytest.mark.parametrize(
    "command",
    [
        ["simulate", "--duration", "1"],
        ["render", "default", "--duration", "1"],
        ["compare", "--suite", "seed002", "--runs", "1", "--duration", "1"],
        ["bench", "--quick"],
        ["sweep", "GRID"],
        ["track", "BAG"],
    ],
)
def test_out_pointing_at_a_file_is_refused_in_words(
    command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    grid = tmp_path / "grid.toml"
    grid.write_text('scenario = "default"\n[grid]\nparticles = [100]\n')
    bag = tmp_path / "flight.bag"
    bag.write_bytes(b"")  # refused for --out before it is read
    args = [str(grid) if a == "GRID" else str(bag) if a == "BAG" else a for a in command]
    out = tmp_path / "results.txt"
    out.write_text("keep me")
    line = _one_error([*args, "--out", str(out)], capsys)
    assert str(out) in line
    assert "is a file" in line
    assert "Errno" not in line
    assert out.read_text() == "keep me"


def test_out_below_a_file_is_refused_in_words(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    line = _one_error(["simulate", "--duration", "1", "--out", str(blocker / "run")], capsys)
    assert f"{blocker} is a file" in line


@pytest.fixture(scope="module")
def short_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A recorded 13 s flight: 10 s of background scan and 3 s of tracking."""
    path = tmp_path_factory.mktemp("bag") / "flight.bag"
    assert run(["record", "--duration", "3", "--out", str(path)]) == 0
    return path


def _background_file(kind: str, path: Path) -> Path:
    if kind == "text":
        path.write_text("not a background model\n")
    elif kind == "pickle":
        np.save(path.with_suffix(".npy"), np.array([{"a": 1}], dtype=object), allow_pickle=True)
        path.with_suffix(".npy").rename(path)
    elif kind == "objects":
        np.savez(path, cells=np.array([{"a": 1}], dtype=object))
    elif kind == "other-npz":
        np.savez(path, values=np.arange(3))
    elif kind == "truncated":
        np.savez(path, format=np.array("x"), cells=np.arange(1000))
        path.write_bytes(path.read_bytes()[:100])
    return path


@pytest.mark.parametrize("kind", ["text", "pickle", "objects", "other-npz", "truncated"])
def test_a_bad_background_file_gets_words_not_numpy_advice(
    kind: str, short_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = _background_file(kind, tmp_path / "bg.npz")
    line = _one_error(
        ["track", str(short_bag), "--background", str(bad), "--out", str(tmp_path / "r")], capsys
    )
    assert str(bad) in line
    assert "allow_pickle" not in line
    assert "pickle.load" not in line
    if kind != "truncated":
        assert "background.npz" in line  # the hint: what to give instead


def test_the_background_a_run_wrote_loads(short_bag: Path, tmp_path: Path) -> None:
    first = tmp_path / "first"
    assert run(["track", str(short_bag), "--out", str(first)]) == 0
    with zipfile.ZipFile(first / "background.npz") as archive:
        assert "cells.npy" in archive.namelist()
    again = tmp_path / "again"
    background = str(first / "background.npz")
    assert run(["track", str(short_bag), "--background", background, "--out", str(again)]) == 0


def test_a_recording_no_longer_than_its_scan_is_refused(
    short_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "r"
    line = _one_error(
        ["track", str(short_bag), "--background-from", "1000", "--out", str(out)], capsys
    )
    length = re.search(r"lasts ([0-9.]+) s", line)
    assert length is not None, line
    assert 12.5 <= float(length.group(1)) <= 13.5  # the bag's 13 s
    assert "background scan of 1000 s" in line
    assert not out.exists()  # no empty run folder left behind


def test_pattern_refuses_a_zero_duration(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "p.csv"
    line = _one_error(["pattern", "avia", "--duration", "0", "--out", str(out)], capsys)
    assert "--duration" in line
    assert not out.exists()


def test_bare_dronetrack_prints_help_and_no_error(capsys: pytest.CaptureFixture[str]) -> None:
    assert run([]) == 0
    captured = capsys.readouterr()
    assert "simulate" in captured.out
    assert "error" not in captured.err


@pytest.mark.parametrize("command", [[], ["simulate"], ["track"], ["sweep"], ["record"]])
def test_dash_h_is_help(command: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert run([*command, "-h"]) == 0
    assert "Usage" in capsys.readouterr().out


def _help(command: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert run([*command, "--help"]) == 0
    # Rich wraps the help in a box: join the cells of each option's rows.
    return " ".join(line.strip("│ ").strip() for line in capsys.readouterr().out.splitlines())


def test_help_states_the_particle_cap(capsys: pytest.CaptureFixture[str]) -> None:
    for command in (["simulate"], ["record"]):
        text = _help(command, capsys)
        assert "2,000,000" in text
    assert run(["simulate", "--particles", "2000001", "--duration", "1"]) == 2
    assert "2000000" in capsys.readouterr().err


def test_record_marks_out_as_required(capsys: pytest.CaptureFixture[str]) -> None:
    text = _help(["record"], capsys)
    assert "[required]" in text
    assert run(["record", "--duration", "1"]) == 2
    err = capsys.readouterr().err
    assert "--out" in err
    assert "Missing option" in err


def test_both_durations_say_whether_a_scan_comes_first(
    capsys: pytest.CaptureFixture[str],
) -> None:
    simulate = _help(["simulate"], capsys)
    render = _help(["render"], capsys)
    assert "after the background scan" in re.sub(r"\s+", " ", simulate)
    assert "no background scan comes first" in re.sub(r"\s+", " ", render)


@pytest.mark.parametrize("command", [["simulate"], ["record"], ["track", "flight.bag"]])
def test_tracker_names_are_the_configs_list(
    command: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """--tracker takes exactly config.pipeline.TrackerKind: an unknown name is one line
    that lists them all (and a known one reaches the command, which is tested elsewhere)."""
    line = _one_error([*command, "--tracker", "pf-nosuch", "--out", str(tmp_path / "o")], capsys)
    assert "--tracker" in line
    offered = line.split("is not one of", 1)[1]
    assert tuple(re.findall(r"'([^']+)'", offered)) == get_args(TrackerKind)
    assert not (tmp_path / "o").exists()


def test_compare_help_names_every_suite(capsys: pytest.CaptureFixture[str]) -> None:
    from dronetrack.experiments.compare.suites import SUITES

    text = _help(["compare"], capsys)
    assert "acquisition" in SUITES
    for name in SUITES:
        assert name in text, name


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
    good = Path(__file__).resolve().parents[2] / "examples" / "trajectory.csv"
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


@pytest.mark.parametrize(
    ("entry", "where", "message"),
    [
        (
            "[[walkers]]\narea_m = [10, -5, 20, 5]\nspeed_m_s = [-1.0, 1.5]\n",
            "walkers.0",
            "speed_m_s must be (low, high) with 0 < low ≤ high ≤ 5 m/s, got -1, 1.5",
        ),
        (
            "[[vehicles]]\npath_m = [[40, 0], [30, 0]]\nspeed_m_s = -3\n",
            "vehicles.0.speed_m_s",
            "Input should be greater than 0",
        ),
        (
            "[[vehicles]]\npath_m = [[40, 0], [30, 0]]\narrive_s = 12\n",
            "vehicles.0.arrive_s",
            "= 12 s is not before the run ends (duration_s = 8 s)",
        ),
    ],
)
def test_a_bad_walker_or_vehicle_entry_is_one_error_line(
    entry: str, where: str, message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "s.toml"
    path.write_text(f'base = "default"\nduration_s = 8.0\n{entry}')
    line = _one_error(["simulate", str(path), "--out", str(tmp_path / "o")], capsys)
    assert f"{path}: {where}" in line
    assert message in line
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize(
    ("section", "key", "value", "message"),
    [
        ("choose", "revisit_s", "0", "pipeline.choose.revisit_s: Input should be greater than 0"),
        ("choose", "revisit_s", "-3", "pipeline.choose.revisit_s: Input should be greater than 0"),
        ("choose", "hysteresis", "0.5", "pipeline.choose.hysteresis"),
        ("tracks", "coast_s", "-1", "pipeline.tracks.coast_s: Input should be greater than 0"),
        (
            "tracks",
            "probation_alpha",
            "1",
            "pipeline.tracks.probation_alpha: Input should be less than 1",
        ),
        (
            "background",
            "learn_s",
            "-1",
            "pipeline.background.learn_s: Input should be greater than 0",
        ),
        (
            "background",
            "learn_share",
            "-0.2",
            "pipeline.background.learn_share: Input should be greater than 0",
        ),
        (
            "background",
            "learn_share",
            "1.5",
            "pipeline.background.learn_share: Input should be less than or equal to 1",
        ),
        (
            "background",
            "learn_after_s",
            "-1",
            "pipeline.background.learn_after_s: Input should be greater than or equal to 0",
        ),
        ("background", "learn_after_s", "30", "must not exceed learn_s (20)"),
    ],
)
def test_a_bad_track_or_turret_setting_is_one_line(
    section: str,
    key: str,
    value: str,
    message: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    scenario = tmp_path / "bad.toml"
    scenario.write_text(f'base = "default"\n[pipeline.{section}]\n{key} = {value}\n')
    line = _one_error(["simulate", str(scenario), "--duration", "1"], capsys)
    assert message in line
    assert str(scenario) in line
