from __future__ import annotations

import logging
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from dronetrack.errors import RecordingError
from dronetrack.geometry.transforms import make_pose
from dronetrack.sinks.strategy_logs import StrategyLogger
from dronetrack.sources.recordings.field_logs import FieldLogRecording, read_points_csv
from dronetrack.sources.recordings.recording import ReplayOptions

PERIOD = 0.1


def _log_run(folder: Path, clouds: list[np.ndarray]) -> None:
    """Write logs with the real logger; frame k ends at 0.1 · (k + 1) s."""
    logger = StrategyLogger(folder)
    for k, cloud in enumerate(clouds):
        result = SimpleNamespace(t=PERIOD * (k + 1), foreground=cloud, estimate=None, phase="track")
        logger.write(None, result)  # type: ignore[arg-type]
    logger.close(SimpleNamespace(transitions=[(0.05, "scan", "track", "raster")]))


def _clouds() -> list[np.ndarray]:
    rng = np.random.default_rng(3)
    return [
        np.round(rng.uniform(-5.0, 5.0, (3, 3)), 4),
        np.round(rng.uniform(-5.0, 5.0, (2, 3)), 4),
        np.empty((0, 3)),  # no foreground: the logger writes no row
        np.round(rng.uniform(-5.0, 5.0, (4, 3)), 4),
    ]


def test_frames_from_the_logger(tmp_path: Path) -> None:
    clouds = _clouds()
    _log_run(tmp_path, clouds)
    pose = make_pose(np.eye(3), [1.0, 2.0, 3.0])
    rec = FieldLogRecording(tmp_path, ReplayOptions(sensor_pose=pose))
    frames = list(rec.frames())
    assert rec.period == pytest.approx(PERIOD)
    assert rec.origin == pytest.approx(0.0)  # the first frame ends at 0.1 s
    assert rec.ground_truth is None
    assert rec.config_text is None
    assert [f.stamp for f in frames] == pytest.approx([0.0, 0.1, 0.2, 0.3])
    assert [f.end for f in frames] == pytest.approx([0.1, 0.2, 0.3, 0.4])
    for frame, cloud in zip(frames, clouds, strict=True):
        np.testing.assert_allclose(frame.points, cloud, atol=1e-12)
        np.testing.assert_array_equal(frame.poses[0], np.eye(4))  # world frame already
        np.testing.assert_array_equal(frame.t, frame.stamp)
    assert not rec.skipped


def test_period_option(tmp_path: Path) -> None:
    _log_run(tmp_path, _clouds())
    rec = FieldLogRecording(tmp_path, ReplayOptions(period_s=0.05))
    assert rec.origin == pytest.approx(0.05)
    assert [f.stamp for f in rec.frames()] == pytest.approx([0.0, 0.1, 0.2, 0.3])
    assert all(f.duration == 0.05 for f in rec.frames())


def test_info_lists_every_csv(tmp_path: Path) -> None:
    _log_run(tmp_path, _clouds())
    info = FieldLogRecording(tmp_path, ReplayOptions()).info()
    assert info.kind == "field-logs"
    assert info.start == pytest.approx(0.0)
    assert info.duration_s == pytest.approx(0.3)
    assert {t.topic: (t.msgtype, t.count) for t in info.topics} == {
        "centroids.csv": ("csv(t,x,y,z)", 0),
        "ekf.csv": ("csv(t,x,y,z,vx,vy,vz,P11,P22,P33,P44,P55,P66)", 0),
        "filtered_points.csv": ("csv(t,x,y,z,seq)", 9),
        "states.csv": ("csv(t,from_state,to_state,strategy)", 1),
    }


def test_bad_rows_are_skipped_and_counted(tmp_path: Path, caplog: pytest.LogCaptureFixture) -> None:
    (tmp_path / "filtered_points.csv").write_text(
        "seq,t,x,y,z\n"  # columns are found by name
        "0,1.0,1,2,3\n"
        "0,1.0,4,5,6\n"
        "\n"
        "1,1.1,oops,5,6\n"
        "1.5,1.1,1,1,1\n"  # a sequence number must be an integer
        "1,1.1,nan,1,1\n"
        "2,1.2,7,8,9\n"
        "3,1.3,7,8\n"  # cut short
    )
    with caplog.at_level(logging.WARNING, logger="dronetrack.sources.recordings.field_logs"):
        rec = FieldLogRecording(tmp_path, ReplayOptions())
    frames = list(rec.frames())
    assert rec.skipped == {"bad_row": 4}
    assert "line 5" in caplog.text
    assert [len(f) for f in frames] == [2, 0, 1]
    assert rec.origin == pytest.approx(0.9)
    np.testing.assert_allclose([f.stamp for f in frames], [0.0, 0.1, 0.2], atol=1e-12)
    table, bad = read_points_csv(tmp_path / "filtered_points.csv")
    assert table.shape == (3, 5)
    assert bad == [5, 6, 7, 9]


def test_a_log_without_points_has_no_frames(tmp_path: Path) -> None:
    _log_run(tmp_path, [np.empty((0, 3))] * 3)
    rec = FieldLogRecording(tmp_path, ReplayOptions())
    assert list(rec.frames()) == []
    assert rec.info().duration_s == 0.0


def test_errors(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="is not a folder"):
        FieldLogRecording(tmp_path / "missing", ReplayOptions())
    with pytest.raises(RecordingError, match=r"no filtered_points\.csv"):
        FieldLogRecording(tmp_path, ReplayOptions())
    (tmp_path / "filtered_points.csv").write_text("time,x,y,z\n1,2,3,4\n")
    with pytest.raises(
        RecordingError, match=r"lacks the columns t, seq \(its header: time,x,y,z\)"
    ):
        FieldLogRecording(tmp_path, ReplayOptions())
    (tmp_path / "filtered_points.csv").write_bytes(b"t,x,y,z,seq\n\xff\xfe\x00")
    with pytest.raises(RecordingError, match="cannot read"):
        FieldLogRecording(tmp_path, ReplayOptions())
