"""``--turret ros2:///NAMESPACE`` on a loopback DDS domain, against a servo node written
in the test: goals as JointState or Interbotix JointGroupCommand (decoded with rosbags),
angles from joint_states, rate commands, holding on close, a silent node, bad URIs.
Every wait is bounded."""

from __future__ import annotations

import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.typesys import get_types_from_msg

from dronetrack.errors import ConfigError, DeviceError
from dronetrack.formats.ros.msgs import JOINT_STATE, encode_joint_state
from dronetrack.types import TurretCommand
from ros2_helpers import loopback_dds

GROUP_MSG = "string name\nfloat32[] cmd\n"


class ServoNode:
    """A turret node: publishes its joints (pan, tilt) at 100 Hz on ``states``, moves them
    to each goal it reads on ``command`` at once, and keeps every goal it got."""

    def __init__(self, domain_id: int, command: str, msg_type: str, states: str) -> None:
        from rosbags.typesys import Stores, get_typestore

        from dronetrack.sources.ros2.dds import DdsDomain

        self.ts = get_typestore(Stores.ROS2_HUMBLE)
        self.ts.register(get_types_from_msg(GROUP_MSG, "interbotix_xs_msgs/msg/JointGroupCommand"))
        self.domain = DdsDomain(domain_id)
        self.msg_type = msg_type
        self.reader = self.domain.reader(command, msg_type, "default")
        self.writer = self.domain.writer(states, JOINT_STATE, "sensor")
        self.angles = [0.1, -0.2]
        self.goals: list[Any] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    def _loop(self) -> None:
        while not self._stop.is_set():
            for raw in self.reader.drain():
                msg = self.ts.deserialize_cdr(raw, self.msg_type)
                self.goals.append(msg)
                if self.msg_type == JOINT_STATE:
                    self.angles = [float(v) for v in msg.position]
                else:
                    self.angles = [float(v) for v in msg.cmd]
            names = ["pan", "tilt", "gripper"]
            self.writer.write(encode_joint_state(time.time_ns(), names, [*self.angles, 9.0]))
            time.sleep(0.01)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(2.0)
        self.domain.close()


def _until(cond: Any, timeout_s: float = 3.0) -> None:
    end = time.monotonic() + timeout_s
    while not cond():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.01)


@pytest.mark.parametrize(
    ("query", "command", "msg_type"),
    [
        ("", "/turret/command", JOINT_STATE),
        (
            "?type=interbotix_xs_msgs/msg/JointGroupCommand",
            "/turret/commands/joint_group",
            "interbotix_xs_msgs/msg/JointGroupCommand",
        ),
    ],
)
def test_goals_out_and_angles_in(
    query: str, command: str, msg_type: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain = loopback_dds(tmp_path, monkeypatch)
    from dronetrack.actuators.ros2_turret import Ros2Turret

    node = ServoNode(domain, command, msg_type, "/turret/joint_states")
    try:
        turret = Ros2Turret(f"ros2:///turret{query}", domain, wait_s=5.0)
        state = turret.state()
        assert state is not None
        assert (state.pan, state.tilt) == pytest.approx((0.1, -0.2))
        _until(lambda: turret._writer.matched() > 0)
        turret.command(TurretCommand(0.0, 0.5, float("nan"), "position"))  # tilt kept
        _until(lambda: len(node.goals) == 1)
        # a rate command leads the newest joint state: wait until it shows the goal
        _until(lambda: turret.state().pan == pytest.approx(0.5, abs=1e-6))  # type: ignore[union-attr]
        turret.command(TurretCommand(0.0, 1.0, -1.0, "velocity"))  # 0.1 s ahead
        _until(lambda: len(node.goals) == 2)
        _until(lambda: turret.state().pan == pytest.approx(0.6, abs=1e-6))  # type: ignore[union-attr]
        turret.close()  # holds where it is
        _until(lambda: len(node.goals) == 3)
    finally:
        node.close()
    if msg_type == JOINT_STATE:
        assert list(node.goals[0].name) == ["pan", "tilt"]
        got = [list(g.position) for g in node.goals]
    else:
        assert node.goals[0].name == "turret"
        got = [list(g.cmd) for g in node.goals]
    np.testing.assert_allclose(got, [[0.5, -0.2], [0.6, -0.3], [0.6, -0.3]], atol=1e-6)


def test_a_silent_turret_is_a_device_error(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Opening gives up after wait_s, naming the topic: 0.5 s of 50 ms waits for a
    joint state, so about ten of them, not a spin nor the default 10 s."""
    domain = loopback_dds(tmp_path, monkeypatch)
    from dronetrack.actuators.ros2_turret import Ros2Turret
    from dronetrack.sources.ros2.dds import RawReader

    waits: list[float] = []
    wait = RawReader.wait

    def wait_and_note(self: RawReader, timeout_s: float) -> bool:
        waits.append(timeout_s)
        return wait(self, timeout_s)

    monkeypatch.setattr(RawReader, "wait", wait_and_note)
    with pytest.raises(
        DeviceError, match=r"no joint state with 'pan' and 'tilt' on /pt/joint_states within 0\.5 s"
    ):
        Ros2Turret("ros2:///pt", domain, wait_s=0.5)
    assert set(waits) == {0.05}
    assert 1 <= len(waits) <= 0.5 / 0.05 + 2  # the last one may begin just before the end


@pytest.mark.parametrize(
    ("uri", "problem"),
    [
        ("ros2://host/turret", "three '/'"),
        ("ros2:///turret?speed=1", "unknown key"),
        ("ros2:///turret?type=std_msgs/msg/String", "type must be"),
        ("ros2:///turret?command=/a//b", "repeat '/'"),
    ],
)
def test_bad_turret_uris(uri: str, problem: str) -> None:
    from dronetrack.actuators.turrets import check_turret_uri

    with pytest.raises(ConfigError, match=problem):
        check_turret_uri(uri)
