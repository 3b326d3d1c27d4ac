"""The emulated rig's parts: the turret's path the servos read, and the choice of device."""

from __future__ import annotations

import numpy as np
import pytest

from dronetrack.errors import ConfigError
from dronetrack.sim.emulate.livox import EmulatedLivox
from dronetrack.sim.emulate.livox2 import EmulatedLivox2
from dronetrack.sim.emulate.livox_stream import GridSource
from dronetrack.sim.emulate.rig import TurretTimeline, livox_device


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
