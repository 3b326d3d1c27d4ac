"""The viewer writers: what the files hold, read back, and the missing-extra hints.

The MCAP summary (topics, schemas, message counts, time range) is parsed here
with the standard library; the decoded point clouds and transforms of the MCAP
and the whole ``.rrd`` are read back with rerun-sdk's readers (``rerun.chunk``).
"""

from __future__ import annotations

import dataclasses
import struct
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from dronetrack.errors import ConfigError, InputError, MissingExtraError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sinks.view import (
    EstimateTrail,
    NamedTransform,
    ViewFrame,
    checked,
    subsample_particles,
    world_poses,
    xyz,
)
from dronetrack.sinks.viewers import close_viewers, open_viewers

START = 1_700_000_000.0  # a replay's clock [s since the epoch]
N_FRAMES = 5
N_PARTICLES = 5000  # → every 3rd particle, 1,667 drawn


def _rigid(translation: list[float], yaw: float) -> FloatArray:
    c, s = np.cos(yaw), np.sin(yaw)
    m = np.eye(4)
    m[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    m[:3, 3] = translation
    return m


def _frames() -> list[ViewFrame]:
    """Frame 2 has no estimate, frame 4 no truth, frame 0 no foreground; odd frames have
    particles."""
    rng = np.random.default_rng(7)
    frames = []
    for i in range(N_FRAMES):
        frames.append(
            ViewFrame(
                t=0.1 * i,
                points=rng.normal(size=(100 + i, 3)),
                foreground=rng.normal(size=(4 + i, 3)) if i else np.empty((0, 3)),
                estimate=None if i == 2 else np.array([10.0 + i, 2.0, 5.0]),
                tracked=i > 2,
                truth=None if i == 4 else np.array([10.0 + i, 2.5, 5.0]),
                particles=rng.normal(size=(N_PARTICLES, 3)) if i % 2 else None,
                transforms=(
                    NamedTransform("world", "turret_pan", _rigid([0.0, 0.0, 1.0], 0.1 * i)),
                    NamedTransform("turret_pan", "lidar", _rigid([0.1, 0.0, 0.2], 0.0)),
                ),
            )
        )
    return frames


# ---------------------------------------------------------------- MCAP summary


MAGIC = b"\x89MCAP0\r\n"
OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_STATISTICS = 0x02, 0x03, 0x04, 0x0B


@dataclass
class McapSummary:
    topics: dict[int, str]  # channel id → topic
    schema_of: dict[str, str]  # topic → schema name
    counts: dict[str, int]  # topic → messages
    start_ns: int
    end_ns: int


class _Cursor:
    def __init__(self, data: bytes, at: int = 0) -> None:
        self.data, self.at = data, at

    def take(self, fmt: str) -> Any:
        (value,) = struct.unpack_from("<" + fmt, self.data, self.at)
        self.at += struct.calcsize("<" + fmt)
        return value

    def text(self) -> str:
        n = self.take("I")
        self.at += n
        return self.data[self.at - n : self.at].decode()


def _read_summary(path: Path) -> McapSummary:
    """Schemas, channels and statistics from the (uncompressed) summary section."""
    data = path.read_bytes()
    assert data[:8] == MAGIC
    assert data[-8:] == MAGIC  # a finished file
    footer = len(data) - 8 - (1 + 8 + 20)
    assert data[footer] == OP_FOOTER
    summary_start, summary_offsets = struct.unpack_from("<QQ", data, footer + 9)
    end = summary_offsets or footer
    schemas: dict[int, str] = {}
    channels: dict[int, tuple[str, int]] = {}
    counts: dict[int, int] = {}
    times = (0, 0)
    at = summary_start
    while at < end:
        op, length = struct.unpack_from("<BQ", data, at)
        body = _Cursor(data, at + 9)
        if op == OP_SCHEMA:
            schema_id = body.take("H")
            schemas[schema_id] = body.text()
        elif op == OP_CHANNEL:
            channel_id, schema_id = body.take("H"), body.take("H")
            channels[channel_id] = (body.text(), schema_id)
        elif op == OP_STATISTICS:
            body.at += 8 + 2 + 4 + 4 + 4 + 4  # message, schema, channel, ... counts
            times = (body.take("Q"), body.take("Q"))
            stop = body.at + 4 + body.take("I")
            while body.at < stop:
                channel_id = body.take("H")
                counts[channel_id] = body.take("Q")
        at += 9 + length
    return McapSummary(
        topics={cid: topic for cid, (topic, _) in channels.items()},
        schema_of={topic: schemas[sid] for topic, sid in channels.values()},
        counts={channels[cid][0]: n for cid, n in counts.items()},
        start_ns=times[0],
        end_ns=times[1],
    )


def _write_mcap(path: Path, frames: list[ViewFrame], start: float = START) -> None:
    from dronetrack.sinks.foxglove.mcap_file import FoxgloveWriter

    with FoxgloveWriter(path, start=start) as writer:
        for frame in frames:
            writer.log(frame)


def test_mcap_has_the_documented_topics_schemas_and_times(tmp_path: Path) -> None:
    pytest.importorskip("foxglove")
    from dronetrack.sinks.foxglove.mcap_file import TOPICS

    path = tmp_path / "run.mcap"
    _write_mcap(path, _frames())
    summary = _read_summary(path)
    assert sorted(summary.topics.values()) == sorted(TOPICS)
    assert summary.schema_of == {
        "/lidar/points": "foxglove.PointCloud",
        "/lidar/foreground": "foxglove.PointCloud",
        "/track/particles": "foxglove.PointCloud",
        "/track/markers": "foxglove.SceneUpdate",
        "/tf": "foxglove.FrameTransform",
    }
    per_frame = {topic: N_FRAMES for topic in TOPICS}
    assert summary.counts == {**per_frame, "/tf": 2 * N_FRAMES}
    assert summary.start_ns == round(START * 1e9)
    assert summary.end_ns == round((START + 0.1 * (N_FRAMES - 1)) * 1e9)


def _pylist(batch: Any) -> list[dict[str, Any]]:
    """A record batch as rows, with times as integer nanoseconds."""
    import pyarrow as pa

    columns = [
        col.cast(pa.int64()) if pa.types.is_temporal(col.type) else col for col in batch.columns
    ]
    rows: list[dict[str, Any]] = pa.RecordBatch.from_arrays(columns, batch.schema.names).to_pylist()
    return rows


def _mcap_rows(path: Path) -> dict[str, list[dict[str, Any]]]:
    """Decoded messages per topic, in log-time order (rerun's MCAP reader)."""
    from rerun.chunk import McapReader

    rows: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for chunk in McapReader(path).stream():
        if not chunk.is_static:
            rows[chunk.entity_path].extend(_pylist(chunk.to_record_batch()))
    for topic_rows in rows.values():
        topic_rows.sort(key=lambda row: row["message_log_time"])
    return rows


def test_mcap_point_clouds_and_transforms_read_back(tmp_path: Path) -> None:
    pytest.importorskip("foxglove")
    pytest.importorskip("rerun")
    frames = _frames()
    path = tmp_path / "run.mcap"
    _write_mcap(path, frames)
    rows = _mcap_rows(path)

    points = rows["/lidar/points"]
    assert len(points) == N_FRAMES
    for frame, row in zip(frames, points, strict=True):
        assert row["message_log_time"] == round((START + frame.t) * 1e9)
        expected = frame.points.astype(np.float32)
        np.testing.assert_array_equal(np.array(row["Points3D:positions"]), expected)
        assert row["CoordinateFrame:frame"] == ["world"]
    assert rows["/lidar/foreground"][0]["Points3D:positions"] == []  # an empty cloud

    particles = rows["/track/particles"]
    assert [len(row["Points3D:positions"]) for row in particles] == [0, 1667, 0, 1667, 0]
    expected = frames[1].particles[::3].astype(np.float32)  # type: ignore[index]
    np.testing.assert_array_equal(np.array(particles[1]["Points3D:positions"]), expected)

    tf = [row for row in rows["/tf"] if row["Transform3D:child_frame"] == ["turret_pan"]]
    assert len(tf) == N_FRAMES
    assert tf[-1]["Transform3D:parent_frame"] == ["world"]
    np.testing.assert_allclose(tf[-1]["Transform3D:translation"], [[0.0, 0.0, 1.0]])
    yaw = 0.1 * 4
    xyzw = [0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)]
    np.testing.assert_allclose(tf[-1]["Transform3D:quaternion"], [xyzw], atol=1e-7)
    assert len(rows["/track/markers"]) == N_FRAMES


