"""Bags written by ``record`` and read back for replay: every container and point
format, the frames' fidelity, ``info``, and bad recordings."""

from __future__ import annotations

import logging
import tomllib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dronetrack.config.rig import turret_spec
from dronetrack.config.run import apply_overrides, dump_scenario
from dronetrack.config.scenarios import get_scenario
from dronetrack.errors import ConfigError, RecordingError
from dronetrack.jobs.simulate import resolve_run, run_simulation
from dronetrack.sinks.bag_writer import RecordingWriter
from dronetrack.sources.recordings.bag import BagRecording
from dronetrack.sources.recordings.opener import open_recording, recording_info
from dronetrack.sources.recordings.recording import ReplayOptions
from dronetrack.types import Frame, Sample, StepResult

VARIANTS = [
    ("ros1", True, "a.bag"),
    ("ros1", False, "b.bag"),
    ("ros2-sqlite3", True, "c.db3"),
    ("ros2-sqlite3", False, "d_folder"),
    ("ros2-mcap", True, "e.mcap"),
    ("ros2-mcap", False, "f_folder"),
]


class EachFrame:
    """A run loop's sink that calls ``fn(frame, truth, result)`` for every frame."""

    def __init__(self, fn: Callable[[Frame, Any, StepResult], None]) -> None:
        self.fn = fn

    def write(self, sample: Sample, result: StepResult) -> None:
        self.fn(sample.frame, sample.truth, result)


def _short_config() -> Any:
    cfg = apply_overrides(get_scenario("default"), seed=4, duration=1.5)
    bg = cfg.pipeline.background.model_copy(update={"scan_s": 1.0})
    cfg = cfg.model_copy(update={"pipeline": cfg.pipeline.model_copy(update={"background": bg})})
    return resolve_run(cfg)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """One short closed-loop run written to all six variants at once."""
    folder = tmp_path_factory.mktemp("bags")
    cfg = _short_config()
    mount = turret_spec(cfg.turret).mount
    writers = [
        RecordingWriter(
            folder / name, fmt, mount, livox_custom=livox, config_text=dump_scenario(cfg)
        )
        for fmt, livox, name in VARIANTS
    ]
    frames: list[Frame] = []
    truths: list[np.ndarray] = []

    def keep(frame: Frame, truth: Any, _: Any) -> None:
        frames.append(frame)
        truths.append(truth.target_position)
        for w in writers:
            w.frame(frame, truth.target_position, truth.target_attitude)

    run_simulation(cfg, sinks=[EachFrame(keep)])
    for w in writers:
        w.close()
    return {"folder": folder, "frames": frames, "truths": np.array(truths), "cfg": cfg}


@pytest.mark.parametrize(("fmt", "livox", "name"), VARIANTS)
def test_frames_come_back_as_recorded(
    recorded: dict[str, Any], fmt: str, livox: bool, name: str
) -> None:
    path = recorded["folder"] / name
    rec = open_recording(path)
    assert isinstance(rec, BagRecording)
    assert rec.period == pytest.approx(0.1, abs=1e-9)
    original: list[Frame] = recorded["frames"]
    replayed = list(rec.frames())
    assert len(replayed) == len(original) == 25
    for a, b in zip(original, replayed, strict=True):
        assert b.stamp == pytest.approx(a.stamp, abs=1e-9)
        assert len(a) == len(b)
        # float32 coordinates; per-point times to the nanosecond (PointCloud2: f64 ns, ~0.3 µs)
        np.testing.assert_allclose(b.points, a.points, atol=2e-5 * max(1.0, np.abs(a.points).max()))
        np.testing.assert_allclose(b.t, a.t, atol=1e-6)
        np.testing.assert_array_equal(b.line, a.line)
        # The /tf chain at 100 Hz gives the sensor poses the simulator used, to within
        # linear interpolation between 10 ms samples of quantised joint angles: one
        # encoder step per axis (0.088°) plus α Δt²/8 (α = 360°/s²), at each point's range.
        step = np.radians(0.088) * np.sqrt(2) + np.radians(360.0) * 0.01**2 / 8
        bound = np.linalg.norm(a.points, axis=1) * step + 1e-4
        miss = np.linalg.norm(b.world_points() - a.world_points(), axis=1)
        assert np.all(miss <= bound), float((miss / bound).max())
    # Ground truth: the target's pose at every frame end.
    truth = rec.ground_truth
    assert truth is not None
    ends = np.array([f.end for f in original])
    np.testing.assert_allclose(truth.at(ends), recorded["truths"], atol=1e-9)
    # The scenario travels with the recording.
    assert rec.config_text is not None
    assert tomllib.loads(rec.config_text)["seed"] == recorded["cfg"].seed
    info = recording_info(path)
    topics = {t.topic: (t.msgtype, t.count) for t in info.topics}
    lidar_type = (
        ("livox_ros_driver" if fmt == "ros1" else "livox_ros_driver2") + "/msg/CustomMsg"
        if livox
        else "sensor_msgs/msg/PointCloud2"
    )
    assert topics["/livox/lidar"] == (lidar_type, 25)
    assert topics["/ground_truth/pose"] == ("geometry_msgs/msg/PoseStamped", 25)
    assert topics["/tf"][1] == 251  # 100 Hz over 2.5 s, and the last frame's end
    assert info.duration_s == pytest.approx(2.5, abs=0.011)
    assert info.kind == {"ros1": "ros1", "ros2-sqlite3": "ros2-sqlite3"}.get(
        fmt, "mcap" if name.endswith(".mcap") else "ros2-mcap"
    )


