"""A ROS 2 point topic as a live source, on a loopback DDS domain: the type found from
discovery, frames with their /tf_static pose, the run's clock, a publisher leaving
ends the stream, a silent one is a device error, and ``info ros2://``.  Every wait
is bounded."""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from dronetrack.errors import DeviceError
from dronetrack.formats.ros.livox_msg import LIVOX_POINT, LivoxCloud, encode_livox_cdr
from dronetrack.formats.ros.msgs import TF_MESSAGE, encode_tf
from dronetrack.geometry.mount import MountGeometry
from dronetrack.types import TurretState
from ros2_helpers import loopback_dds

T0_NS = 1_767_225_600_000_000_000
MOUNT = MountGeometry((0.0, 0.0, 1.0), (0.0, 0.0, 0.05), (0.025, 0.0, 0.086))


def _cloud(k: int) -> bytes:
    """Frame k: 10 points 20 m ahead, 10 ms apart, from 0.1 k s on."""
    pts = np.zeros(10, dtype=LIVOX_POINT)
    pts["x"], pts["y"], pts["z"] = 20.0, np.arange(10) * 0.1, 1.0 * k
    pts["offset_time"] = np.arange(10) * 10_000_000
    stamp = T0_NS + k * 100_000_000
    return encode_livox_cdr(LivoxCloud(stamp, "lidar", stamp, pts))


def _wait(cond: object, timeout_s: float) -> None:
    end = time.monotonic() + timeout_s
    while not cond():  # type: ignore[operator]
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


