"""``sources.recordings.lvx``: Livox Viewer files built by hand (``tests/lvx_files.py``) read as
recordings: frames, times, the extrinsics as the sensor pose, one device of several,
and one RecordingError for every truncated or corrupt file."""

from __future__ import annotations

import math
import struct
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import RecordingError
from dronetrack.sources.recordings.lvx import LvxRecording
from dronetrack.sources.recordings.opener import open_recording, recording_info
from dronetrack.sources.recordings.recording import ReplayOptions
from lvx_files import (
    T0,
    avia_records,
    lvx1_device,
    lvx1_package,
    lvx2_device,
    lvx2_package,
    lvx_file,
    private_header,
    public_header,
    sdk1_packet,
)

DT = 4167  # ns between an Avia's firings
YAW90 = (0.0, 0.0, 90.0, 1.0, 2.0, 3.0)  # roll, pitch, yaw [°], x, y, z [m]


def _x_mm(k: int) -> int:
    """Firing k returns 10 m + (k mod 1000) mm ahead; every fifth firing none."""
    return 0 if k % 5 == 4 else 10_000 + k % 1000


def _avia_packet(index: int, k0: int, t0: int = T0) -> bytes:
    """The package of firings k0 … k0 + 95 (data type 2), stamped with firing k0's time."""
    pts = [(_x_mm(k), 0, 0, 7, 0) if _x_mm(k) else (0, 0, 0, 0, 0) for k in range(k0, k0 + 96)]
    return lvx1_package(index, sdk1_packet(2, t0 + k0 * DT, avia_records(pts)))


def _avia_file(
    path: Path, ext: tuple[float, ...] = YAW90, enable: int = 1, frames: int = 2, per_frame: int = 5
) -> Path:
    """An Avia's LVX file: ``frames`` frames of ``per_frame`` consecutive packets."""
    head = (
        public_header((1, 1, 0, 0))
        + private_header(1)
        + lvx1_device(b"3GGDJ6K00100581", 0, 7, enable, ext)
    )
    bodies = [
        b"".join(_avia_packet(0, 96 * (f * per_frame + p)) for p in range(per_frame))
        for f in range(frames)
    ]
    path.write_bytes(lvx_file(head, bodies))
    return path


def test_avia_frames_points_times_and_extrinsic_pose(tmp_path: Path) -> None:
    """10 packets of 96 firings (4 ms), cut into 1 ms frames: every return at its firing's
    time, in the device's frame, and the pose is the extrinsics: yaw 90° at (1, 2, 3) m."""
    rec = open_recording(_avia_file(tmp_path / "a.dat"), ReplayOptions(period_s=0.001))
    assert isinstance(rec, LvxRecording)
    assert rec.origin == T0 / 1e9
    assert rec.pose_warning is None
    assert len(rec) == 4  # 960 firings · 4.167 µs = 4.0 ms
    frames = list(rec.frames())
    assert [f.stamp for f in frames] == pytest.approx([0.0, 0.001, 0.002, 0.003])
    t = np.concatenate([f.t for f in frames])
    k = np.rint(t * 1e9 / DT).astype(int)
    np.testing.assert_allclose(t, k * DT * 1e-9, atol=1e-12)
    np.testing.assert_array_equal(k, [k for k in range(960) if k % 5 != 4])  # every return, once
    xyz = np.concatenate([f.points for f in frames])
    np.testing.assert_allclose(xyz[:, 0], [_x_mm(int(i)) * 1e-3 for i in k], atol=1e-12)
    for f in frames:
        assert np.all((f.t >= f.stamp - 1e-12) & (f.t < f.stamp + f.duration))
        np.testing.assert_array_equal(f.intensity, 7)
        np.testing.assert_array_equal(f.line, (np.rint(f.t * 1e9 / DT).astype(int) % 96) % 6)
        # yaw 90° then (1, 2, 3): a return x m ahead lies at (1, 2 + x, 3)
        world = f.points @ f.poses[0][:3, :3].T + f.poses[0][:3, 3]
        np.testing.assert_allclose(
            world, np.c_[np.ones(len(f)), 2 + f.points[:, 0], np.full(len(f), 3.0)], atol=1e-6
        )
    assert rec.skipped == {}


def test_default_period_is_a_tenth_of_a_second(tmp_path: Path) -> None:
    rec = LvxRecording(_avia_file(tmp_path / "a.lvx"))
    assert rec.period == 0.1
    (frame,) = rec.frames()
    assert len(frame) == 768  # 960 firings, every fifth without a return