def test_options_choose_and_reject_topics(recorded: dict[str, Any]) -> None:
    path = recorded["folder"] / "a.bag"
    rec = BagRecording(
        path, ReplayOptions(lidar_topic="/livox/lidar", gt_topic="/ground_truth/pose")
    )
    assert rec.ground_truth is not None
    with pytest.raises(RecordingError, match=r"no topic '/nope'.*topics: /dronetrack/config"):
        BagRecording(path, ReplayOptions(lidar_topic="/nope"))
    with pytest.raises(
        RecordingError, match="/ground_truth/pose has type geometry_msgs/msg/PoseStamped"
    ):
        BagRecording(path, ReplayOptions(lidar_topic="/ground_truth/pose"))
    # An unknown pose frame: the error lists the frames /tf has.
    with pytest.raises(
        RecordingError,
        match="'map' is not in the /tf tree; its frames are: lidar, pan_link, tilt_link, "
        "turret_base, world",
    ):
        list(BagRecording(path, ReplayOptions(pose_frame="map")).frames())
    # A frame of the tree that is not above the LiDAR's: its chain is shown.
    with pytest.raises(RecordingError, match=r"not below 'pan_link'.*its chain is"):
        list(BagRecording(path, ReplayOptions(pose_frame="pan_link")).frames())


def test_writer_refuses_existing_paths_and_bad_formats(tmp_path: Path) -> None:
    mount = turret_spec(_short_config().turret).mount
    (tmp_path / "x.bag").write_bytes(b"")
    with pytest.raises(ConfigError, match="exists"):
        RecordingWriter(tmp_path / "x.bag", "ros1", mount)
    with pytest.raises(ConfigError, match="unknown format 'ros3'"):
        RecordingWriter(tmp_path / "y.bag", "ros3", mount)  # type: ignore[arg-type]


def _read_all(path: Path) -> int:
    return sum(1 for _ in open_recording(path).frames())


@pytest.mark.parametrize("name", ["a.bag", "e.mcap", "c.db3"])
def test_truncated_recordings_fail_with_one_line(
    recorded: dict[str, Any], tmp_path: Path, name: str
) -> None:
    data = (recorded["folder"] / name).read_bytes()
    cut = tmp_path / name
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(RecordingError) as err:
        _read_all(cut)
    assert "\n" not in str(err.value)
    assert str(cut) in str(err.value)


