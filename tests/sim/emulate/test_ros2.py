"""The emulated rig on ROS 2 (``sim.emulate.ros2``): its messages decoded by rosbags'
Humble typestore (an independent decoder), its /tf chain against the mount
kinematics, and the device on a loopback DDS domain with a stand-in rig: the stream
starts at the first subscriber, one message per period with the points of that
period, goals reach the rig, joint states come out.  Every wait is bounded."""

from __future__ import annotations

import time
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pytest

from dronetrack.errors import ConfigError
from dronetrack.formats.ros.livox_msg import livox_typestore
from dronetrack.geometry.mount import MountGeometry, sensor_poses
from dronetrack.sim.emulate.livox_stream import PointChunk
from dronetrack.sim.emulate.ros2 import (
    CUSTOM_MSG,
    Ros2Options,
    custom_msg,
    joint_links,
    slice_length,
    static_links,
)
from ros2_helpers import loopback_dds

if TYPE_CHECKING:
    from dronetrack.sources.ros2.dds import RawReader

MOUNT = MountGeometry((1.0, 2.0, 1.5), (0.0, 0.0, 0.05), (0.03, 0.0, 0.09))


def test_a_custom_msg_reads_back_with_rosbags() -> None:
    xyz = np.array([[10.0, -1.5, 2.25], [3.5, 0.0, -0.5]])
    t_ns = np.array([2_100_000_000, 2_150_000_123], np.int64)
    raw = custom_msg(2_100_000_000, "livox_frame", xyz, t_ns, np.array([7, 200], np.uint8))
    msg = livox_typestore(ros1=False).deserialize_cdr(raw, CUSTOM_MSG)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (2, 100_000_000)
    assert msg.header.frame_id == "livox_frame"
    assert msg.timebase == 2_100_000_000
    assert msg.point_num == 2
    assert [p.offset_time for p in msg.points] == [0, 50_000_123]
    assert [(p.x, p.y, p.z) for p in msg.points] == [(10.0, -1.5, 2.25), (3.5, 0.0, -0.5)]
    assert [p.reflectivity for p in msg.points] == [7, 200]


def test_a_point_before_the_timebase_is_refused() -> None:
    with pytest.raises(ConfigError, match=r"within 4\.29 s after its timebase"):
        custom_msg(10, "f", np.zeros((1, 3)), np.array([9], np.int64), np.zeros(1, np.uint8))


@pytest.mark.parametrize(("pan", "tilt"), [(0.0, 0.0), (0.7, -0.3), (-2.5, 0.4)])
def test_the_tf_chain_is_the_mount_kinematics(pan: float, tilt: float) -> None:
    (world_base, tilt_sensor) = static_links(MOUNT, "livox_frame")
    base_pan, pan_tilt = joint_links(pan, tilt, MOUNT)
    names = [world_base[:2], base_pan[:2], pan_tilt[:2], tilt_sensor[:2]]
    assert names == [
        ("world", "turret_base"),
        ("turret_base", "pan_link"),
        ("pan_link", "tilt_link"),
        ("tilt_link", "livox_frame"),
    ]
    T = world_base[2] @ base_pan[2] @ pan_tilt[2] @ tilt_sensor[2]
    np.testing.assert_allclose(T, sensor_poses(pan, tilt, MOUNT), atol=1e-12)


def test_slices_are_whole_fractions_of_the_period() -> None:
    assert slice_length(0.1) == pytest.approx(0.02)
    assert slice_length(0.05) == pytest.approx(0.025)
    assert slice_length(0.01) == pytest.approx(0.01)
    with pytest.raises(ConfigError):
        slice_length(0.0)


class _FakeRig:
    """The rig's turret: goals recorded, the pointing a fixed ramp in time."""

    def __init__(self) -> None:
        self.goals: list[tuple[str, float]] = []

    def command_axis(self, axis: str, angle: float, t: float) -> None:
        self.goals.append((axis, angle))

    def turret_at(self, t: float) -> tuple[float, float]:
        return 0.25, -0.125

    def turret_rate(self, t: float) -> tuple[float, float]:
        return 0.5, 0.0


def _chunks() -> list[PointChunk]:
    """Three 20 ms slices with a point every 5 ms (reflectivity = its index)."""
    out = []
    for j in range(3):
        t = np.arange(4, dtype=np.int64) * 5_000_000 + j * 20_000_000
        k = t // 5_000_000
        xyz = np.column_stack([10.0 + k, np.zeros(4), np.zeros(4)])
        out.append(PointChunk(xyz, t, k.astype(np.uint8), end_ns=(j + 1) * 20_000_000))
    return out


def _first_messages(reader: RawReader, n: int, timeout_s: float = 5.0) -> list[bytes]:
    """At least ``n`` messages off ``reader``, or what came within ``timeout_s``."""
    got: list[bytes] = []
    end = time.monotonic() + timeout_s
    while len(got) < n and time.monotonic() < end:
        reader.wait(0.05)
        got.extend(reader.drain())
    return got


