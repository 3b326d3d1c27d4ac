"""The emulated rig's parts: the turret's path the servos read, and the choice of device."""

from __future__ import annotations

import numpy as np
import pytest

from dronetrack.config.run import SensorConfig
from dronetrack.errors import ConfigError
from dronetrack.sim.emulate.lidars import DEVICES, default_velodyne_dest, host_uri, lidar_device
from dronetrack.sim.emulate.livox import EmulatedLivox
from dronetrack.sim.emulate.livox2 import EmulatedLivox2
from dronetrack.sim.emulate.livox_stream import GridSource
from dronetrack.sim.emulate.rig import livox_device
from dronetrack.sim.emulate.timeline import TurretTimeline
from dronetrack.sim.emulate.velodyne import EmulatedVelodyne


def test_the_timeline_interpolates_the_path_and_holds_outside_it() -> None:
    line = TurretTimeline()
    line.reset(0.0, 0.1, -0.2)
    assert line.at(5.0) == (0.1, -0.2)
    # pan ramps at 2 rad/s from 0.1, tilt holds: q(t) = 0.1 + 2 t
    t = np.linspace(0.0, 0.1, 101)
    line.add(t, 0.1 + 2.0 * t, np.full(101, -0.2))
    assert len(line.t) == 101  # the first sample repeats the last one: not added twice
    assert line.at(0.0505) == pytest.approx((0.1 + 2.0 * 0.0505, -0.2))
    assert line.at(-1.0) == (0.1, -0.2)
    assert line.at(1.0) == pytest.approx((0.3, -0.2))
    # the slope over ±10 ms, clipped to the samples at the ends
    assert line.rate(0.05) == pytest.approx((2.0, 0.0))
    assert line.rate(0.1) == pytest.approx((2.0, 0.0))
    assert line.rate(0.2) == (0.0, 0.0)  # past the end: no path
    assert line.end == pytest.approx(0.1)


def test_the_timeline_keeps_only_its_last_seconds() -> None:
    line = TurretTimeline(keep_s=1.0)
    line.reset(0.0, 0.0, 0.0)
    t = np.arange(1, 3001) * 1e-3
    line.add(t, t, -t)
    assert line.t[0] == pytest.approx(2.0)
    assert line.t[-1] == pytest.approx(3.0)
    assert line.at(0.5) == pytest.approx((2.0, -2.0))  # forgotten: held at the oldest kept


@pytest.mark.parametrize(
    ("sensor", "kind", "dev_type"),
    [("avia", EmulatedLivox, 7), ("mid40", EmulatedLivox, 1), ("mid360", EmulatedLivox2, None)],
)
def test_each_livox_sensor_gets_its_device(sensor: str, kind: type, dev_type: int | None) -> None:
    dev = livox_device(sensor, any_ports=True)(GridSource(10_000, 0.1))
    try:
        assert isinstance(dev, kind)
        assert getattr(dev, "dev_type", None) == dev_type
        assert dev.address[0] == "127.0.0.1"
    finally:
        dev.close()


def test_a_sensor_no_device_emulates_is_refused() -> None:
    with pytest.raises(
        ConfigError, match=r"sensors avia, mid40, mid360, vlp16, vlp16-side;.*'file:scan.npy'"
    ):
        livox_device("file:scan.npy")


@pytest.mark.parametrize(("sensor", "side"), [("vlp16", False), ("vlp16-side", True)])
def test_each_vlp16_sensor_gets_the_velodyne_device_at_its_spin(sensor: str, side: bool) -> None:
    cfg = SensorConfig(model=sensor, rpm=900.0)
    dev = lidar_device(cfg, dest=("127.0.0.1", 23_680))(GridSource(10_000, 0.1))
    try:
        assert isinstance(dev, EmulatedVelodyne)
        assert dev.rpm == 900.0
        assert (dev.rotation is not None) == side
        assert host_uri(DEVICES[sensor], dev) == "velodyne://127.0.0.1:23680"
    finally:
        dev.close()
    # by default a loopback VLP-16 sends to 127.0.0.1:2368, as a host on this machine listens
    dev = lidar_device(sensor)(GridSource(10_000, 0.1))
    try:
        assert isinstance(dev, EmulatedVelodyne)
        assert dev.dest == ("127.0.0.1", 2368)
        assert dev.rpm == 600.0
    finally:
        dev.close()
    assert default_velodyne_dest("192.168.1.201") == ("255.255.255.255", 2368)