def test_pose_without_extrinsics_and_with_sensor_pose(tmp_path: Path) -> None:
    path = _avia_file(tmp_path / "off.lvx", enable=0)
    rec = LvxRecording(path)
    np.testing.assert_array_equal(rec.pose, np.eye(4))  # disabled: the values are ignored
    assert rec.pose_warning is not None
    assert "--sensor-pose" in rec.pose_warning
    P = np.eye(4)
    P[:3, 3] = (100.0, 0.0, 0.0)
    rec = LvxRecording(path, ReplayOptions(sensor_pose=P))
    np.testing.assert_array_equal(rec.pose, P)
    assert rec.pose_warning is None
    # enabled: world_T_sensor = P · E; the return 10 m ahead lies at (101, 12, 3)
    on = LvxRecording(_avia_file(tmp_path / "on.lvx"), ReplayOptions(sensor_pose=P))
    np.testing.assert_allclose(on.pose @ [10.0, 0.0, 0.0, 1.0], [101.0, 12.0, 3.0, 1.0], atol=1e-6)


def _two_device_file(path: Path) -> Path:
    head = public_header((1, 1, 0, 0)) + private_header(2)
    head += lvx1_device(b"AAAA", 0, 7, 0, YAW90) + lvx1_device(b"BBBB", 1, 1, 1, YAW90)
    mid40 = lvx1_package(
        1, sdk1_packet(0, T0, b"".join(struct.pack("<iiiB", 5000, 0, 0, 1) for _ in range(100)))
    )
    bodies = [_avia_packet(0, 0) + mid40 + _avia_packet(0, 96), mid40]
    path.write_bytes(lvx_file(head, bodies))
    return path


def test_one_device_of_several_by_lidar_topic(tmp_path: Path) -> None:
    path = _two_device_file(tmp_path / "two.lvx")
    with pytest.raises(RecordingError, match=r"holds 2 LiDARs .*--lidar-topic"):
        LvxRecording(path)
    with pytest.raises(RecordingError, match="no LiDAR 'CCCC'"):
        LvxRecording(path, ReplayOptions(lidar_topic="CCCC"))
    mid40 = LvxRecording(path, ReplayOptions(lidar_topic="BBBB"))
    (frame,) = mid40.frames()
    assert len(frame) == 200  # its two packets only
    np.testing.assert_allclose(frame.points[:, 0], 5.0)
    t = np.sort(frame.t)
    np.testing.assert_allclose(t[::2], np.arange(100) * 10e-6, atol=1e-12)  # Mid-40: 10 µs
    avia = LvxRecording(path, ReplayOptions(lidar_topic="AAAA"))
    assert sum(len(f) for f in avia.frames()) == 2 * 96 - 38
    info = recording_info(path)
    assert info.kind == "lvx"
    assert [(t.topic, t.count) for t in info.topics] == [("AAAA", 2), ("BBBB", 2)]
    assert "Mid-40 packets, extrinsics on" in info.topics[1].msgtype


def test_lvx2_mid360(tmp_path: Path) -> None:
    """A Mid-360's LVX2 file, LiDAR ID as Livox Viewer 2 writes it: point i of a package
    at its timestamp + i · 5 µs, line i mod 4; roll 180° turns the sensor upside down."""
    head = public_header((2, 0, 0, 0)) + private_header(1)
    head += lvx2_device(b"47MDK9DF710030", 738306240, 9, 1, (180.0, 0, 0, 0, 0, 1.0))
    recs = b"".join(struct.pack("<iiiBB", 2000, 1000, 500, i, 0) for i in range(96))
    bodies = [
        b"".join(lvx2_package(738306240, T0 + p * 480_000, 1, recs, udp=p) for p in range(4)),
        lvx2_package(738306240, T0 + 4 * 480_000, 1, recs, udp=4),
    ]
    path = tmp_path / "m.lvx2"
    path.write_bytes(lvx_file(head, bodies))
    rec = open_recording(path, ReplayOptions(period_s=0.001))
    frames = list(rec.frames())
    assert [len(f) for f in frames] == [200, 200, 80]
    t = np.concatenate([f.t for f in frames])
    np.testing.assert_allclose(t, np.arange(480) * 5e-6, atol=1e-12)
    line = np.concatenate([f.line for f in frames])
    np.testing.assert_array_equal(line, np.arange(480) % 96 % 4)
    f = frames[0]
    world = f.points @ f.poses[0][:3, :3].T + f.poses[0][:3, 3]
    np.testing.assert_allclose(world[0], [2.0, -1.0, 0.5], atol=1e-6)  # (2, 1, 0.5) rolled, 1 m up
    info = rec.info()
    assert (info.kind, info.topics[0].topic, info.topics[0].count) == ("lvx2", "47MDK9DF710030", 5)
    assert info.duration_s == pytest.approx(479 * 5e-6)