def test_corrupt_bytes_never_crash(recorded: dict[str, Any], tmp_path: Path) -> None:
    """Flipped bytes inside the data either end the read with a RecordingError or
    skip (and count) the messages they hit; nothing else escapes."""
    data = bytearray((recorded["folder"] / "a.bag").read_bytes())
    rng = np.random.default_rng(7)
    failed: list[str] = []
    read = 0
    for trial in range(8):
        bad = bytearray(data)
        at = rng.integers(len(bad) // 10, len(bad) * 9 // 10, size=40)
        if trial == 0:  # the bag's header record, right after "#ROSBAG V2.0\n"
            at[0] = 13
        bad[at[0] : at[0] + 64] = rng.integers(0, 256, 64, dtype=np.uint8).tobytes()
        for i in at[1:]:
            bad[i] ^= 0xFF
        path = tmp_path / f"bad{trial}.bag"
        path.write_bytes(bytes(bad))
        try:
            rec = open_recording(path)
            n = sum(1 for _ in rec.frames())
        except RecordingError as err:
            failed.append(str(err))
            continue
        assert n + sum(rec.skipped.values()) >= 1
        read += 1
    # Both outcomes happen (a damaged bag header cannot be read past), and every
    # error is one line.
    assert read >= 1
    assert failed
    assert all("\n" not in e for e in failed)


def _write_pc2_bag(
    path: Path, clouds: list[tuple[list[tuple[str, int, int]], bytes, int, int]]
) -> None:
    """A ROS 2 bag of hand-made PointCloud2 messages: (fields, data, width, point_step)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/points", "sensor_msgs/msg/PointCloud2", typestore=ts)
        for k, (fields, data, width, step) in enumerate(clouds):
            stamp = T["builtin_interfaces/msg/Time"](sec=100, nanosec=k * 100_000_000)
            msg = T["sensor_msgs/msg/PointCloud2"](
                header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="velodyne"),
                height=1,
                width=width,
                fields=[
                    T["sensor_msgs/msg/PointField"](name=n, offset=o, datatype=d, count=1)
                    for n, o, d in fields
                ],
                is_bigendian=False,
                point_step=step,
                row_step=step * width,
                data=np.frombuffer(data, np.uint8),
                is_dense=True,
            )
            w.write(
                conn,
                100 * 10**9 + k * 100_000_000,
                ts.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"),
            )


def test_bad_point_messages_are_skipped_counted_and_warned(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    xyz = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)]
    good = np.arange(30, dtype="<f4").tobytes()  # 10 points of 12 bytes
    clouds = [(xyz, good, 10, 12)] * 3
    clouds.insert(1, ([("a", 0, 7), ("b", 4, 7), ("c", 8, 7)], good, 10, 12))  # no x, y, z
    clouds.insert(3, (xyz, good, 11, 12))  # 11 points declared, 10 in the data
    path = tmp_path / "points"
    _write_pc2_bag(path, clouds)
    rec = open_recording(path)
    with caplog.at_level(logging.WARNING):
        frames = list(rec.frames())
    assert len(frames) == 3
    assert rec.skipped["bad_point_message"] == 2
    assert "no x, y, z" in caplog.text
    assert "11" in caplog.text
    np.testing.assert_allclose(frames[0].points, np.arange(30).reshape(10, 3))
    # No /tf: the identity pose; no ground truth; no carried config.
    np.testing.assert_allclose(frames[0].poses[0], np.eye(4))
    assert rec.ground_truth is None
    assert rec.config_text is None


def test_a_bag_without_point_topics_is_named(tmp_path: Path) -> None:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    path = tmp_path / "empty.bag"
    with Writer(path) as w:
        conn = w.add_connection("/chatter", "std_msgs/msg/String", typestore=ts)
        w.write(
            conn,
            10**9,
            ts.serialize_ros1(ts.types["std_msgs/msg/String"](data="hi"), "std_msgs/msg/String"),
        )
    with pytest.raises(
        RecordingError, match=r"no LiDAR topic; topics: /chatter \(std_msgs/msg/String\)"
    ):
        open_recording(path)
    assert [t.topic for t in recording_info(path).topics] == ["/chatter"]


def test_navsatfix_ground_truth_in_a_local_enu_frame(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """GNSS fixes become positions in the ENU frame at --gt-origin, turned by the heading;
    a fix without a fix (status −1) is skipped and counted."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    from dronetrack.geometry.geodesy import enu_from_geodetic

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    path = tmp_path / "gnss.mcap"
    origin = (47.47, 19.06, 120.0)
    lat = origin[0] + 1e-4 * np.arange(6)
    lon = origin[1] + 2e-4 * np.arange(6)
    alt = origin[2] + np.arange(6.0)
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        pc = w.add_connection("/points", "sensor_msgs/msg/PointCloud2", typestore=ts)
        fix = w.add_connection("/fix", "sensor_msgs/msg/NavSatFix", typestore=ts)
        for k in range(6):
            stamp = T["builtin_interfaces/msg/Time"](sec=50, nanosec=k * 100_000_000)
            header = T["std_msgs/msg/Header"](stamp=stamp, frame_id="lidar")
            msg = T["sensor_msgs/msg/PointCloud2"](
                header=header,
                height=1,
                width=1,
                fields=[
                    T["sensor_msgs/msg/PointField"](name=n, offset=4 * i, datatype=7, count=1)
                    for i, n in enumerate("xyz")
                ],
                is_bigendian=False,
                point_step=12,
                row_step=12,
                data=np.zeros(12, np.uint8),
                is_dense=True,
            )
            t_ns = 50 * 10**9 + k * 100_000_000
            w.write(pc, t_ns, ts.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2"))
            status = T["sensor_msgs/msg/NavSatStatus"](status=-1 if k == 3 else 0, service=1)
            gnss = T["sensor_msgs/msg/NavSatFix"](
                header=header,
                status=status,
                latitude=lat[k],
                longitude=lon[k],
                altitude=alt[k],
                position_covariance=np.zeros(9),
                position_covariance_type=0,
            )
            w.write(fix, t_ns, ts.serialize_cdr(gnss, "sensor_msgs/msg/NavSatFix"))
    rec = BagRecording(path, ReplayOptions(gt_origin=origin, gt_heading_deg=30.0))
    assert rec.ground_truth is not None
    keep = np.array([0, 1, 2, 4, 5])
    np.testing.assert_allclose(rec.ground_truth.t, 0.1 * keep, atol=1e-9)
    want = enu_from_geodetic(lat[keep], lon[keep], alt[keep], origin, 30.0)
    np.testing.assert_allclose(rec.ground_truth.position, want, atol=1e-9)
    assert rec.skipped["gt_no_fix"] == 1
    # Without an origin, the first fix is the origin, with a warning naming the option.
    with caplog.at_level(logging.WARNING):
        first = BagRecording(path).ground_truth
    assert first is not None
    np.testing.assert_allclose(first.position[0], 0.0, atol=1e-9)
    assert "--gt-origin" in caplog.text
    # A site's frame: the turret base 1 m up at the origin, world x 60° from north (a
    # yaw of 30° from east): the same positions, 1 m up, as the tracks' frame is.
    from dronetrack.geometry.geodesy import SiteFrame

    site = SiteFrame(*origin, heading_deg=60.0, base=(0.0, 0.0, 1.0))
    placed = BagRecording(path, ReplayOptions(gt_site=site)).ground_truth
    assert placed is not None
    np.testing.assert_allclose(placed.position, want + np.array([0.0, 0.0, 1.0]), atol=1e-6)


def test_a_moving_observer_is_recorded_as_odometry_in_tf(tmp_path: Path) -> None:
    """seed 002's relative tracking: /tf carries world → base_link (the observer's
    odometry) above the fixed turret, and the replayed frames land where the simulated
    ones did."""
    cfg = apply_overrides(get_scenario("seed002-relative"), duration=1.0)
    cfg = resolve_run(cfg)
    assert cfg.observer is not None
    path = tmp_path / "observer.mcap"
    writer = RecordingWriter(
        path,
        "ros2-mcap",
        turret_spec(cfg.turret).mount,
        config_text=dump_scenario(cfg),
        observer=True,
    )
    frames: list[Frame] = []

    def keep(frame: Frame, truth: Any, _: Any) -> None:
        frames.append(frame)
        turret = (truth.turret.pan, truth.turret.tilt)
        writer.frame(frame, truth.target_position, truth.target_attitude, turret)

    run_simulation(cfg, sinks=[EachFrame(keep)])
    writer.close()
    rec = open_recording(path)
    assert isinstance(rec, BagRecording)
    assert rec.tf.chain("lidar") == [
        "world",
        "base_link",
        "turret_base",
        "pan_link",
        "tilt_link",
        "lidar",
    ]
    replayed = list(rec.frames())
    assert len(replayed) == len(frames)
    for a, b in zip(frames, replayed, strict=True):
        # The body moves smoothly, so 100 Hz samples interpolate it to well under a
        # milliradian; the rest is float32 coordinates.
        bound = np.linalg.norm(a.points, axis=1) * 1e-3 + 1e-3
        miss = np.linalg.norm(b.world_points() - a.world_points(), axis=1)
        assert np.all(miss <= bound), float((miss / bound).max())


@pytest.mark.parametrize("name", ["a.bag", "f_folder"])  # Livox CustomMsg, PointCloud2
def test_period_recuts_a_bags_frames_by_the_points_times(
    recorded: dict[str, Any], name: str
) -> None:
    """``--period`` T re-cuts the messages (0.1 s each): every point lands in the frame
    [kT, (k + 1)T) its time falls in, none lost; T = 0.1 s gives the messages back.
    (PointCloud2 times are float64 nanoseconds, ~0.3 µs: a point that close to a cut
    may fall on either side.)"""
    path = recorded["folder"] / name
    messages = list(open_recording(path).frames())
    t = np.concatenate([f.t for f in messages])
    for period in (0.1, 0.05, 0.25):
        rec = open_recording(path, ReplayOptions(period_s=period))
        frames = list(rec.frames())
        k = np.floor(t / period).astype(int)  # the frame each point belongs to
        edge = np.abs(t / period - np.rint(t / period)) * period < 1e-6  # near a cut
        assert [round(f.stamp / period) for f in frames] == sorted(set(k.tolist()))
        assert sum(len(f) for f in frames) == len(t)
        for f in frames:
            i = round(f.stamp / period)
            assert f.duration == pytest.approx(period, abs=1e-9)
            assert np.all((f.t >= f.stamp - 1e-6) & (f.t < f.end + 1e-6))
            near = np.count_nonzero(edge & ((k == i) | (k == i - 1) | (k == i + 1)))
            assert abs(len(f) - np.count_nonzero(k == i)) <= near
        assert rec.skipped == {}
    again = list(open_recording(path, ReplayOptions(period_s=0.1)).frames())
    assert len(again) == len(messages) == 25
    for a, b in zip(messages, again, strict=True):
        assert b.stamp == pytest.approx(a.stamp, abs=1e-9)
        np.testing.assert_allclose(b.world_points(), a.world_points(), atol=1e-6)


def test_period_is_refused_for_points_without_times(tmp_path: Path) -> None:
    """Clouds with no time field cannot be re-cut: ``--period`` is refused with the
    reason, unless it is the messages' own period (0.1 s here)."""
    xyz = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)]
    clouds = [(xyz, np.arange(30, dtype="<f4").tobytes(), 10, 12)] * 4
    path = tmp_path / "points"
    _write_pc2_bag(path, clouds)
    with pytest.raises(RecordingError) as err:
        open_recording(path, ReplayOptions(period_s=0.05))
    assert "--period 0.05 s cannot re-cut /points" in str(err.value)
    assert "no per-point time field (offset_time, t, time, timestamp)" in str(err.value)
    assert "0.1 s apart by their stamps" in str(err.value)
    frames = list(open_recording(path, ReplayOptions(period_s=0.1)).frames())
    assert [f.stamp for f in frames] == pytest.approx([0.0, 0.1, 0.2, 0.3])