@pytest.mark.slow
def test_frames_of_a_custommsg_topic_with_their_static_pose(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain_id = loopback_dds(tmp_path, monkeypatch)
    from dronetrack.sources.ros2.dds import DdsDomain
    from dronetrack.sources.ros2.topic import CUSTOM_MSG, Ros2Source, point_type

    pub = DdsDomain(domain_id)
    sub = DdsDomain(domain_id)
    try:
        T = np.eye(4)
        T[:3, 3] = (1.0, 2.0, 3.0)
        static = pub.writer("/tf_static", TF_MESSAGE, "static")
        static.write(encode_tf(T0_NS, [("world", "lidar", T)]))  # before anyone listens
        points = pub.writer("/livox/lidar", CUSTOM_MSG, "default")
        assert point_type(sub, "/livox/lidar", 5.0) == CUSTOM_MSG
        source = Ros2Source(sub, "/livox/lidar", CUSTOM_MSG, MOUNT, period_s=0.1, max_frames=10)
        source.start()
        _wait(lambda: points.matched() > 0, 5.0)

        def publish() -> None:
            for k in range(5):
                points.write(_cloud(k))
                time.sleep(0.02)
            time.sleep(0.2)
            pub.close()  # the publisher leaves: the stream ends

        threading.Thread(target=publish, daemon=True).start()
        t_start = time.monotonic()
        samples = list(source)
        assert time.monotonic() - t_start < 5.0
    finally:
        pub.close()
        sub.close()
    assert len(samples) == 5
    for k, s in enumerate(samples):
        f = s.frame
        assert f.stamp == pytest.approx(0.1 * k)  # seconds since the first stamp
        assert f.t == pytest.approx(0.1 * k + np.arange(10) * 0.01)
        np.testing.assert_allclose(f.poses[0], T)  # the transient-local /tf_static
        np.testing.assert_allclose(f.world_points()[:, 2], 1.0 * k + 3.0, atol=1e-6)
        assert s.received is not None
        assert s.turret is None
    assert source.frames_dropped == 0


@pytest.mark.slow
def test_a_silent_publisher_is_a_device_error(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain_id = loopback_dds(tmp_path, monkeypatch)
    from dronetrack.sources.ros2.dds import DdsDomain
    from dronetrack.sources.ros2.topic import CUSTOM_MSG, Ros2Source

    pub = DdsDomain(domain_id)
    sub = DdsDomain(domain_id)
    try:
        points = pub.writer("/livox/lidar", CUSTOM_MSG, "default")
        source = Ros2Source(sub, "/livox/lidar", CUSTOM_MSG, MOUNT, stall_s=0.5, first_s=3.0)
        source.start()
        _wait(lambda: points.matched() > 0, 5.0)
        points.write(_cloud(0))
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match=r"ros2:///livox/lidar: no message for 0.5 s"):
            list(source)
        assert time.monotonic() - t0 < 3.0
    finally:
        pub.close()
        sub.close()


@pytest.mark.slow
def test_no_publisher_names_what_the_domain_has(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain_id = loopback_dds(tmp_path, monkeypatch)
    from dronetrack.jobs.live.ros2 import probe_ros2
    from dronetrack.sources.ros2.dds import DdsDomain
    from dronetrack.sources.ros2.topic import point_type

    pub = DdsDomain(domain_id)
    sub = DdsDomain(domain_id)
    try:
        tf = pub.writer("/tf", TF_MESSAGE, "tf")
        with pytest.raises(DeviceError, match=r"no publisher of ROS 2 topic /x .*/tf \(tf2_msgs"):
            point_type(sub, "/x", 1.0)
        with pytest.raises(DeviceError, match="carries tf2_msgs/msg/TFMessage"):
            point_type(sub, "/tf", 1.0)
        lines = dict(probe_ros2("ros2://", domain_id, wait_s=2.0))
        assert lines["/tf"].startswith("tf2_msgs/msg/TFMessage, 1 publisher(s)")
        stop = threading.Event()

        def publish() -> None:
            while not stop.is_set():
                tf.write(encode_tf(T0_NS, [("a", "b", np.eye(4))]))
                time.sleep(0.02)

        threading.Thread(target=publish, daemon=True).start()
        try:
            rate = dict(probe_ros2("ros2:///tf", domain_id, wait_s=2.0, sample_s=1.0))
        finally:
            stop.set()
        hz = float(rate["rate over 1 s"].split(", ")[1].split(" Hz")[0])
        assert 30.0 < hz < 55.0  # 50 Hz less the sleep's overrun
    finally:
        pub.close()
        sub.close()


class _RampTurret:
    """A polled turret whose pan turns at 1 rad/s on the host's clock (tilt 0.2 rad):
    ``readings`` gives one reading per 10 ms since the last call, stamped then."""

    RATE = 1.0

    def __init__(self) -> None:
        self.t_ref = time.monotonic()
        self.last = self.t_ref

    def _state(self, t: float) -> TurretState:
        return TurretState(t, self.RATE * (t - self.t_ref), 0.2, self.RATE, 0.0)

    def state(self) -> TurretState:
        return self._state(time.monotonic())

    def readings(self, until: float = -np.inf, timeout_s: float = 1.0) -> list[TurretState]:
        stamps = np.arange(self.last + 0.01, time.monotonic(), 0.01)
        if len(stamps):
            self.last = float(stamps[-1])
        return [self._state(float(t)) for t in stamps]


def test_without_tf_the_turret_readings_give_each_pose_by_interpolation(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """No /tf for the cloud's frame: the poses come from the turret's time-stamped
    readings, interpolated within the frame (the pan turns 0.1 rad over a frame), not
    the newest reading held over it."""
    domain_id = loopback_dds(tmp_path, monkeypatch)
    from dronetrack.geometry.mount import pointing_angles
    from dronetrack.sources.ros2.dds import DdsDomain
    from dronetrack.sources.ros2.topic import CUSTOM_MSG, Ros2Source

    pub = DdsDomain(domain_id)
    sub = DdsDomain(domain_id)
    try:
        points = pub.writer("/livox/lidar", CUSTOM_MSG, "default")
        turret = _RampTurret()
        source = Ros2Source(
            sub, "/livox/lidar", CUSTOM_MSG, MOUNT, turret, period_s=0.1, max_frames=10
        )
        source.start()
        _wait(lambda: points.matched() > 0, 5.0)

        def publish() -> None:
            start = time.monotonic()
            for k in range(6):  # each frame once its period has passed, as a driver does
                time.sleep(max(start + 0.1 * (k + 1) - time.monotonic(), 0.0))
                points.write(_cloud(k))
            time.sleep(0.2)
            pub.close()

        threading.Thread(target=publish, daemon=True).start()
        samples = list(source)
    finally:
        pub.close()
        sub.close()
    assert len(samples) == 6
    for s in samples[1:]:
        pan, tilt = pointing_angles(s.frame.poses)
        np.testing.assert_allclose(tilt, 0.2, atol=1e-9)
        # pan(t) = ω t + c across the frame's poses: ω = 1 rad/s, as the turret turned
        slope = np.polyfit(s.frame.pose_t, pan, 1)[0]
        assert slope == pytest.approx(_RampTurret.RATE, rel=0.02)
        assert s.turret is not None
