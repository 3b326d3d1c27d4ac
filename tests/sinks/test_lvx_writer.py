"""``sinks.lvx_writer``: frames written as LVX / LVX2 and read back; the bytes it
writes read by hand at the specifications' offsets; the firing grid."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.errors import ConfigError, InputError
from dronetrack.formats.livox.lvx import extrinsic_pose
from dronetrack.sinks.lvx_writer import DEFAULT_START_NS, LvxWriter, firing_slots, lvx_turret_mode
from dronetrack.sources.frames import fixed_pose_frame
from dronetrack.sources.recordings.lvx import LvxRecording
from dronetrack.sources.recordings.recording import ReplayOptions
from dronetrack.types import Frame

POSE = extrinsic_pose((0.0, -12.5, 30.0, 0.25, -1.0, 1.5))


def _frame(rng: np.random.Generator, stamp: float, n: int, rate_hz: float, pose=POSE) -> Frame:  # type: ignore[no-untyped-def]
    """``n`` returns 20-120 m away on a simulated sensor's firing grid (firing k at k / rate),
    at distinct random firings of the 0.1 s frame."""
    k0 = round(stamp * rate_hz)
    k = np.sort(rng.choice(round(0.1 * rate_hz), size=n, replace=False)) + k0
    d = rng.normal(size=(n, 3)) * [0.1, 0.4, 0.3] + [1.0, 0.0, 0.0]
    pts = d / np.linalg.norm(d, axis=1)[:, None] * rng.uniform(20, 120, size=(n, 1))
    intensity = rng.integers(0, 151, n).astype(np.float32)
    return fixed_pose_frame(stamp, 0.1, pts, t=k / rate_hz, intensity=intensity, pose=pose)


@pytest.mark.parametrize(
    ("fmt", "sensor", "rate"),
    [("lvx", "avia", 240_000.0), ("lvx", "mid40", 100_000.0), ("lvx2", "mid360", 200_000.0)],
)
def test_frames_read_back_as_written(tmp_path: Path, fmt: str, sensor: str, rate: float) -> None:
    """Positions within the packets' millimetre, times within a firing, every return kept;
    the pose, the truth and the scenario beside the file."""
    rng = np.random.default_rng(7)
    path = tmp_path / f"f.{fmt}"
    writer = LvxWriter(path, fmt, sensor, "seed = 3\n")
    frames = [_frame(rng, 0.1 * i, 3000, rate) for i in range(5)]
    for i, f in enumerate(frames):
        writer.frame(f, np.array([10.0 + i, 0.5, 3.0]))
    writer.close()
    rec = LvxRecording(path)
    assert rec.origin == DEFAULT_START_NS / 1e9
    back = list(rec.frames())
    assert len(back) == 5
    interval = {"avia": 4167e-9, "mid40": 10e-6, "mid360": 5e-6}[sensor]
    for a, b in zip(frames, back, strict=True):
        assert b.stamp == pytest.approx(a.stamp, abs=1e-12)
        assert len(b) == len(a)
        ia, ib = np.argsort(a.t, kind="stable"), np.argsort(b.t, kind="stable")
        np.testing.assert_allclose(b.points[ib], a.points[ia], atol=0.5e-3 + 1e-9)
        # round to the device's grid, plus at most two firings shifted off a shared one
        assert np.abs(b.t[ib] - a.t[ia]).max() <= 2.5 * interval
        np.testing.assert_array_equal(b.intensity[ib], a.intensity[ia])
        np.testing.assert_allclose(b.poses[0], POSE, atol=1e-6)
    truth = np.loadtxt(writer.truth_path, delimiter=",", skiprows=1)
    np.testing.assert_allclose(truth, [[0.1 * (i + 1), 10.0 + i, 0.5, 3.0] for i in range(5)])
    assert writer.truth_path.read_text().startswith("t,x,y,z\n")
    assert writer.scenario_path.read_text() == "seed = 3\n"
    assert writer.frames_written == 10  # 50 ms each


def test_written_bytes_at_the_specification_offsets(tmp_path: Path) -> None:
    """One Avia return at firing 3 of a frame starting at 1 s: the header's extrinsics,
    the first frame's header and the first package read with struct at their offsets."""
    pts = np.array([[12.3456, -0.5, 2.0]])
    frame = fixed_pose_frame(
        1.0, 0.1, pts, t=np.array([1.0 + 3 * 4167e-9]), intensity=[42], pose=POSE
    )
    path = tmp_path / "one.lvx"
    writer = LvxWriter(path, "lvx", "avia")
    writer.frame(frame, np.zeros(3))
    writer.close()
    data = path.read_bytes()
    assert data[:16] == b"livox_tech" + bytes(6)
    assert struct.unpack_from("<4BI", data, 16) == (1, 1, 0, 0, 0xAC0EA767)
    assert struct.unpack_from("<IB", data, 24) == (50, 1)
    code, hub, index, dev_type, enable = struct.unpack_from("<16s16sBBB", data, 29)
    assert (code.rstrip(b"\0"), hub, index, dev_type, enable) == (
        b"3GGDJ1234567890",
        bytes(16),
        0,
        7,
        1,
    )
    ext = struct.unpack_from("<6f", data, 29 + 35)
    np.testing.assert_allclose(ext, (0.0, -12.5, 30.0, 0.25, -1.0, 1.5), atol=1e-5)
    first = 29 + 59
    cur, nxt, idx = struct.unpack_from("<QQQ", data, first)
    assert (cur, idx) == (first, 0)
    packages = (nxt - first - 24) // (1 + 18 + 96 * 14)
    assert (nxt - first - 24) % (1 + 18 + 96 * 14) == 0
    assert packages == -(-50_000_000 // (96 * 4167))  # the packets stamped in the first 50 ms
    p = first + 24
    dev, version, _, _, _, status, ts_type, data_type, stamp = struct.unpack_from(
        "<BBBBBIBBQ", data, p
    )
    assert (dev, version, status, ts_type, data_type) == (0, 5, 0, 1, 2)
    assert stamp == DEFAULT_START_NS + 1_000_000_000
    records = [struct.unpack_from("<iiiBB", data, p + 19 + 14 * j) for j in range(5)]
    assert records[3] == (12346, -500, 2000, 42, 0)
    assert all(r == (0, 0, 0, 0, 0) for j, r in enumerate(records) if j != 3)
    second = struct.unpack_from("<QQQ", data, nxt)
    assert second[0] == nxt
    assert second[1] == len(data)
    assert second[2] == 1


def test_a_moving_sensor_and_other_sensors_are_refused(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    writer = LvxWriter(tmp_path / "m.lvx", "lvx", "avia")
    writer.frame(_frame(rng, 0.0, 10, 240_000.0), np.zeros(3))
    moved = POSE.copy()
    moved[0, 3] += 1e-3
    with pytest.raises(InputError, match=r"the sensor moved at t = 0\.100 s.*--turret fixed"):
        writer.frame(_frame(rng, 0.1, 10, 240_000.0, pose=moved), np.zeros(3))
    writer.close()
    with pytest.raises(ConfigError, match="--sensor mid360"):
        LvxWriter(tmp_path / "a.lvx2", "lvx2", "avia")
    with pytest.raises(ConfigError, match="--sensor avia or mid40"):
        LvxWriter(tmp_path / "b.lvx", "lvx", "vlp16")
    with pytest.raises(ConfigError, match="exists"):
        LvxWriter(tmp_path / "m.lvx", "lvx", "avia")
    with pytest.raises(ConfigError, match="moving observer"):
        LvxWriter(tmp_path / "o.lvx2", "lvx2", "mid360", observer=True)
    (tmp_path / "c.truth.csv").write_text("")
    with pytest.raises(ConfigError, match=r"c\.truth\.csv exists"):
        LvxWriter(tmp_path / "c.lvx", "lvx", "avia")


def test_turret_mode_for_lvx() -> None:
    assert lvx_turret_mode("lvx", None, False, True) == "fixed"
    assert lvx_turret_mode("lvx", "fixed", False, True) == "fixed"
    with pytest.raises(ConfigError, match="not --turret tracking"):
        lvx_turret_mode("lvx", "tracking", False, True)
    with pytest.raises(ConfigError, match="--compress"):
        lvx_turret_mode("lvx2", None, True, True)
    with pytest.raises(ConfigError, match="--pointcloud2"):
        lvx_turret_mode("lvx2", None, False, False)


@given(st.lists(st.floats(0.0, 1e-3), max_size=200))
def test_firing_slots_take_the_nearest_free_firing(times: list[float]) -> None:
    """k is the least strictly increasing sequence with k_i ≥ round((t_i − t₀)/Δt): the
    definition k_i = max(round(...), k_{i−1} + 1), checked point by point."""
    t = np.sort(np.array(times))
    dt = 4167e-9
    k = firing_slots(t, 0.0, dt)
    expect: list[int] = []
    for ti in t:
        r = int(np.rint(ti / dt))
        expect.append(r if not expect else max(r, expect[-1] + 1))
    assert k.tolist() == expect


def test_replay_of_a_written_file_with_its_period(tmp_path: Path) -> None:
    """--period cuts the written 0.1 s frames into halves, each point in its half."""
    rng = np.random.default_rng(2)
    path = tmp_path / "p.lvx"
    writer = LvxWriter(path, "lvx", "avia")
    writer.frame(_frame(rng, 0.0, 500, 240_000.0), np.zeros(3))
    writer.close()
    halves = list(LvxRecording(path, ReplayOptions(period_s=0.05)).frames())
    assert [h.stamp for h in halves] == [0.0, 0.05]
    assert sum(len(h) for h in halves) == 500
    assert all(np.all((h.t >= h.stamp) & (h.t < h.stamp + 0.05)) for h in halves)
