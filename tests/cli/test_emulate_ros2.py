"""The whole live chain over ROS 2 on one machine: ``dronetrack emulate --ros2`` (the
simulator in real time behind an emulated livox_ros_driver2, /tf and a ROS 2 turret
controller) in its own process, and ``dronetrack live --lidar ros2:///livox/lidar
--turret ros2:///turret`` against it, on a loopback DDS domain of the test's own, for
20 s of the ``default`` flight after its 10 s scan, the sensor's random false alarms off
(as in ``test_live_end_to_end.py``: they fall differently in the two runs compared).

The bars are those of ``test_live_end_to_end.py``: against ``dronetrack simulate`` of
the same seed and flight time, coverage within 10 points, the same frames, no frame
dropped, no malformed message.  Measured: live 95.0 %, simulate 95.0 %.

Poses come from /tf here.  Without it (``emulate --ros2 --no-tf``) the source takes
them from the turret's joint states: that path is ``tests/sources/test_ros2_dds.py``'s,
and the emulator's silence on /tf is ``tests/sim/emulate/test_ros2.py``'s.  The same
run end to end with ``--no-tf`` gave 95.0 % in every one of 4 runs; it left the suite
for time."""

from __future__ import annotations

from pathlib import Path

import pytest

from emulated_rig import (
    FLIGHT_S,
    assert_tracks_as_simulated,
    emulator,
    live_then_simulate,
    without_false_alarms,
)
from ros2_helpers import loopback_dds


@pytest.mark.slow
def test_live_over_ros2_against_the_emulated_rig_tracks_as_the_simulation_does(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain = str(loopback_dds(tmp_path, monkeypatch))
    ros = ["--ros2", "--ros-domain-id", domain]
    scenario = without_false_alarms(tmp_path, "default")
    with emulator(tmp_path, scenario, "--seed", "0", "--duration", FLIGHT_S, *ros) as emu:
        assert emu.lines[0].startswith("lidar: ros2:///livox/lidar  (livox_ros_driver2/msg/")
        assert emu.lines[1].startswith("turret: ros2:///turret  (sensor_msgs/JointState")
        got, want = live_then_simulate(
            tmp_path,
            emu,
            scenario,
            "ros2:///livox/lidar",
            "ros2:///turret",
            "--ros-domain-id",
            domain,
        )
        assert emu.proc.wait(timeout=15.0) == 0  # the scenario streamed, it ends by itself
    assert got["lidar"] == "ros2:///livox/lidar"
    assert_tracks_as_simulated(got, want)