def test_malformed_packets_unknown_devices_and_a_clock_going_back_are_counted(
    tmp_path: Path,
) -> None:
    head = public_header((1, 1, 0, 0)) + private_header(1) + lvx1_device(b"A", 0, 7, 1, YAW90)
    old = lvx1_package(0, sdk1_packet(2, T0, avia_records([(1, 1, 1, 1, 1)] * 96), version=4))
    stranger = _avia_packet(3, 0)  # device index 3: not in the header
    back = _avia_packet(0, 0, t0=T0 - 10**9)  # one second before the first frame
    path = tmp_path / "c.lvx"
    path.write_bytes(lvx_file(head, [_avia_packet(0, 0) + old + stranger, back]))
    rec = LvxRecording(path)
    frames = list(rec.frames())
    assert [len(f) for f in frames] == [96 - 19]
    assert rec.skipped == {"malformed_packets": 1, "unknown_device": 1, "late_points": 96 - 19}


def _sizes(data: bytes) -> tuple[int, int]:
    """The offsets of the first frame and of the second."""
    first = 24 + 5 + 59
    return first, struct.unpack_from("<Q", data, first + 8)[0]


@pytest.mark.parametrize(
    ("cut", "message"),
    [
        (8, "it starts with b'livox_te'"),  # LVX is known by its 10-byte signature
        (22, "truncated in its public header"),
        (27, "truncated in its private header"),
        (60, "truncated in its device info"),
        ("first+10", "truncated in the header of frame 0"),
        ("first+500", "truncated: frame 0 should end at byte"),
        ("second+23", "truncated in the header of frame 1"),
        ("end-1", "truncated: frame 1 should end at byte"),
    ],
)
def test_truncated_files_raise_one_recording_error(
    tmp_path: Path, cut: object, message: str
) -> None:
    data = _avia_file(tmp_path / "a.lvx").read_bytes()
    first, second = _sizes(data)
    at = {
        "first+10": first + 10,
        "first+500": first + 500,
        "second+23": second + 23,
        "end-1": len(data) - 1,
    }
    n = at.get(str(cut), cut)
    path = tmp_path / "cut.lvx"
    path.write_bytes(data[: int(n)])  # type: ignore[call-overload]
    with pytest.raises(RecordingError, match=message):
        open_recording(path)
    with pytest.raises(RecordingError):
        recording_info(path)


def test_a_file_cut_between_two_frames_plays_the_frames_before(tmp_path: Path) -> None:
    data = _avia_file(tmp_path / "a.lvx").read_bytes()
    path = tmp_path / "cut.lvx"
    path.write_bytes(data[: _sizes(data)[1]])
    (frame,) = LvxRecording(path).frames()
    assert len(frame) == 384  # the first 480 firings
    path.write_bytes(data[: _sizes(data)[0]])
    with pytest.raises(RecordingError, match="holds no frame"):
        LvxRecording(path)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        (0, 1, "says it is frame 0 at byte 1"),
        (2, 5, "says it is frame 5"),
        (1, 10, "the next one at byte 10"),
    ],
)
def test_corrupt_frame_headers_raise(tmp_path: Path, field: int, value: int, message: str) -> None:
    data = bytearray(_avia_file(tmp_path / "a.lvx").read_bytes())
    first = _sizes(bytes(data))[0]
    struct.pack_into("<Q", data, first + 8 * field, value)
    path = tmp_path / "bad.lvx"
    path.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match=message):
        LvxRecording(path)


def test_bad_magic_raises(tmp_path: Path) -> None:
    data = bytearray(_avia_file(tmp_path / "a.lvx").read_bytes())
    data[20:24] = struct.pack("<I", 0xDEADBEEF)
    path = tmp_path / "bad.lvx"
    path.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match="magic code 0xDEADBEEF is not 0xAC0EA767"):
        open_recording(path)


@pytest.fixture(scope="module")
def small_lvx() -> bytes:
    with tempfile.TemporaryDirectory() as tmp:
        return _avia_file(Path(tmp) / "a.lvx", frames=2, per_frame=2).read_bytes()


@settings(max_examples=300)
@given(
    st.lists(st.tuples(st.integers(0, 10**6), st.integers(0, 255)), max_size=6),
    st.integers(0, 10**6),
)
def test_damaged_files_only_raise_recording_errors(
    small_lvx: bytes, edits: list[tuple[int, int]], cut: int
) -> None:
    """Random bytes anywhere and a random cut: the file reads, or one RecordingError."""
    data = bytearray(small_lvx)
    for at, value in edits:
        data[at % len(data)] = value
    data = data[: max(10, len(data) - cut % 200 if cut % 3 else len(data))]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "x.lvx"
        path.write_bytes(bytes(data))
        try:
            rec = open_recording(path)
            frames = list(rec.frames())
            rec.info()
        except RecordingError:
            return
        assert all(math.isfinite(f.stamp) for f in frames)
