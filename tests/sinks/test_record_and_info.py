"""``record`` writes what ``info`` and ``track`` read back, whatever the file is called.

Recordings are recognised by their content (``io.magic``), the container follows
the ``--out`` suffix unless ``--format`` says otherwise (a mismatch is refused), and
``info`` lists any MCAP file, Foxglove's own included.
"""

from __future__ import annotations

import json
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest

from dronetrack.cli.main import run
from dronetrack.formats.magic import sniff_file
from dronetrack.formats.pcd import write_pcd

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _err_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: "), err
    assert len(err.splitlines()) == 1, err
    return err


def _metrics(folder: Path) -> dict[str, object]:
    data: dict[str, object] = json.loads((folder / "metrics.json").read_text())
    return data


@pytest.fixture(scope="module")
def flights(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """One 2 s flight (12 s with the scan) in each container, under misleading names."""
    folder = tmp_path_factory.mktemp("flights")
    made = {}
    for fmt, name in (("ros1", "a.bag"), ("ros2-mcap", "b.mcap"), ("ros2-sqlite3", "c.db3")):
        path = folder / name
        assert run(["record", "--format", fmt, "--duration", "2", "--out", str(path)]) == 0
        made[fmt] = path
    return made


@pytest.mark.parametrize("fmt", ["ros1", "ros2-mcap", "ros2-sqlite3"])
@pytest.mark.slow
def test_a_recording_is_read_by_its_content_not_its_name(
    fmt: str, flights: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    original = flights[fmt]
    for name in ("flight", "flight.dat"):
        renamed = tmp_path / name
        shutil.copyfile(original, renamed)
        assert run(["info", str(renamed)]) == 0
        assert "/livox/lidar" in capsys.readouterr().out
        out = tmp_path / f"track-{name}"
        assert run(["track", str(renamed), "--out", str(out)]) == 0
        assert _metrics(out)["frames"] == 20
        renamed.unlink()


def test_record_without_a_suffix_writes_a_ros1_bag_that_reads_back(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "flight"
    assert run(["record", "--duration", "1", "--out", str(path)]) == 0
    assert sniff_file(path) == "ros1"
    capsys.readouterr()
    assert run(["info", str(path)]) == 0
    assert "(ros1," in capsys.readouterr().out
    assert run(["track", str(path), "--out", str(tmp_path / "t")]) == 0


@pytest.mark.parametrize(
    ("suffix", "kind"), [(".bag", "ros1"), (".mcap", "mcap"), (".db3", "sqlite3")]
)
@pytest.mark.slow
def test_the_suffix_chooses_the_container(suffix: str, kind: str, tmp_path: Path) -> None:
    path = tmp_path / f"flight{suffix}"
    assert run(["record", "--duration", "0.5", "--out", str(path)]) == 0
    assert path.is_file()
    assert sniff_file(path) == kind


@pytest.mark.parametrize(
    ("fmt", "name", "implied"),
    [
        ("ros1", "x.mcap", "ros2-mcap"),
        ("ros1", "x.db3", "ros2-sqlite3"),
        ("ros2-mcap", "x.bag", "ros1"),
        ("ros2-sqlite3", "x.mcap", "ros2-mcap"),
    ],
)
def test_a_format_the_suffix_contradicts_is_refused(
    fmt: str, name: str, implied: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / name
    assert run(["record", "--format", fmt, "--duration", "0.5", "--out", str(out)]) == 2
    line = _err_line(capsys)
    assert f"--format {fmt}" in line
    assert f"--format {implied}" in line  # the way out
    assert not out.exists()


def test_a_ros2_format_without_a_suffix_writes_a_rosbag2_folder(tmp_path: Path) -> None:
    out = tmp_path / "flight"
    assert run(["record", "--format", "ros2-mcap", "--duration", "0.5", "--out", str(out)]) == 0
    assert (out / "metadata.yaml").is_file()


def test_record_creates_folders_and_says_what_it_wrote(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "new" / "deeper" / "flight.mcap"
    assert run(["record", "--duration", "1", "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    size_mb = out.stat().st_size / 1e6
    wrote = [line for line in printed.splitlines() if line.startswith("wrote ")]
    assert wrote == [f"wrote {out}: ROS 2 bag, MCAP storage, 110 frames, 11.0 s, {size_mb:.1f} MB"]
    for topic in ("/livox/lidar", "/tf", "/tf_static", "/ground_truth/pose", "/dronetrack/config"):
        assert any(line.split()[:1] == [topic] for line in printed.splitlines()), topic


def test_record_takes_the_options_of_simulate(tmp_path: Path) -> None:
    bag = tmp_path / "flight.bag"
    args = [
        "record",
        "--duration",
        "1",
        "--sensor",
        "mid40",
        "--drone",
        "f550",
        "--visibility",
        "800",
        "--particles",
        "321",
        "--turret",
        "fixed",
        "--out",
        str(bag),
    ]
    assert run(args) == 0
    out = tmp_path / "track"
    assert run(["track", str(bag), "--out", str(out)]) == 0
    cfg = tomllib.loads((out / "config.toml").read_text())  # the configuration the bag carried
    assert cfg["sensor"]["model"] == "mid40"
    assert cfg["drone"]["model"] == "f550"
    assert cfg["weather"]["visibility_m"] == 800.0
    assert cfg["pipeline"]["tracker"]["particles"] == 321
    assert cfg["pipeline"]["controller"]["mode"] == "fixed"


@pytest.mark.slow
def test_record_takes_a_config_file(tmp_path: Path) -> None:
    bag = tmp_path / "site.bag"
    site = str(EXAMPLES / "site.toml")
    assert run(["record", "--config", site, "--duration", "1", "--out", str(bag)]) == 0
    out = tmp_path / "track"
    assert run(["track", str(bag), "--out", str(out)]) == 0
    assert "site-example" in (out / "config.toml").read_text()


@pytest.mark.parametrize(
    ("fmt", "name"), [("ros1", "c.bag"), ("ros2-mcap", "c.mcap"), ("ros2-sqlite3", "folder")]
)
@pytest.mark.slow
def test_compressed_recordings_read_back_the_same(
    fmt: str, name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    common = ["--format", fmt, "--duration", "2"]
    plain, packed = tmp_path / f"plain-{name}", tmp_path / name
    assert run(["record", *common, "--out", str(plain)]) == 0
    assert run(["record", *common, "--compress", "--out", str(packed)]) == 0
    assert "compressed (" in capsys.readouterr().out
    for rec in (plain, packed):
        assert run(["track", str(rec), "--out", str(tmp_path / f"t-{rec.name}")]) == 0
    a, b = _metrics(tmp_path / f"t-{plain.name}"), _metrics(tmp_path / f"t-{packed.name}")
    for key in ("frames", "coverage_pct", "rmse_m", "target_points_total"):
        assert a[key] == b[key], key

    def size(p: Path) -> int:
        return sum(f.stat().st_size for f in p.rglob("*")) if p.is_dir() else p.stat().st_size

    # Measured: zstd takes 30 % off MCAP and 24 % off a sqlite3 folder, lz4 5 % off a
    # ROS 1 bag (float32 coordinates compress poorly).
    assert size(packed) < size(plain)


def test_a_compressed_bare_db3_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "x.db3"
    assert run(["record", "--compress", "--duration", "0.5", "--out", str(out)]) == 2
    assert "metadata.yaml" in _err_line(capsys)
    assert not out.exists()


@pytest.fixture(scope="module")
def foxglove_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """What ``simulate --foxglove`` writes for a 1 s flight: protobuf schemas, no profile."""
    folder = tmp_path_factory.mktemp("view")
    view = folder / "view.mcap"
    args = ["simulate", "--duration", "1", "--foxglove", str(view), "--out", str(folder / "r")]
    assert run(args) == 0
    return view


def test_info_lists_any_mcap_file_foxgloves_own_included(
    foxglove_file: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    assert run(["info", str(foxglove_file)]) == 0
    listing = capsys.readouterr().out
    rows = {line.split()[1]: line for line in listing.splitlines() if line.startswith("│ /")}
    # 110 frames (the 10 s scan and the 1 s flight); four transforms each on /tf.
    for topic, schema, count in (
        ("/lidar/points", "foxglove.PointCloud (protobuf)", 110),
        ("/track/markers", "foxglove.SceneUpdate (protobuf)", 110),
        ("/tf", "foxglove.FrameTransform (protobuf)", 440),
    ):
        assert schema in rows[topic]
        assert rows[topic].split("│")[3].strip() == str(count)
    assert "no profile" in listing


def test_a_truncated_mcap_is_called_truncated_with_the_way_to_recover_it(
    flights: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(flights["ros2-mcap"].read_bytes()[:-50_000])
    for command in ("info", "track"):
        assert run([command, str(cut)]) == 2
        line = _err_line(capsys)
        assert "truncated" in line
        assert f"mcap recover {cut}" in line
        assert "magic is invalid" not in line


def test_random_bytes_named_bag_get_words_not_a_codec_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    fake = tmp_path / "fake.bag"
    fake.write_bytes(np.random.default_rng(3).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    for command in ("info", "track"):
        assert run([command, str(fake)]) == 2
        line = _err_line(capsys)
        assert "codec" not in line
        assert "not a recording dronetrack reads" in line
        assert "#ROSBAG V2.0" in line
    empty = tmp_path / "empty.bag"
    empty.write_bytes(b"")
    assert run(["info", str(empty)]) == 2
    assert "is empty" in _err_line(capsys)


def _pcd_cloud(path: Path) -> None:
    rng = np.random.default_rng(0)
    arr = np.zeros(200, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    for axis in ("x", "y", "z"):
        arr[axis] = rng.normal(10.0, 1.0, 200)
    write_pcd(path, arr)


def test_no_pose_source_is_a_warning_on_screen_and_in_metrics(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = tmp_path / "clouds"
    folder.mkdir()
    for k in range(5):
        _pcd_cloud(folder / f"{k:03d}.pcd")
    assert run(["track", str(folder), "--background-from", "0", "--out", str(tmp_path / "a")]) == 0
    err = capsys.readouterr().err
    warnings = [line for line in err.splitlines() if line.startswith("warning: ")]
    assert len(warnings) == 1, err
    assert "identity" in warnings[0]
    assert "--sensor-pose" in warnings[0]
    assert _metrics(tmp_path / "a")["warnings"] == [warnings[0].removeprefix("warning: ")]
    # With the pose given, nothing is assumed.
    pose = ["--sensor-pose", "0,0,1,0,0,0"]
    args = ["track", str(folder), "--background-from", "0", *pose, "--out", str(tmp_path / "b")]
    assert run(args) == 0
    assert "warning:" not in capsys.readouterr().err
    assert "warnings" not in _metrics(tmp_path / "b")


def test_a_bag_without_tf_warns_of_the_identity_pose(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    T = ts.types
    path = tmp_path / "points"
    xyz = np.random.default_rng(1).normal(10.0, 1.0, (50, 3)).astype("<f4")
    fields = [
        T["sensor_msgs/msg/PointField"](name=n, offset=4 * k, datatype=7, count=1)
        for k, n in enumerate("xyz")
    ]
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conn = w.add_connection("/points", "sensor_msgs/msg/PointCloud2", typestore=ts)
        for k in range(5):
            stamp = T["builtin_interfaces/msg/Time"](sec=100, nanosec=k * 100_000_000)
            msg = T["sensor_msgs/msg/PointCloud2"](
                header=T["std_msgs/msg/Header"](stamp=stamp, frame_id="velodyne"),
                height=1,
                width=50,
                fields=fields,
                is_bigendian=False,
                point_step=12,
                row_step=600,
                data=np.frombuffer(xyz.tobytes(), np.uint8),
                is_dense=True,
            )
            raw = ts.serialize_cdr(msg, "sensor_msgs/msg/PointCloud2")
            w.write(conn, 100 * 10**9 + k * 100_000_000, raw)
    assert run(["track", str(path), "--background-from", "0", "--out", str(tmp_path / "r")]) == 0
    err = capsys.readouterr().err
    assert "warning: points has no /tf for its LiDAR frame 'velodyne'" in err
    assert "warnings" in _metrics(tmp_path / "r")


def test_a_cut_or_unclosed_ros1_bag_says_so_with_the_way_to_repair_it(
    flights: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = flights["ros1"].read_bytes()
    cut = tmp_path / "cut.bag"
    cut.write_bytes(data[: len(data) // 2])
    # The ROS bag 2.0 file header: index_pos, 8 bytes, 0 until the bag is closed.
    unclosed = tmp_path / "unclosed.bag"
    at = data.index(b"index_pos=") + len(b"index_pos=")
    unclosed.write_bytes(data[:at] + bytes(8) + data[at + 8 :])
    for path, words in ((cut, "is truncated"), (unclosed, "was never closed")):
        assert run(["info", str(path)]) == 2
        line = _err_line(capsys)
        assert words in line
        assert "rosbag reindex" in line


def test_an_mcap_of_another_profile_is_listed_but_not_replayed(
    foxglove_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capsys.readouterr()
    assert run(["track", str(foxglove_file), "--out", str(tmp_path / "t")]) == 2
    line = _err_line(capsys)
    assert "not a ROS 2 bag" in line
    assert "dronetrack info" in line


def test_info_counts_an_mcap_without_a_summary_by_reading_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A writer that leaves out the summary section (statistics): the counts come from
    the messages themselves; a channel without a schema is listed as such."""
    from mcap.writer import IndexType, Writer

    path = tmp_path / "plain.mcap"
    with path.open("wb") as fh:
        w = Writer(
            fh,
            index_types=IndexType.NONE,
            use_chunking=False,
            use_statistics=False,
            use_summary_offsets=False,
            repeat_channels=False,
            repeat_schemas=False,
        )
        w.start(profile="", library="a test")
        schema = w.register_schema("test.Reading", "jsonschema", b"{}")
        readings = w.register_channel("/readings", "json", schema)
        notes = w.register_channel("/notes", "text", 0)
        for k in range(7):
            w.add_message(readings, log_time=10**9 + k * 10**8, data=b"{}", publish_time=0)
        for k in range(3):
            w.add_message(notes, log_time=2 * 10**9 + k, data=b"hi", publish_time=0)
        w.finish()
    assert run(["info", str(path)]) == 0
    listing = capsys.readouterr().out
    rows = {line.split()[1]: line for line in listing.splitlines() if line.startswith("│ /")}
    assert "test.Reading (jsonschema)" in rows["/readings"]
    assert rows["/readings"].split("│")[3].strip() == "7"
    assert "(no schema), text" in rows["/notes"]
    assert rows["/notes"].split("│")[3].strip() == "3"
    assert "1.000 s" in listing  # from the first message (1 s) to the last (2 s)
