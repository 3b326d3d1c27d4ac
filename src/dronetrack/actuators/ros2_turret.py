"""A turret driven over ROS 2 (``--turret ros2:///NAMESPACE``), through DDS with no ROS
install (``sources.ros2.dds``).

    ros2:///turret[?command=/TOPIC&states=/TOPIC&type=pkg/msg/Name&pan=NAME&tilt=NAME&group=NAME]

Goals go out as ``sensor_msgs/JointState`` (names and positions [rad]) on
``NAMESPACE/command`` by default, or, with ``type=interbotix_xs_msgs/msg/JointGroupCommand``,
as Interbotix's joint-group command (``name`` = ``group``, default ``turret``; ``cmd`` =
[pan, tilt]) on ``NAMESPACE/commands/joint_group``, the topic Interbotix's xs_sdk
listens on.  The measured angles come from ``sensor_msgs/JointState`` on
``NAMESPACE/joint_states``: the joints named ``pan`` and ``tilt`` (the URI's keys
rename them).  A rate command becomes a goal 0.1 s ahead of the newest reading, as
the Dynamixel driver does.  Commands are reliable KEEP_LAST 10, states read best
effort (a sensor stream).

Readings.  Opening waits for the first joint state (a turret that sends none is a
DeviceError naming the topic); then a thread of the turret's own
(``state_poller.StatePoller``) takes each one as it arrives, stamped on the host's
clock then, so ``readings`` gives a live frame every reading since the last frame
(``sources.live`` interpolates the pose per point between them).  ``state`` is the
newest.  No joint state for 3 × ``STATE_WAIT_S`` ends the run, naming the topic.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from urllib.parse import parse_qsl, urlsplit

from dronetrack.actuators.state_poller import StatePoller
from dronetrack.errors import ConfigError, DecodeError, DeviceError
from dronetrack.formats.ros.msgs import (
    JOINT_GROUP_COMMAND,
    JOINT_STATE,
    decode_joint_state,
    encode_joint_command,
    encode_joint_state,
)
from dronetrack.formats.ros.names import ROS2_SCHEME, check_type_name, ros_topic_name
from dronetrack.sources.ros2.dds import DdsDomain
from dronetrack.types import TurretCommand, TurretState

__all__ = ["Ros2Turret", "Ros2TurretUri", "parse_ros2_turret_uri"]

LEAD_S = 0.1  # a rate command's goal is this far ahead of the newest reading
STATE_WAIT_S = 0.5  # a reading is missed after this long without a joint state
STALE_S = 0.1  # ``readings`` waits for one newer than this before the time asked for
KEYS = ("command", "states", "type", "pan", "tilt", "group")


class Ros2TurretUri:
    """The parts of a ``ros2:///NAMESPACE?…`` turret URI (module docstring)."""

    def __init__(self, uri: str) -> None:
        parts = urlsplit(uri)
        if not uri.startswith(ROS2_SCHEME) or parts.netloc:
            raise ConfigError(f"--turret {uri!r}: give ros2:///NAMESPACE (three '/')")
        query = dict(parse_qsl(parts.query, keep_blank_values=True))
        unknown = sorted(set(query) - set(KEYS))
        if unknown:
            raise ConfigError(
                f"--turret {uri!r}: unknown key(s) {', '.join(unknown)} (known: {', '.join(KEYS)})"
            )
        try:
            ns = "" if parts.path in ("", "/") else ros_topic_name(parts.path)
            msg_type = query.get("type", JOINT_STATE)
            pkg, msg = check_type_name(msg_type)
            self.msg_type = f"{pkg}/msg/{msg}"
            if self.msg_type not in (JOINT_STATE, JOINT_GROUP_COMMAND):
                raise ConfigError(f"type must be {JOINT_STATE} or {JOINT_GROUP_COMMAND}")
            default = "commands/joint_group" if self.msg_type == JOINT_GROUP_COMMAND else "command"
            self.command = ros_topic_name(query.get("command", f"{ns}/{default}"))
            self.states = ros_topic_name(query.get("states", f"{ns}/joint_states"))
        except ConfigError as exc:
            raise ConfigError(f"--turret {uri!r}: {exc}") from None
        self.pan = query.get("pan", "pan")
        self.tilt = query.get("tilt", "tilt")
        self.group = query.get("group", "turret")


def parse_ros2_turret_uri(uri: str) -> Ros2TurretUri:
    return Ros2TurretUri(uri)