def test_two_mcap_writers_in_one_process_keep_their_own_messages(tmp_path: Path) -> None:
    pytest.importorskip("foxglove")
    from dronetrack.sinks.foxglove.mcap_file import FoxgloveWriter

    frames = _frames()
    a, b = tmp_path / "a.mcap", tmp_path / "b.mcap"
    with FoxgloveWriter(a) as wa, FoxgloveWriter(b) as wb:
        for frame in frames:
            wa.log(frame)
        wb.log(frames[0])
    assert _read_summary(a).counts["/lidar/points"] == N_FRAMES
    assert _read_summary(b).counts["/lidar/points"] == 1
    _write_mcap(a, frames[:2], start=0.0)  # overwrites, and a sim starts at the epoch
    summary = _read_summary(a)
    assert summary.counts["/lidar/points"] == 2
    assert summary.start_ns == 0


# ---------------------------------------------------------------- rerun


def _write_rrd(path: Path, frames: list[ViewFrame], start: float = START) -> None:
    from dronetrack.sinks.rerun_out import RerunWriter

    with RerunWriter(path, start=start) as writer:
        for frame in frames:
            writer.log(frame)


def _rrd_rows(path: Path) -> dict[str, list[dict[str, Any]]]:
    """Rows per entity path, static rows first, then by frame (rerun's RRD reader).

    ``store()`` reads the footer's manifest, so this also checks the file was finished.
    """
    from rerun.chunk import RrdReader

    rows: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for chunk in RrdReader(path).store().stream():
        rows[chunk.entity_path].extend(_pylist(chunk.to_record_batch()))
    for entity_rows in rows.values():
        entity_rows.sort(key=lambda row: row.get("frame", -1))
    return rows


