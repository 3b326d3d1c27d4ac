"""Frames cut from a live point stream by the points' own times, and the sensor pose
from the turret's readings."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import ConfigError, InputError
from dronetrack.geometry.mount import MountGeometry, sensor_poses
from dronetrack.sources.assembly import NS, FrameAssembler, PointBatch, PoseHistory, StreamFrame
from dronetrack.types import TurretState

T0 = 1_700_000_000 * NS  # a sensor clock far from zero, as a PTP or GPS time is


def _batch(t_ns: np.ndarray) -> PointBatch:
    n = len(t_ns)
    xyz = np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.ones(n)])
    return PointBatch(xyz, t_ns.astype(np.int64), np.full(n, 7, np.uint8), np.zeros(n, np.uint8))


def _run(assembler: FrameAssembler, t_ns: np.ndarray, cuts: list[int]) -> list[StreamFrame]:
    frames: list[StreamFrame] = []
    for part in np.split(t_ns, sorted(set(cuts))):
        frames += assembler.push(_batch(part))
    return frames + assembler.flush()


def test_points_go_to_the_period_their_time_falls_in() -> None:
    # 100 ms frames from T0: points at 0, 50, 99.999, 100, 250 ms
    ms = np.array([0.0, 50.0, 99.999, 100.0, 250.0])
    t_ns = T0 + np.round(ms * 1e6).astype(np.int64)
    frames = _run(FrameAssembler(0.1), t_ns, [2])
    assert [f.index for f in frames] == [0, 1, 2]
    assert [len(f.points) for f in frames] == [3, 1, 1]
    assert [f.start_ns - T0 for f in frames] == [0, 100_000_000, 200_000_000]


def test_a_period_without_points_is_counted_and_a_late_point_dropped() -> None:
    a = FrameAssembler(0.1, t0_ns=T0)
    out = a.push(_batch(T0 + np.array([10, 20]) * 1_000_000))
    out += a.push(_batch(T0 + np.array([350]) * 1_000_000))  # frames 1 and 2 got nothing
    out += a.push(_batch(T0 + np.array([90]) * 1_000_000))  # frame 0 is gone: late
    out += a.flush()
    assert [f.index for f in out] == [0, 3]
    assert a.empty_periods == 2
    assert a.late_points == 1


def test_a_bad_period_is_refused() -> None:
    with pytest.raises(ConfigError, match="integration time"):
        FrameAssembler(0.0)


@settings(max_examples=60, deadline=None)
@given(
    gaps=st.lists(st.integers(0, 60_000_000), min_size=1, max_size=300),
    cuts=st.lists(st.integers(0, 300), max_size=20),
    period_ms=st.sampled_from([10, 50, 100]),
)
def test_every_point_lands_once_in_its_own_period_however_the_stream_is_split(
    gaps: list[int], cuts: list[int], period_ms: int
) -> None:
    t_ns = T0 + np.cumsum(np.array(gaps, dtype=np.int64))
    frames = _run(FrameAssembler(period_ms / 1000), t_ns, cuts)
    got = np.concatenate([f.points.t_ns for f in frames])
    np.testing.assert_array_equal(got, t_ns)  # all, once, in order
    idx = [f.index for f in frames]
    assert idx == sorted(set(idx))
    for f in frames:
        assert np.all(f.points.t_ns >= f.start_ns)
        assert np.all(f.points.t_ns < f.start_ns + f.period_ns)
    # the same frames whatever the packet boundaries
    whole = _run(FrameAssembler(period_ms / 1000), t_ns, [])
    assert [(f.index, len(f.points)) for f in whole] == [(f.index, len(f.points)) for f in frames]


def test_the_pose_follows_the_readings_between_them_and_holds_after() -> None:
    mount = MountGeometry(
        base=(0.0, 0.0, 1.0), pan_to_tilt=(0.0, 0.0, 0.1), tilt_to_sensor=(0.05, 0, 0)
    )
    history = PoseHistory(mount)
    history.add(TurretState(0.0, pan=0.0, tilt=0.0))
    history.add(TurretState(0.1, pan=0.2, tilt=-0.1))
    pan, tilt = history.angles(np.array([0.05, 0.1, 0.3]))
    np.testing.assert_allclose(pan, [0.1, 0.2, 0.2])
    np.testing.assert_allclose(tilt, [-0.05, -0.1, -0.1])
    # a frame from 0 to 0.1 s: its poses are the kinematics at the interpolated angles
    t_ns = T0 + np.array([0, 50_000_000], dtype=np.int64)
    frame = history.frame(StreamFrame(0, T0, 100_000_000, _batch(t_ns)), T0, samples=3)
    np.testing.assert_allclose(frame.pose_t, [0.0, 0.05, 0.1])
    np.testing.assert_allclose(frame.t, [0.0, 0.05])
    np.testing.assert_allclose(frame.poses[1], sensor_poses(0.1, -0.05, mount))
    assert math.isclose(frame.end, 0.1)


def test_no_reading_means_no_pose_and_old_readings_are_forgotten() -> None:
    history = PoseHistory(MountGeometry(), keep_s=1.0)
    with pytest.raises(InputError, match="no turret reading"):
        history.angles(np.array([0.0]))
    for k in range(50):
        history.add(TurretState(0.1 * k, pan=0.0, tilt=0.0))
    history.add(TurretState(1.0, pan=1.0, tilt=0.0))  # older than the newest: ignored
    assert len(history) <= 12  # readings of the last 1 s (10 Hz), and one before
    np.testing.assert_allclose(history.angles(np.array([4.9]))[0], [0.0])


def test_a_batch_out_of_time_order_is_put_in_order() -> None:
    t_ns = T0 + np.array([150, 20, 120, 10], dtype=np.int64) * 1_000_000
    a = FrameAssembler(0.1, t0_ns=T0)
    frames = a.push(_batch(t_ns)) + a.flush()
    assert [f.index for f in frames] == [0, 1]
    np.testing.assert_array_equal(frames[0].points.t_ns - T0, [10_000_000, 20_000_000])
    np.testing.assert_array_equal(frames[1].points.t_ns - T0, [120_000_000, 150_000_000])
    assert a.late_points == 0


def _fired(t_ns: np.ndarray, first_ms: float, last_ms: float) -> PointBatch:
    """Points at ``t_ns`` from packets whose firings span first_ms … last_ms after T0."""
    span = (T0 + round(first_ms * 1e6), T0 + round(last_ms * 1e6))
    return replace(_batch(t_ns), firings=span)


def test_a_firing_past_its_end_completes_a_frame_with_no_point_after_it() -> None:
    """Returns at 10 and 60 ms, then open sky: the packet whose firings reach 100 ms
    completes frame 0 with no return of its own; before that the frame stays open."""
    a = FrameAssembler(0.1, t0_ns=T0)
    pts = T0 + np.array([10, 60], dtype=np.int64) * 1_000_000
    assert a.push(_fired(pts, 0.0, 60.0)) == []
    assert a.push(_fired(pts[:0], 60.0, 99.9)) == []  # sky: firings, no return
    (frame,) = a.push(_fired(pts[:0], 99.95, 100.35))
    assert (frame.index, len(frame.points)) == (0, 2)
    # a point of the closed frame arriving after it is late, and counted
    assert a.push(_fired(T0 + np.array([99_000_000]), 99.0, 99.0)) == []
    assert a.late_points == 1
    # the next frame opens with its first return, and the periods without one are counted
    (later,) = a.push(_fired(T0 + np.array([310_000_000, 420_000_000]), 300.0, 420.0))
    assert later.index == 3
    assert a.empty_periods == 2  # frames 1 and 2 had no return


def test_taking_points_keeps_the_batchs_firings() -> None:
    batch = _fired(T0 + np.array([5, 6, 7], dtype=np.int64), 0.0, 1.0)
    assert batch.take(np.array([True, False, True])).firings == batch.firings
    assert (batch.first_ns, batch.last_ns) == (T0, T0 + 1_000_000)
    bare = _batch(T0 + np.array([5, 6, 7], dtype=np.int64))
    assert (bare.first_ns, bare.last_ns) == (T0 + 5, T0 + 7)
    assert _batch(np.zeros(0, np.int64)).first_ns is None


def test_beyond_the_newest_reading_its_rates_carry_the_pose_for_lead_s() -> None:
    # q(t) = q_k + ω_k · min(t − t_k, lead_s): at 0.2 s pan 0.2 rad, 1 rad/s; tilt −0.5 rad/s
    history = PoseHistory(MountGeometry(), lead_s=0.05)
    history.add(TurretState(0.1, pan=0.1, tilt=0.0))
    history.add(TurretState(0.2, pan=0.2, tilt=0.0, pan_rate=1.0, tilt_rate=-0.5))
    pan, tilt = history.angles(np.array([0.15, 0.2, 0.23, 0.25, 0.4]))
    np.testing.assert_allclose(pan, [0.15, 0.2, 0.23, 0.25, 0.25])
    np.testing.assert_allclose(tilt, [0.0, 0.0, -0.015, -0.025, -0.025])
    with pytest.raises(ConfigError, match="lead"):
        PoseHistory(MountGeometry(), lead_s=-0.1)