class Ros2Turret:
    """A turret on ROS 2 topics (module docstring); ``close`` holds it where it is and
    leaves the domain."""

    def __init__(
        self,
        uri: str,
        domain_id: int | None = None,
        *,
        wait_s: float = 10.0,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.uri = Ros2TurretUri(uri)
        self.name = f"ROS 2 turret ({self.uri.command} → {self.uri.states})"
        self.clock = clock
        self.domain = DdsDomain(domain_id)
        self._writer = self.domain.writer(self.uri.command, self.uri.msg_type, "default")
        self._reader = self.domain.reader(self.uri.states, JOINT_STATE, "sensor")
        self._newest: TurretState | None = None
        self.commands = 0
        self.bad_states = 0
        end = time.monotonic() + wait_s
        while self._take() is None:
            if time.monotonic() > end:
                self.domain.close()
                raise DeviceError(
                    f"{self.name}: no joint state with {self.uri.pan!r} and {self.uri.tilt!r} "
                    f"on {self.uri.states} within {wait_s:g} s"
                )
            self._reader.wait(0.05)
        # from here on only the poller's thread takes from the reader
        self.poller = StatePoller(self._next_reading, 1000.0, name=self.name)
        self.poller.start()

    def _next_reading(self) -> TurretState:
        """The next joint state as it arrives (the poller's read); DeviceError (a miss)
        after STATE_WAIT_S without one."""
        before = self._newest
        end = time.monotonic() + STATE_WAIT_S
        while True:
            newest = self._take()
            if newest is not None and newest is not before:
                return newest
            left = end - time.monotonic()
            if left <= 0:
                raise DeviceError(
                    f"{self.name}: no joint state on {self.uri.states} for {STATE_WAIT_S:g} s"
                )
            self._reader.wait(min(left, 0.05))

    def _take(self) -> TurretState | None:
        """Take in the readings that came; the newest."""
        for raw in self._reader.drain():
            try:
                r = decode_joint_state(raw)
            except DecodeError:
                self.bad_states += 1
                continue
            pan, tilt = r.position.get(self.uri.pan), r.position.get(self.uri.tilt)
            if pan is None or tilt is None or not (math.isfinite(pan) and math.isfinite(tilt)):
                continue
            rates = (r.velocity.get(self.uri.pan, 0.0), r.velocity.get(self.uri.tilt, 0.0))
            pan_rate, tilt_rate = (v if math.isfinite(v) else 0.0 for v in rates)
            self._newest = TurretState(self.clock(), pan, tilt, pan_rate, tilt_rate)
        return self._newest

    def state(self) -> TurretState | None:
        return self._newest  # the poller's thread replaces it whole

    @property
    def reads_missed(self) -> int:
        """Waits of STATE_WAIT_S that saw no joint state."""
        return self.poller.misses

    def readings(self, until: float = -math.inf, timeout_s: float = 1.0) -> list[TurretState]:
        """The joint states taken since the last call, oldest first, stamped on ``clock``
        as they arrived, once the newest is no more than STALE_S older than ``until``
        (waiting up to ``timeout_s``); DeviceError if they stopped coming."""
        return self.poller.take(until - STALE_S, timeout_s)

    def command(self, command: TurretCommand) -> None:
        newest = self._newest
        pan, tilt = command.pan, command.tilt
        if command.mode == "velocity":
            if newest is None:
                return
            pan = newest.pan + (pan if math.isfinite(pan) else 0.0) * LEAD_S
            tilt = newest.tilt + (tilt if math.isfinite(tilt) else 0.0) * LEAD_S
        if newest is not None:  # NaN: keep that axis where it is
            pan = pan if math.isfinite(pan) else newest.pan
            tilt = tilt if math.isfinite(tilt) else newest.tilt
        if not (math.isfinite(pan) and math.isfinite(tilt)):
            return
        self._send(pan, tilt)

    def _send(self, pan: float, tilt: float) -> None:
        if self.uri.msg_type == JOINT_GROUP_COMMAND:
            raw = encode_joint_command(self.uri.group, [pan, tilt])
        else:
            raw = encode_joint_state(time.time_ns(), [self.uri.pan, self.uri.tilt], [pan, tilt])
        self._writer.write(raw)
        self.commands += 1

    def close(self) -> None:
        """Hold the present position, then leave the domain."""
        self.poller.stop()
        try:
            newest = self._newest
            if newest is not None:
                self._send(newest.pan, newest.tilt)
        finally:
            self.domain.close()