def test_sensor_pose_is_ignored_with_a_warning_where_tf_gives_the_pose(
    recorded: dict[str, Any], tmp_path: Path
) -> None:
    """A bag whose /tf places its LiDAR: the frames keep /tf's poses and the recording
    says that --sensor-pose is ignored.  Without /tf, the pose is used, and no warning."""
    shifted = np.eye(4)
    shifted[:3, 3] = (5.0, 0.0, 0.0)
    path = recorded["folder"] / "a.bag"
    plain = list(open_recording(path).frames())
    rec = open_recording(path, ReplayOptions(sensor_pose=shifted))
    given = list(rec.frames())
    for a, b in zip(plain, given, strict=True):
        np.testing.assert_array_equal(a.poses, b.poses)
    assert rec.pose_warning == (
        "a.bag's /tf gives the pose of its LiDAR frame 'lidar' (the chain from 'world'), "
        "so --sensor-pose is ignored"
    )
    xyz = [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)]
    bare = tmp_path / "points"
    _write_pc2_bag(bare, [(xyz, np.arange(30, dtype="<f4").tobytes(), 10, 12)] * 2)
    rec = open_recording(bare, ReplayOptions(sensor_pose=shifted))
    np.testing.assert_array_equal(next(iter(rec.frames())).poses[0], shifted)
    assert rec.pose_warning is None