def test_rrd_has_the_documented_entities_rows_and_values(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    from dronetrack.sinks.rerun_out import ENTITY_PATHS

    frames = _frames()
    path = tmp_path / "run.rrd"
    _write_rrd(path, frames)
    rows = _rrd_rows(path)
    frame_paths = {"/world/frames/turret_pan", "/world/frames/lidar"}
    assert {"/" + p for p in ENTITY_PATHS} | frame_paths <= set(rows)

    assert len(rows["/world"]) == 1  # the static view coordinates
    for entity in ("/world/lidar/points", "/world/lidar/foreground", "/world/track/particles"):
        assert [row["frame"] for row in rows[entity]] == list(range(N_FRAMES))
    points = rows["/world/lidar/points"]
    np.testing.assert_allclose(
        np.array(points[3]["Points3D:positions"]), frames[3].points, atol=1e-6
    )
    assert points[3]["time"] == round(0.3 * 1e9)
    assert points[3]["timestamp"] == round((START + 0.3) * 1e9)
    assert rows["/world/lidar/foreground"][0]["Points3D:positions"] == []
    assert [len(r["Points3D:positions"]) for r in rows["/world/track/particles"]] == [
        0,
        1667,
        0,
        1667,
        0,
    ]

    estimate = rows["/world/track/estimate"]
    assert [row.get("Clear:is_recursive") is not None for row in estimate] == [
        False,
        False,
        True,  # frame 2 has no estimate: cleared
        False,
        False,
    ]
    trail = [row.get("LineStrips3D:strips") for row in rows["/world/track/trail"]]
    assert [None if s is None else len(s[0]) for s in trail] == [None, 2, None, None, 2]

    truth = rows["/world/truth"]
    assert [row.get("Clear:is_recursive") is not None for row in truth] == [False] * 4 + [True]
    errors = rows["/plots/error_m"]
    assert [row["frame"] for row in errors] == [0, 1, 3]
    assert all(row["Scalars:scalars"] == pytest.approx([0.5]) for row in errors)
    assert [row["Scalars:scalars"] for row in rows["/plots/n_foreground"]] == [
        [0.0],
        [5.0],
        [6.0],
        [7.0],
        [8.0],
    ]

    lidar = rows["/world/frames/lidar"][4]  # composed: world_T_pan @ pan_T_lidar
    expected = world_poses(frames[4].transforms)["lidar"]
    np.testing.assert_allclose(lidar["Transform3D:translation"], [expected[:3, 3]], atol=1e-6)
    mat = np.array(lidar["Transform3D:mat3x3"]).reshape(3, 3).T  # stored column-major
    np.testing.assert_allclose(mat, expected[:3, :3], atol=1e-6)


def test_two_rrd_writers_in_one_process_write_separate_recordings(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    from rerun.chunk import RrdReader

    frames = _frames()
    a, b = tmp_path / "a.rrd", tmp_path / "b.rrd"
    _write_rrd(a, frames)
    _write_rrd(b, frames[:2], start=0.0)
    assert len(_rrd_rows(a)["/world/lidar/points"]) == N_FRAMES
    rows_b = _rrd_rows(b)
    assert len(rows_b["/world/lidar/points"]) == 2
    assert "timestamp" not in rows_b["/world/lidar/points"][0]  # no clock for a simulation
    [rec_a], [rec_b] = RrdReader(a).recordings(), RrdReader(b).recordings()
    assert rec_a.recording_id != rec_b.recording_id


def test_rerun_disabled_by_the_environment_is_refused(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    pytest.importorskip("rerun")
    from dronetrack.sinks.rerun_out import RerunWriter

    monkeypatch.setenv("RERUN", "off")
    with pytest.raises(ConfigError, match="RERUN"):
        RerunWriter(tmp_path / "run.rrd")
    pytest.importorskip("foxglove")
    fox = tmp_path / "run.mcap"
    with pytest.raises(ConfigError, match="RERUN"):
        open_viewers(fox, tmp_path / "run.rrd")
    assert _read_summary(fox).counts == {}  # the MCAP opened first was closed, not left open


def test_a_bad_frame_raises_and_writes_nothing(tmp_path: Path) -> None:
    pytest.importorskip("foxglove")
    pytest.importorskip("rerun")
    from dronetrack.sinks.foxglove.mcap_file import FoxgloveWriter
    from dronetrack.sinks.rerun_out import RerunWriter

    good = _frames()[1]
    bad_shape = dataclasses.replace(good, foreground=np.ones((4, 2)))
    bad_tree = dataclasses.replace(good, transforms=(NamedTransform("base", "lidar", np.eye(4)),))
    fox, rrd = tmp_path / "run.mcap", tmp_path / "run.rrd"
    with FoxgloveWriter(fox) as wf, RerunWriter(rrd) as wr:
        for writer in (wf, wr):
            writer.log(good)
            with pytest.raises(InputError, match="foreground must have shape"):
                writer.log(bad_shape)
        with pytest.raises(InputError, match="not connected to 'world'"):
            wr.log(bad_tree)  # rerun composes world poses; the MCAP keeps /tf as given
    assert set(_read_summary(fox).counts.values()) == {1, 2}  # /tf: 2 edges
    rows = _rrd_rows(rrd)
    assert all(len(rows[p]) == 1 for p in ("/world/lidar/points", "/plots/n_foreground"))


# ---------------------------------------------------------------- open / close


@pytest.mark.parametrize(
    ("module", "hint"),
    [
        ("foxglove", "--foxglove needs foxglove-sdk: pip install 'dronetrack[foxglove]'"),
        ("rerun", "--rerun needs rerun-sdk: pip install 'dronetrack[rerun]'"),
    ],
)
def test_a_missing_sdk_names_its_extra_and_leaves_no_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, module: str, hint: str
) -> None:
    monkeypatch.setitem(sys.modules, module, None)
    fox, rrd = tmp_path / "run.mcap", tmp_path / "run.rrd"
    with pytest.raises(MissingExtraError) as err:
        open_viewers(fox, rrd)
    assert str(err.value) == hint
    assert not fox.exists()
    assert not rrd.exists()


def test_open_and_close_viewers(tmp_path: Path) -> None:
    assert open_viewers(None, None) == []
    pytest.importorskip("foxglove")
    pytest.importorskip("rerun")
    fox, rrd = tmp_path / "out" / "run.mcap", tmp_path / "out" / "run.rrd"
    fox.parent.mkdir()
    fox.write_bytes(b"old")  # overwritten
    sinks = open_viewers(fox, rrd, start=START)
    assert len(sinks) == 2
    for frame in _frames():
        for sink in sinks:
            sink.log(frame)
    close_viewers(sinks)
    close_viewers(sinks)  # a second close does nothing
    assert _read_summary(fox).counts["/lidar/points"] == N_FRAMES
    assert len(_rrd_rows(rrd)["/world/lidar/points"]) == N_FRAMES
    with pytest.raises(ValueError, match="closed"):
        sinks[0].log(_frames()[0])


class _Failing:
    def __init__(self, closed: list[str], name: str, fail: bool) -> None:
        self.closed, self.name, self.fail = closed, name, fail

    def log(self, frame: ViewFrame) -> None:
        """Not used."""

    def close(self) -> None:
        self.closed.append(self.name)
        if self.fail:
            raise OSError(f"{self.name} failed")


def test_close_viewers_closes_all_then_raises_the_first_failure() -> None:
    closed: list[str] = []
    sinks = [_Failing(closed, "a", True), _Failing(closed, "b", True), _Failing(closed, "c", False)]
    with pytest.raises(OSError, match="a failed"):
        close_viewers(sinks)
    assert closed == ["a", "b", "c"]


# ---------------------------------------------------------------- shared helpers


def test_particles_are_subsampled_with_a_deterministic_stride() -> None:
    p = np.arange(3 * 4001, dtype=float).reshape(-1, 3)
    out = subsample_particles(p, limit=2000)
    np.testing.assert_array_equal(out, p[::3])
    assert len(out) <= 2000
    assert len(subsample_particles(p[:2000], limit=2000)) == 2000
    assert subsample_particles(None).shape == (0, 3)
    assert subsample_particles(np.empty((0, 3))).shape == (0, 3)


def test_the_trail_keeps_the_last_estimates_and_restarts_without_one() -> None:
    trail = EstimateTrail(length=3)
    for k in range(5):
        out = trail.update(np.array([k, 0.0, 0.0]))
    np.testing.assert_array_equal(out[:, 0], [2, 3, 4])
    assert trail.update(None).shape == (0, 3)
    assert trail.update(np.zeros(3)).shape == (1, 3)


def test_world_poses_compose_edges_in_any_order() -> None:
    pan = NamedTransform("world", "pan", _rigid([0.0, 0.0, 1.0], np.pi / 2))
    lidar = NamedTransform("pan", "lidar", _rigid([1.0, 0.0, 0.0], 0.0))
    poses = world_poses([lidar, pan])
    np.testing.assert_allclose(poses["lidar"][:3, 3], [0.0, 1.0, 1.0], atol=1e-12)
    assert set(poses) == {"pan", "lidar"}
    with pytest.raises(InputError, match="base->lidar"):
        world_poses([NamedTransform("base", "lidar", np.eye(4))])


def test_frames_are_checked_for_shapes() -> None:
    assert xyz(np.empty(0), "points").shape == (0, 3)
    assert xyz(np.ones(3), "estimate").shape == (1, 3)
    with pytest.raises(InputError, match=r"points must have shape \(N, 3\)"):
        xyz(np.ones((4, 2)), "points")
    frame = _frames()[1]
    ok = checked(dataclasses.replace(frame, points=np.empty(0), estimate=[1, 2, 3]))
    assert ok.points.shape == (0, 3)
    assert ok.estimate is not None
    assert ok.estimate.shape == (3,)
    with pytest.raises(InputError, match=r"estimate must have shape \(3,\)"):
        checked(dataclasses.replace(frame, estimate=np.ones((2, 3))))
    with pytest.raises(InputError, match=r"turret_pan->lidar is \(3, 3\)"):
        checked(
            dataclasses.replace(
                frame, transforms=(NamedTransform("turret_pan", "lidar", np.eye(3)),)
            )
        )
