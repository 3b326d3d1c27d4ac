"""``dronetrack live --lidar ros2:///…`` end to end on a loopback DDS domain: a
recording of a short flight played by a separate publisher process (cyclonedds'
public API and rosbags' bytes, ``tests/ros2_player.py``) is tracked live as
``dronetrack track`` tracks the recording; bad ROS 2 options.  Every wait is bounded."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run
from ros2_helpers import check_tracks_published, loopback_dds

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = """\
base = "default"
seed = 0
[pipeline.background]
scan_s = 4.0
"""


@pytest.fixture(scope="module")
def flight(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """12 s of the default flight (4 s of scan, 8 s of flight; first lock at 7.5 s),
    as PointCloud2 in ROS 2 MCAP, and ``track``'s run of it next to it."""
    folder = tmp_path_factory.mktemp("ros2")
    (folder / "scenario.toml").write_text(SCENARIO)
    bag = folder / "flight.mcap"
    args = ["record", str(folder / "scenario.toml"), "--duration", "8", "--pointcloud2"]
    assert run([*args, "--out", str(bag)]) == 0
    assert run(["track", str(bag), "--out", str(folder / "track")]) == 0
    return bag


@pytest.mark.slow
def test_live_over_dds_tracks_as_track_does(
    flight: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain = loopback_dds(tmp_path, monkeypatch)
    out = tmp_path / "live"
    player = subprocess.Popen(
        [sys.executable, str(ROOT / "tests" / "ros2_player.py"), str(flight), str(domain)],
        env={**os.environ, "PYTHONPATH": f"{ROOT / 'src'}:{ROOT}"},
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        config = flight.parent / "track" / "config.toml"  # the recording's own scenario
        lidar = "ros2:///livox/lidar?truth=/ground_truth/pose"
        args = ["live", str(config), "--lidar", lidar, "--turret", "none"]
        code = run([*args, "--ros-domain-id", str(domain), "--out", str(out)])
        _, err = player.communicate(timeout=30)
    finally:
        player.kill()
    assert code == 0
    assert player.returncode == 0, err
    live = json.loads((out / "metrics.json").read_text())
    track = json.loads((flight.parent / "track" / "metrics.json").read_text())
    assert live["frames"] == track["frames"]
    assert live["frames_dropped"] == 0
    assert abs(live["coverage_pct"] - track["coverage_pct"]) <= 2.0
    assert track["coverage_pct"] > 30.0  # there is something to compare
    assert live["latency_ms_p50"] < 100.0  # within a frame period


@pytest.mark.parametrize(
    ("lidar", "problem"),
    [
        ("ros2://host/livox/lidar", "no host"),
        ("ros2:///livox//lidar", "must not repeat '/'"),
        ("ros2://", "names no topic"),
        ("ros2:///x?type=sensor_msgs/msg/Imu", "is not sensor_msgs/msg/PointCloud2 or"),
    ],
)
def test_bad_ros2_lidar_is_one_error_line(
    lidar: str,
    problem: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    loopback_dds(tmp_path, monkeypatch)
    args = ["live", "--lidar", lidar, "--turret", "none", "--out", str(tmp_path / "run")]
    assert run(args) == 2
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(err) == 1, err
    assert err[0].startswith("error: ")
    assert problem in err[0]


@pytest.mark.slow
def test_live_publishes_its_estimate_on_ros2(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``live --publish ros2`` (a recording played at wall-clock speed as the LiDAR):
    a subscriber on the domain decodes the estimates and the tracks with rosbags' Humble
    typestore, and they are the run's own estimates, in order, in the world frame, and
    every track of every frame as its tracks.csv logs them."""
    import csv
    import time

    from rosbags.typesys import Stores, get_typestore

    from dronetrack.formats.ros.msgs import MARKER_ARRAY, POINT_STAMPED
    from dronetrack.sources.ros2.dds import DdsDomain

    domain = loopback_dds(tmp_path, monkeypatch)
    scenario = 'base = "default"\nseed = 0\n[pipeline.background]\nscan_s = 1.0\n'
    (tmp_path / "s.toml").write_text(scenario)
    bag = tmp_path / "flight.mcap"
    assert run(["record", str(tmp_path / "s.toml"), "--duration", "3", "--out", str(bag)]) == 0
    sub = DdsDomain(domain)
    reader = sub.reader("/dronetrack/estimate", POINT_STAMPED, "tf")  # reliable, depth 100
    tracks = sub.reader("/dronetrack/tracks", MARKER_ARRAY, "tf")
    out = tmp_path / "live"
    got: list[bytes] = []
    got_tracks: list[bytes] = []
    try:
        args = ["live", "--lidar", f"file://{bag}", "--turret", "none", "--publish", "ros2"]
        assert run([*args, "--ros-domain-id", str(domain), "--out", str(out)]) == 0
        end = time.monotonic() + 2.0
        while time.monotonic() < end:
            got.extend(reader.drain())
            got_tracks.extend(tracks.drain())
            reader.wait(0.05)
    finally:
        sub.close()
    ts = get_typestore(Stores.ROS2_HUMBLE)
    msgs = [ts.deserialize_cdr(raw, POINT_STAMPED) for raw in got]
    with (out / "frames.csv").open() as fh:
        rows = [r for r in csv.DictReader(fh) if r["est_x"] not in ("", "nan")]
    assert len(rows) > 5  # it tracked
    assert len(msgs) == len(rows)  # reliable: one per estimate
    assert all(m.header.frame_id == "world" for m in msgs)
    got_xyz = np.array([(m.point.x, m.point.y, m.point.z) for m in msgs])
    want = np.array([[float(r[k]) for k in ("est_x", "est_y", "est_z")] for r in rows])
    np.testing.assert_allclose(got_xyz, want, atol=1e-5)
    check_tracks_published([ts.deserialize_cdr(raw, MARKER_ARRAY) for raw in got_tracks], out)
