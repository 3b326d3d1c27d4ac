"""``dronetrack record``, ``info`` and ``track``: the round trip and bad input."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.eval.log import FRAME_COLUMNS


def _metrics(folder: Path) -> dict[str, object]:
    result: dict[str, object] = json.loads((folder / "metrics.json").read_text())
    return result


@pytest.mark.slow
def test_record_then_track_gives_the_simulated_metrics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``track FILE`` with no options replays a recorded flight as ``simulate`` ran it.

    Measured on the default scenario (seeds 0-3, 20 s): coverage and maximum tracking
    distance identical, RMSE within 0.6 %, the target's points within 1.5 % (replay
    counts returns near the truth, the simulator knows which hit the drone).  The
    bounds below leave room for the float32 points and 100 Hz /tf of the recording.
    """
    bag = tmp_path / "flight.bag"
    args = ["--seed", "2", "--duration", "12"]
    assert run(["record", "--format", "ros1", "--livox-custom", "--out", str(bag), *args]) == 0
    assert run(["simulate", "--out", str(tmp_path / "sim"), *args]) == 0
    capsys.readouterr()
    assert run(["info", str(bag)]) == 0
    listing = capsys.readouterr().out
    for topic in ("/livox/lidar", "/tf", "/tf_static", "/ground_truth/pose", "/dronetrack/config"):
        assert topic in listing
    assert run(["track", str(bag), "--out", str(tmp_path / "track")]) == 0
    sim, rep = _metrics(tmp_path / "sim"), _metrics(tmp_path / "track")
    assert rep["frames"] == sim["frames"]
    assert abs(float(rep["coverage_pct"]) - float(sim["coverage_pct"])) <= 2.0  # type: ignore[arg-type]
    for key, rel in (
        ("max_tracking_distance_m", 0.02),
        ("rmse_m", 0.03),
        ("target_points_total", 0.03),
    ):
        a, b = float(sim[key]), float(rep[key])  # type: ignore[arg-type]
        assert abs(a - b) <= rel * a, (key, a, b)
    assert rep["skipped_messages"] == {}
    folder = tmp_path / "track"
    for name in ("config.toml", "frames.csv", "commands.csv", "metrics.json", "top_view.png"):
        assert (folder / name).exists(), name
    with (folder / "frames.csv").open() as fh:
        header = next(csv.reader(fh))
    assert tuple(header[: len(FRAME_COLUMNS)]) == FRAME_COLUMNS
    commands = (folder / "commands.csv").read_text().splitlines()
    assert commands[0] == "t,mode,pan_rad,tilt_rad"
    assert len(commands) > 100  # the turret is commanded every frame, scan included


@pytest.mark.slow
def test_track_options_without_ground_truth(tmp_path: Path) -> None:
    """A PointCloud2 recording in ROS 2 MCAP, replayed with another tracker and a
    background from its first seconds; without ground truth there are no accuracy metrics."""
    bag = tmp_path / "flight.mcap"
    assert (
        run(
            [
                "record",
                "--format",
                "ros2-mcap",
                "--pointcloud2",
                "--out",
                str(bag),
                "--seed",
                "1",
                "--duration",
                "3",
            ]
        )
        == 0
    )
    out = tmp_path / "t"
    args = ["track", str(bag), "--gt-topic", "/ground_truth/pose", "--tracker", "ekf-dogru"]
    assert run([*args, "--background-from", "8", "--out", str(out)]) == 0
    cfg = (out / "config.toml").read_text()
    assert 'kind = "ekf-dogru"' in cfg
    assert "scan_s = 8.0" in cfg
    m = _metrics(out)
    assert m["frames"] == 50  # 13 s recorded, 8 s of background scan
    assert "coverage_pct" in m


