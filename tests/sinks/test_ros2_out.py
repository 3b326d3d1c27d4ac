"""``--publish ros2``: what a run publishes for RViz, taken by a subscriber on a
loopback DDS domain and decoded with rosbags' ROS 2 typestore (not our decoders);
the topics and types obey ROS 2's naming rules.  Every wait is bounded."""

from __future__ import annotations

import csv
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from dronetrack.cli.main import run
from dronetrack.formats.ros.names import check_type_name, ros_topic_name
from ros2_helpers import check_tracks_published, loopback_dds


def _subscribe(domain_id: int) -> tuple[Any, dict[str, Any]]:
    from dronetrack.sinks.ros2_out import TOPICS
    from dronetrack.sources.ros2.dds import DdsDomain

    sub = DdsDomain(domain_id)
    # the reliable topics with depth 100 (every sample of the run), the clouds best effort
    readers = {
        key: sub.reader(topic, msg_type, "sensor" if "PointCloud2" in msg_type else "tf")
        for key, (topic, msg_type) in TOPICS.items()
    }
    return sub, readers


def test_topics_and_types_follow_ros2_naming() -> None:
    from dronetrack.sinks.ros2_out import TOPICS

    for topic, msg_type in TOPICS.values():
        assert ros_topic_name(topic) == topic
        check_type_name(msg_type)


def test_simulate_publishes_what_rosbags_decodes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """1 s of scan and 2 s of flight: every frame's track, clouds and (once tracking)
    the estimate, in the world frame, decoded by rosbags."""
    domain = loopback_dds(tmp_path, monkeypatch)
    from dronetrack.sinks.ros2_out import TOPICS

    scenario = tmp_path / "s.toml"
    scenario.write_text('base = "default"\n[pipeline.background]\nscan_s = 1.0\n')
    sub, readers = _subscribe(domain)
    try:
        args = ["simulate", str(scenario), "--duration", "2", "--publish", "ros2"]
        assert run([*args, "--ros-domain-id", str(domain), "--out", str(tmp_path / "r")]) == 0
        got: dict[str, list[bytes]] = {k: [] for k in readers}
        end = time.monotonic() + 3.0
        while time.monotonic() < end and (len(got["track"]) < 30 or len(got["tracks"]) < 20):
            for key, reader in readers.items():
                got[key].extend(reader.drain())
            time.sleep(0.05)
    finally:
        sub.close()
    ts = get_typestore(Stores.ROS2_HUMBLE)
    decoded = {
        key: [ts.deserialize_cdr(raw, TOPICS[key][1]) for raw in raws] for key, raws in got.items()
    }
    frames = 30  # 3 s of 0.1 s frames
    assert len(decoded["track"]) == frames  # reliable: every one
    assert 0 < len(decoded["estimate"]) <= frames
    for key in ("particles", "foreground", "points"):
        assert 0 < len(decoded[key]) <= 5  # best effort, KEEP_LAST 5: the last ones
    markers = decoded.pop("tracks")
    for msgs in decoded.values():
        assert all(m.header.frame_id == "world" for m in msgs)
    last = decoded["track"][-1]
    est = decoded["estimate"][-1].point
    assert len(last.poses) > 0
    p = last.poses[-1].pose.position
    assert (p.x, p.y, p.z) == (est.x, est.y, est.z)  # the path ends at the estimate
    cloud = decoded["points"][-1]
    assert cloud.width > 0
    assert cloud.row_step == cloud.point_step * cloud.width
    names = [f.name for f in cloud.fields]
    assert names[:3] == ["x", "y", "z"]
    xyz = np.frombuffer(cloud.data, dtype=np.float32).reshape(cloud.width, -1)[:, :3]
    assert np.all(np.isfinite(xyz))
    with (tmp_path / "r" / "frames.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    logged = [float(rows[-1][k]) for k in ("est_x", "est_y", "est_z")]
    assert [est.x, est.y, est.z] == pytest.approx(logged, abs=1e-6)  # the run's own estimate

    # every track of every tracking frame (none during the 1 s scan), as tracks.csv
    # logs it
    assert len(markers) == 20
    check_tracks_published(markers, tmp_path / "r")