def test_the_device_streams_periods_from_the_first_subscriber(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain_id = loopback_dds(tmp_path, monkeypatch)
    from dronetrack.formats.ros.livox_msg import decode_livox_cdr
    from dronetrack.formats.ros.msgs import (
        JOINT_STATE,
        TF_MESSAGE,
        decode_joint_state,
        decode_tf,
        encode_joint_state,
    )
    from dronetrack.sim.emulate.ros2 import Ros2Device
    from dronetrack.sources.ros2.dds import DdsDomain

    rig = _FakeRig()
    device = Ros2Device(
        lambda: iter(_chunks()),
        period_s=0.04,
        mount=MOUNT,
        options=Ros2Options(state_hz=50.0),
        domain_id=domain_id,
    )
    device.attach(rig)
    host = DdsDomain(domain_id)
    try:
        device.start()
        states = host.reader("/turret/joint_states", JOINT_STATE, "sensor")
        static = host.reader("/tf_static", TF_MESSAGE, "static")
        tf = host.reader("/tf", TF_MESSAGE, "tf")  # volatile: matched before the stream
        end = time.monotonic() + 5.0
        while device._tf.matched() == 0 and time.monotonic() < end:
            time.sleep(0.01)
        time.sleep(0.2)
        assert device.starts == 0  # no subscriber of the points yet
        points = host.reader("/livox/lidar", CUSTOM_MSG, "sensor")
        command = host.writer("/turret/command", JOINT_STATE, "default")
        got = _first_messages(points, 2)
        deadline = time.monotonic() + 2.0
        while not rig.goals and time.monotonic() < deadline:
            command.write(encode_joint_state(0, ["pan", "tilt"], [0.5, -0.25]))
            time.sleep(0.05)
        js = [decode_joint_state(r) for r in states.drain()]
        moving = [s for r in tf.drain() for s in decode_tf(r)]
        fixed = [s for r in static.drain() for s in decode_tf(r)]
    finally:
        host.close()
        device.close()
    assert device.starts == 1
    clouds = [decode_livox_cdr(r) for r in got]
    # period 0: [0, 40 ms), points 0-7; period 1: [40, 60 ms) the rest (the stream ends)
    assert [c.timebase_ns for c in clouds] == [0, 40_000_000]
    assert clouds[0].points["reflectivity"].tolist() == list(range(8))
    assert clouds[0].points["offset_time"].tolist() == [5_000_000 * k for k in range(8)]
    assert clouds[1].points["reflectivity"].tolist() == list(range(8, 12))
    assert clouds[1].points["offset_time"].tolist() == [5_000_000 * k for k in range(4)]
    np.testing.assert_array_equal(clouds[1].points["x"], 10.0 + np.arange(8, 12))
    assert ("pan", 0.5) in rig.goals
    assert ("tilt", -0.25) in rig.goals
    assert js
    assert js[-1].position == {"pan": 0.25, "tilt": -0.125}
    assert js[-1].velocity == {"pan": 0.5, "tilt": 0.0}
    assert {(s.parent, s.child) for s in fixed} == {
        ("world", "turret_base"),
        ("tilt_link", "livox_frame"),
    }
    stamps = sorted({s.stamp_ns for s in moving})
    assert stamps[:3] == [0, 20_000_000, 40_000_000]  # the 50 Hz grid, scenario time


def test_without_tf_the_device_publishes_points_and_no_transform(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``emulate --ros2 --no-tf``: the points flow, and neither /tf nor /tf_static carries
    a message, so a host takes its poses from the turret's joint states (that path:
    ``tests/sources/test_ros2_dds.py``)."""
    domain_id = loopback_dds(tmp_path, monkeypatch)
    from dronetrack.formats.ros.msgs import TF_MESSAGE
    from dronetrack.sim.emulate.ros2 import Ros2Device
    from dronetrack.sources.ros2.dds import DdsDomain

    device = Ros2Device(
        lambda: iter(_chunks()),
        period_s=0.04,
        mount=MOUNT,
        options=Ros2Options(state_hz=50.0, tf=False),
        domain_id=domain_id,
    )
    device.attach(_FakeRig())
    host = DdsDomain(domain_id)
    try:
        device.start()
        static = host.reader("/tf_static", TF_MESSAGE, "static")
        tf = host.reader("/tf", TF_MESSAGE, "tf")
        points = host.reader("/livox/lidar", CUSTOM_MSG, "sensor")
        got = _first_messages(points, 2)
        time.sleep(0.2)
        moving, fixed = list(tf.drain()), list(static.drain())
    finally:
        host.close()
        device.close()
    assert len(got) == 2
    assert (moving, fixed) == ([], [])