def test_track_without_ground_truth_has_no_accuracy_metrics(tmp_path: Path) -> None:
    from sources.recordings.test_bag import _write_pc2_bag

    xyz = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)]
    rng = np.random.default_rng(3)
    clouds = [
        (xyz, (rng.normal(size=(50, 3)) * 0.1 + [20.0, 0.0, 5.0]).astype("<f4").tobytes(), 50, 12)
        for _ in range(30)
    ]
    path = tmp_path / "points"
    _write_pc2_bag(path, clouds)
    out = tmp_path / "t"
    assert run(["track", str(path), "--background-from", "0", "--out", str(out)]) == 0
    m = _metrics(out)
    assert m["frames"] == 30
    assert "coverage_pct" not in m
    assert "rmse_m" not in m
    with (out / "frames.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert all(r["gt_x"] in ("", "nan") for r in rows)
    # The tracker found the cluster at (20, 0, 5) m.
    est = np.array([[float(r[k]) for k in ("est_x", "est_y", "est_z")] for r in rows[-5:]])
    np.testing.assert_allclose(est.mean(axis=0), [20.0, 0.0, 5.0], atol=0.3)


@pytest.fixture(scope="module")
def small_bag(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("small")
    bag = folder / "a.bag"
    assert run(["record", "--out", str(bag), "--duration", "0.5"]) == 0
    data = bag.read_bytes()
    (folder / "trunc.bag").write_bytes(data[: len(data) // 3])
    (folder / "notes.txt").write_text("hello")
    (folder / "empty").mkdir()
    return bag


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["track", "missing.bag"], "no such recording"),
        (["track", "{tmp}/notes.txt"], "it starts with b'hello', not a ROS 1 bag"),
        (["track", "{bag}", "--lidar-topic", "/nope"], "no topic '/nope'"),
        (["track", "{bag}", "--gt-topic", "/livox/lidar"], "not a ground-truth type"),
        (["track", "{bag}", "--gt-origin", "47.1,19"], "--gt-origin takes 3"),
        (["track", "{bag}", "--background", "{tmp}/bg.npz", "--background-from", "2"], "not both"),
        (["track", "{trunc}"], "the ROS 1 bag is truncated"),
        (["info", "{trunc}"], "the ROS 1 bag is truncated"),
        (["record", "--out", "{bag}"], "exists"),
        (["record", "--format", "ros3", "--out", "{tmp}/x.bag"], "ros3"),
        (["track", "{tmp}/empty"], "a folder with no bag"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    small_bag: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    bag, tmp_path = small_bag, small_bag.parent
    capsys.readouterr()
    filled = [a.format(tmp=tmp_path, bag=bag, trunc=tmp_path / "trunc.bag") for a in argv]
    assert run(filled) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:")
    assert message in err
    assert len(err.splitlines()) == 1


@pytest.mark.slow
def test_viewer_files_from_simulate_and_track(tmp_path: Path) -> None:
    from rerun.chunk import RrdReader  # the rerun extra is part of the test install

    fox, rrd = tmp_path / "sim.mcap", tmp_path / "sim.rrd"
    bag = tmp_path / "a.bag"
    args = ["--duration", "1", "--seed", "5"]
    assert (
        run(
            [
                "simulate",
                *args,
                "--out",
                str(tmp_path / "s"),
                "--foxglove",
                str(fox),
                "--rerun",
                str(rrd),
            ]
        )
        == 0
    )
    assert fox.read_bytes()[:8] == b"\x89MCAP0\r\n"
    entities = {str(p) for p in RrdReader(rrd).store().schema().entity_paths()}
    assert {"/world/lidar/points", "/world/track/estimate", "/world/frames/lidar"} <= entities
    assert run(["record", *args, "--out", str(bag)]) == 0
    replay_fox = tmp_path / "track.mcap"
    assert (
        run(["track", str(bag), "--out", str(tmp_path / "t"), "--foxglove", str(replay_fox)]) == 0
    )
    assert replay_fox.stat().st_size > 10_000


def test_missing_viewer_extra_is_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    import sys

    monkeypatch.setitem(sys.modules, "foxglove", None)
    out = tmp_path / "x.mcap"
    assert (
        run(["simulate", "--duration", "0.5", "--foxglove", str(out), "--out", str(tmp_path / "s")])
        == 2
    )
    err = capsys.readouterr().err.strip()
    assert err == "error: --foxglove needs foxglove-sdk: pip install 'dronetrack[foxglove]'"
    assert not out.exists()


def _moving_cluster(k: int, rng: np.random.Generator) -> np.ndarray:
    """Frame k of a 30-point cluster flying along x at 2 m/s, 20 m out, 5 m up."""
    return rng.normal(size=(30, 3)) * 0.1 + [20.0 + 0.2 * k, 0.0, 5.0]


def _check_track(out: Path, frames: int) -> None:
    m = _metrics(out)
    assert m["frames"] == frames
    with (out / "frames.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    last = np.array([float(rows[-1][k]) for k in ("est_x", "est_y", "est_z")])
    k = frames - 1
    np.testing.assert_allclose(last, [20.0 + 0.2 * k, 0.0, 5.0], atol=0.5)


def test_track_reads_pcd_folders_las_files_and_field_logs(tmp_path: Path) -> None:
    """The other inputs run through the same command: a .pcd folder timed by its file
    names, a .las file split into frames by GPS time, and seed 003's CSV logs."""
    import laspy

    from dronetrack.formats.pcd import write_pcd

    rng = np.random.default_rng(11)
    clouds = [_moving_cluster(k, rng) for k in range(30)]
    common = ["--background-from", "0", "--tracker", "pf-cv"]
    # .pcd files named by their Unix time in seconds
    pcd = tmp_path / "pcd"
    pcd.mkdir()
    for k, c in enumerate(clouds):
        arr = np.zeros(len(c), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
        arr["x"], arr["y"], arr["z"] = c.T
        write_pcd(pcd / f"{1_700_000_000 + 0.1 * k:.3f}.pcd", arr)
    assert run(["track", str(pcd), *common, "--out", str(tmp_path / "p")]) == 0
    _check_track(tmp_path / "p", 30)
    # one .las file with gps_time
    header = laspy.LasHeader(point_format=1, version="1.2")
    header.scales = np.array([0.001, 0.001, 0.001])
    las = laspy.LasData(header)
    xyz = np.concatenate(clouds)
    las.x, las.y, las.z = xyz.T
    las.gps_time = np.repeat(1000.0 + 0.1 * np.arange(30), 30) + 0.01
    las.write(tmp_path / "flight.las")
    assert run(["track", str(tmp_path / "flight.las"), *common, "--out", str(tmp_path / "l")]) == 0
    _check_track(tmp_path / "l", 30)
    # seed 003's filtered_points.csv: t,x,y,z,seq in the world frame
    logs = tmp_path / "logs"
    logs.mkdir()
    lines = ["t,x,y,z,seq"]
    for k, c in enumerate(clouds):
        lines += [f"{0.1 * (k + 1):.6f},{x:.4f},{y:.4f},{z:.4f},{k}" for x, y, z in c]
    (logs / "filtered_points.csv").write_text("\n".join(lines) + "\n")
    assert run(["track", str(logs), *common, "--out", str(tmp_path / "f")]) == 0
    _check_track(tmp_path / "f", 30)


def _pcd_folder(folder: Path) -> Path:
    """30 .pcd files of the moving cluster, named by their Unix time in seconds."""
    from dronetrack.formats.pcd import write_pcd

    rng = np.random.default_rng(11)
    folder.mkdir()
    for k in range(30):
        c = _moving_cluster(k, rng)
        arr = np.zeros(len(c), dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
        arr["x"], arr["y"], arr["z"] = c.T
        write_pcd(folder / f"{1_700_000_000 + 0.1 * k:.3f}.pcd", arr)
    return folder


def test_truth_outside_the_recording_is_a_warning_with_both_spans(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The cluster's true path given in seconds from the recording's start scores the
    run; the same path stamped in Unix seconds misses every frame, and ``track`` says so
    in one ``warning:`` line and in ``metrics.json``, with the recording's span (from
    its start and as stamped) and the truth's as given."""
    pcd = _pcd_folder(tmp_path / "pcd")
    t = 0.1 * np.arange(31)
    path = np.c_[20.0 + 2.0 * t, np.zeros_like(t), np.full_like(t, 5.0)]
    for name, shift in (("start.csv", 0.0), ("unix.csv", 1_700_000_000.0)):
        rows = [
            f"{ti + shift:.3f},{x:.3f},{y:.3f},{z:.3f}"
            for ti, (x, y, z) in zip(t, path, strict=True)
        ]
        (tmp_path / name).write_text("t,x,y,z\n" + "\n".join(rows) + "\n")
    common = ["track", str(pcd), "--background-from", "0", "--sensor-pose", "0,0,0,0,0,0"]
    capsys.readouterr()
    assert run([*common, "--truth", str(tmp_path / "start.csv"), "--out", str(tmp_path / "a")]) == 0
    assert "warning" not in capsys.readouterr().err
    scored = _metrics(tmp_path / "a")
    assert "warnings" not in scored
    assert float(scored["coverage_pct"]) > 50  # type: ignore[arg-type]
    assert run([*common, "--truth", str(tmp_path / "unix.csv"), "--out", str(tmp_path / "b")]) == 0
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("warning:")]
    assert len(lines) == 1
    warning = lines[0].removeprefix("warning: ")
    assert _metrics(tmp_path / "b")["warnings"] == [warning]
    assert warning.startswith("no truth sample falls inside the recording's time span")
    assert "0.000 to 3.000 s from its start (1700000000.000 to 1700000003.000 s as stamped)" in (
        warning
    )
    assert "unix.csv's t spans 1700000000.000 to 1700000003.000 s as given" in warning


def test_sensor_pose_on_a_bag_with_tf_is_a_warning(
    small_bag: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The recorded bag's /tf places its LiDAR, so ``--sensor-pose`` changes nothing and
    ``track`` says it is ignored, in a ``warning:`` line and in ``metrics.json``."""
    capsys.readouterr()
    out = tmp_path / "t"
    assert run(["track", str(small_bag), "--sensor-pose", "1,2,3,0,0,90", "--out", str(out)]) == 0
    lines = [ln for ln in capsys.readouterr().err.splitlines() if ln.startswith("warning:")]
    expected = (
        "a.bag's /tf gives the pose of its LiDAR frame 'lidar' (the chain from 'world'), "
        "so --sensor-pose is ignored"
    )
    assert lines.count(f"warning: {expected}") == 1
    assert _metrics(out)["warnings"] == [expected]


def test_period_on_a_bag_without_point_times_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from sources.recordings.test_bag import _write_pc2_bag

    xyz = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)]
    path = tmp_path / "points"
    _write_pc2_bag(path, [(xyz, np.arange(30, dtype="<f4").tobytes(), 10, 12)] * 5)
    capsys.readouterr()
    assert run(["track", str(path), "--period", "0.05", "--out", str(tmp_path / "t")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:")
    assert "--period 0.05 s cannot re-cut /points" in err
    assert len(err.splitlines()) == 1
