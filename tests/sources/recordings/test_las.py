from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dronetrack.errors import MissingExtraError, RecordingError
from dronetrack.geometry.transforms import make_pose
from dronetrack.sources.recordings.las import LasRecording, read_las
from dronetrack.sources.recordings.recording import ReplayOptions

GPS0 = 1_300_000_000.0  # adjusted standard GPS time [s]


@pytest.fixture
def laspy() -> Any:
    return pytest.importorskip("laspy")


def _write(
    laspy: Any, path: Path, n: int = 400, point_format: int = 3, seed: int = 0
) -> dict[str, np.ndarray]:
    """A LAS/LAZ file of ``n`` points over 0.35 s, written in shuffled time order."""
    rng = np.random.default_rng(seed)
    header = laspy.LasHeader(point_format=point_format, version="1.2")
    header.scales = np.full(3, 0.001)
    header.offsets = np.array([100.0, -50.0, 0.0])
    las = laspy.LasData(header)
    xyz = np.column_stack(
        [rng.uniform(90.0, 110.0, n), rng.uniform(-60.0, -40.0, n), rng.uniform(0.0, 30.0, n)]
    )
    xyz = np.round(xyz, 3)
    las.x, las.y, las.z = xyz.T
    intensity = rng.integers(0, 65535, n).astype(np.uint16)
    las.intensity = intensity
    t = GPS0 + rng.uniform(0.0, 0.35, n)
    t[:1] = GPS0  # the earliest point
    if point_format in (1, 3):
        las.gps_time = t
    las.write(path)
    return {"xyz": xyz, "intensity": intensity, "t": t}


def test_frames_by_gps_time(laspy: Any, tmp_path: Path) -> None:
    data = _write(laspy, tmp_path / "scan.las")
    rec = LasRecording(tmp_path / "scan.las", ReplayOptions())
    frames = list(rec.frames())
    assert rec.origin == GPS0
    assert rec.period == 0.1
    assert [f.stamp for f in frames] == pytest.approx([0.0, 0.1, 0.2, 0.3])
    rel = data["t"] - GPS0
    expected = [int(np.count_nonzero(np.floor(rel / 0.1) == k)) for k in range(4)]
    assert [len(f) for f in frames] == expected
    for f in frames:
        assert np.all((f.t >= f.stamp - 1e-9) & (f.t < f.end + 1e-9))
        assert np.all(np.diff(f.t) >= 0)
        np.testing.assert_array_equal(f.line, 0)
        np.testing.assert_array_equal(f.poses[0], np.eye(4))
    points = np.concatenate([f.points for f in frames])
    times = np.concatenate([f.t for f in frames])
    order = np.argsort(rel, kind="stable")
    np.testing.assert_allclose(points, data["xyz"][order], atol=1e-9)
    np.testing.assert_allclose(times, rel[order], atol=1e-6)
    intensity = np.concatenate([f.intensity for f in frames])
    np.testing.assert_array_equal(intensity, data["intensity"][order].astype(np.float32))
    assert not rec.skipped


def test_period_and_sensor_pose_options(laspy: Any, tmp_path: Path) -> None:
    _write(laspy, tmp_path / "scan.las")
    pose = make_pose(np.eye(3), [0.0, 0.0, 2.0])
    rec = LasRecording(tmp_path / "scan.las", ReplayOptions(period_s=0.2, sensor_pose=pose))
    frames = list(rec.frames())
    assert [f.stamp for f in frames] == pytest.approx([0.0, 0.2])
    assert all(f.duration == 0.2 for f in frames)
    np.testing.assert_array_equal(frames[0].poses[0], pose)


def test_points_without_a_finite_time_are_skipped(laspy: Any, tmp_path: Path) -> None:
    data = _write(laspy, tmp_path / "scan.las", n=100)
    las = laspy.read(tmp_path / "scan.las")
    gps_time = np.array(las.gps_time)
    gps_time[[3, 7]] = np.nan
    las.gps_time = gps_time
    las.write(tmp_path / "scan.las")
    rec = LasRecording(tmp_path / "scan.las", ReplayOptions())
    assert rec.skipped == {"no_time": 2}
    assert sum(len(f) for f in rec.frames()) == 98
    assert rec.origin == float(np.delete(data["t"], [3, 7]).min())


def test_without_gps_time_the_file_is_one_frame(laspy: Any, tmp_path: Path) -> None:
    data = _write(laspy, tmp_path / "scan.las", n=50, point_format=0)
    rec = LasRecording(tmp_path / "scan.las", ReplayOptions())
    (frame,) = rec.frames()
    assert rec.origin == 0.0
    assert frame.stamp == 0.0
    np.testing.assert_array_equal(frame.t, 0.0)
    np.testing.assert_allclose(frame.points, data["xyz"], atol=1e-9)
    assert rec.info().topics[0].msgtype == "las/point-format-0"


def test_laz(laspy: Any, tmp_path: Path) -> None:
    pytest.importorskip("lazrs")
    data = _write(laspy, tmp_path / "scan.laz", n=100)
    rec = LasRecording(tmp_path / "scan.laz", ReplayOptions())
    assert sum(len(f) for f in rec.frames()) == 100
    info = rec.info()
    assert info.topics[0].msgtype == "laz/point-format-3"
    assert info.duration_s == pytest.approx(float(np.ptp(data["t"])))


def test_read_las_in_chunks(laspy: Any, tmp_path: Path) -> None:
    data = _write(laspy, tmp_path / "scan.las", n=250)
    points = read_las(tmp_path / "scan.las", chunk_points=64)
    np.testing.assert_allclose(points.xyz, data["xyz"], atol=1e-9)
    assert points.gps_time is not None
    np.testing.assert_array_equal(points.gps_time, data["t"])
    assert (points.point_format, points.version) == (3, "1.2")


def test_info(laspy: Any, tmp_path: Path) -> None:
    data = _write(laspy, tmp_path / "scan.las")
    info = LasRecording(tmp_path / "scan.las", ReplayOptions()).info()
    assert info.kind == "las"
    assert info.start == GPS0
    assert info.duration_s == pytest.approx(float(np.ptp(data["t"])))
    assert [(t.topic, t.msgtype, t.count) for t in info.topics] == [
        ("scan.las", "las/point-format-3", 4)
    ]


def test_errors(laspy: Any, tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="does not exist"):
        LasRecording(tmp_path / "missing.las", ReplayOptions())
    (tmp_path / "scan.txt").write_text("1 2 3")
    with pytest.raises(RecordingError, match="not a LAS or LAZ file"):
        LasRecording(tmp_path / "scan.txt", ReplayOptions())
    (tmp_path / "junk.las").write_bytes(b"LASF" + bytes(50))
    with pytest.raises(RecordingError, match="cannot read"):
        LasRecording(tmp_path / "junk.las", ReplayOptions())
    _write(laspy, tmp_path / "empty.las", n=0)
    with pytest.raises(RecordingError, match="has no points"):
        LasRecording(tmp_path / "empty.las", ReplayOptions())


def test_missing_laspy_names_the_extra(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    (tmp_path / "scan.las").write_bytes(b"LASF")
    monkeypatch.setitem(sys.modules, "laspy", None)  # makes "import laspy" fail
    with pytest.raises(MissingExtraError, match=r"dronetrack\[las\]"):
        LasRecording(tmp_path / "scan.las", ReplayOptions())
