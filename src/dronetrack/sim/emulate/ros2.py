"""The emulated rig on ROS 2 (``dronetrack emulate --ros2``): the simulated sensor
published as livox_ros_driver2 publishes it, and the simulated turret as a ROS 2 joint
controller, over DDS with no ROS install (``sources.ros2.dds``).

Topics (defaults; ``Ros2Options`` renames them):

- ``/livox/lidar``: livox_ros_driver2/CustomMsg (or PointCloud2), reliable KEEP_LAST 10,
  one message per integration period;
- ``/tf``: tf2_msgs/TFMessage, reliable, ``turret_base → pan_link → tilt_link`` at
  100 Hz; ``/tf_static`` (reliable, transient local): ``world → turret_base`` and
  ``tilt_link → livox_frame``;
- ``/turret/joint_states``: sensor_msgs/JointState, best effort, ``pan`` and ``tilt``
  position [rad] and velocity [rad/s] at 100 Hz;
- ``/turret/command`` (read, reliable): sensor_msgs/JointState goals, as ``live
  --turret ros2:///turret`` sends them.

Clock.  livox_ros_driver2 stamps with the device's clock; the emulated device has no
time synchronisation, so every stamp is scenario time, nanoseconds since the stream
started (as the Livox emulator's packets and the truth file).  The stream starts when
the point topic gets its first subscriber (a driver publishes regardless; the
emulator waits so that a host gets the whole scenario) and stops if every
subscriber leaves; the next one starts the scenario again, as a Livox host's next
start of sampling does.  Joint states are published from the start (stamped 0 until
the stream starts), so a host can open the turret first.

Points.  The world is stepped in slices of ``slice_s`` (20 ms, a whole fraction of the
integration time T), each made when the scenario clock reaches its start with the
goals known then (so a goal acts after the turret preset's latency, as in
``simulate``).  Period k, [kT, (k+1)T), is published once the clock passes its end:
``timebase`` = header stamp = kT (the first firing of the period; the device fires
without pause), each point's ``offset_time`` = t − kT [ns], its reflectivity, tag 0
and scan line.  With ``pointcloud2`` the same points go out in livox_ros_driver2's
PointCloud2 layout (x, y, z, intensity, tag, line, timestamp).

Turret.  A goal on the command topic drives that axis of the world's turret plant
(``EmulatedRig.command_axis``, stamped with the scenario time it was taken at); the
joint states and ``/tf`` are the plant's pointing at their stamps, from the path the
slices' sensor poses came from (``EmulatedRig.turret_at``).  The /tf chain is the
one ``geometry.mount.turret_links`` gives (the URDF chain robot_state_publisher
would publish), its product world_T_livox_frame = ``sensor_poses(pan, tilt, mount)``;
``tf`` False publishes none (neither /tf nor /tf_static: a host finding part of a
chain would take it for the whole), so that a host takes the pose from the joint
states.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from typing import Protocol, Self

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError, DecodeError, DronetrackError
from dronetrack.formats.ros.livox_msg import LIVOX_POINT, LivoxCloud, encode_livox_cdr
from dronetrack.formats.ros.msgs import (
    JOINT_STATE,
    POINTCLOUD2,
    TF_MESSAGE,
    decode_joint_state,
    encode_joint_state,
    encode_points,
    encode_tf,
)
from dronetrack.formats.ros.names import ros_topic_name
from dronetrack.geometry.mount import MountGeometry, turret_links
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.emulate.livox_stream import PointChunk, PointSource
from dronetrack.sources.ros2.dds import DdsDomain

__all__ = [
    "CUSTOM_MSG",
    "Ros2Device",
    "Ros2Options",
    "custom_msg",
    "joint_links",
    "slice_length",
    "static_links",
]

CUSTOM_MSG = "livox_ros_driver2/msg/CustomMsg"
SLICE_S = 0.02  # the world's step, about the Livox emulator's device block
TICK_S = 0.005  # longest the device thread sleeps
MAX_TF_CATCH_UP = 20  # /tf samples published in one pass when the thread fell behind


@dataclass(frozen=True, slots=True)
class Ros2Options:
    """The emulated driver's topics and frames (module docstring)."""

    topic: str = "/livox/lidar"
    pointcloud2: bool = False
    frame_id: str = "livox_frame"
    turret_ns: str = "/turret"
    pan: str = "pan"
    tilt: str = "tilt"
    tf: bool = True
    state_hz: float = 100.0  # joint states and /tf samples a second

    @property
    def msg_type(self) -> str:
        return POINTCLOUD2 if self.pointcloud2 else CUSTOM_MSG

    @property
    def command_topic(self) -> str:
        return ros_topic_name(f"{self.turret_ns.rstrip('/')}/command")

    @property
    def states_topic(self) -> str:
        return ros_topic_name(f"{self.turret_ns.rstrip('/')}/joint_states")

    def checked(self) -> Self:
        """These options, or ConfigError naming the bad one."""
        ros_topic_name(self.topic)
        self.command_topic  # noqa: B018 (checks the namespace)
        if not self.frame_id or "\0" in self.frame_id:
            raise ConfigError(f"frame_id {self.frame_id!r} must be a non-empty name")
        if not 1.0 <= self.state_hz <= 1000.0:
            raise ConfigError(f"joint states go out at 1-1000 Hz, not {self.state_hz:g}")
        return self


def slice_length(period_s: float, target_s: float = SLICE_S) -> float:
    """The world's step: the whole fraction T / n of the integration time T nearest
    ``target_s`` (n ≥ 1), so that periods are made of whole slices."""
    if not period_s > 0:
        raise ConfigError(f"the integration time must be positive, got {period_s} s")
    return period_s / max(1, round(period_s / target_s))


# --- messages (pure) ---------------------------------------------------------------------


def custom_msg(
    stamp_ns: int,
    frame_id: str,
    xyz: FloatArray,
    t_ns: NDArray[np.int64],
    reflectivity: NDArray[np.uint8],
    line: NDArray[np.uint8] | None = None,
) -> bytes:
    """livox_ros_driver2/CustomMsg CDR bytes of points xyz (N, 3) [m] at times t_ns [ns]:
    timebase = header stamp = ``stamp_ns``, offset_time = t − stamp_ns (≥ 0)."""
    n = len(t_ns)
    offset = np.asarray(t_ns, np.int64) - int(stamp_ns)
    if n and (offset.min() < 0 or offset.max() > 2**32 - 1):
        raise ConfigError("a CustomMsg's points must lie within 4.29 s after its timebase")
    pts = np.zeros(n, LIVOX_POINT)
    pts["offset_time"] = offset
    pts["x"], pts["y"], pts["z"] = (np.asarray(xyz, np.float64)[:, k] for k in range(3))
    pts["reflectivity"] = reflectivity
    if line is not None:
        pts["line"] = line
    return encode_livox_cdr(LivoxCloud(int(stamp_ns), frame_id, int(stamp_ns), pts))


def joint_links(pan: float, tilt: float, mount: MountGeometry) -> list[tuple[str, str, FloatArray]]:
    """The moving /tf edges at (pan, tilt): turret_base → pan_link → tilt_link."""
    return turret_links(pan, tilt, mount)[1:3]


def static_links(
    mount: MountGeometry, frame_id: str = "livox_frame"
) -> list[tuple[str, str, FloatArray]]:
    """The fixed /tf_static edges: world → turret_base (the mount's base) and
    tilt_link → ``frame_id`` (the sensor on the tilt axis)."""
    links = turret_links(0.0, 0.0, mount)
    parent, _, T = links[3]
    return [links[0], (parent, frame_id, T)]


# --- the device --------------------------------------------------------------------------


class _Rig(Protocol):
    """What the device needs of the rig (``EmulatedRig``); monotonic times."""

    def command_axis(self, axis: str, angle: float, t: float) -> None: ...

    def turret_at(self, t: float) -> tuple[float, float]: ...

    def turret_rate(self, t: float) -> tuple[float, float]: ...


class Ros2Device:
    """The rig's LiDAR and turret as ROS 2 topics (module docstring); the rig's device
    (``rig.RigDevice``).  ``attach`` gives it the rig before ``start``; ``close`` stops
    the thread within about 1 s and leaves the domain.

    ``source``: the rig's slices (``EmulatedRig._stream``); ``period_s``: the
    integration time, a whole number of ``slice_s``; ``mount``: the turret's mount.

    Counters: ``messages_sent`` (point messages), ``points_built``, ``states_sent``,
    ``tf_sent``, ``commands_taken``, ``commands_bad``, ``starts``.
    """

    def __init__(
        self,
        source: PointSource,
        *,
        period_s: float,
        mount: MountGeometry,
        options: Ros2Options | None = None,
        domain_id: int | None = None,
        slice_s: float | None = None,
    ) -> None:
        self.options = (options or Ros2Options()).checked()
        self.source = source
        self.mount = mount
        self.period_ns = round(period_s * 1e9)
        slice_s = slice_length(period_s) if slice_s is None else slice_s
        self._block_ns = round(slice_s * 1e9)
        if self._block_ns <= 0 or self.period_ns % self._block_ns:
            raise ConfigError(
                f"the integration time {period_s:g} s is not a whole number of slices of "
                f"{slice_s:g} s"
            )
        self.sampling = False
        self.messages_sent = self.points_built = self.states_sent = self.tf_sent = 0
        self.commands_taken = self.commands_bad = self.starts = 0
        self.error: DronetrackError | None = None
        self._rig: _Rig | None = None
        self._t_start = time.monotonic()
        self._armed = True
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._reset()
        opts = self.options
        self.domain = DdsDomain(domain_id)
        try:
            self._points = self.domain.writer(opts.topic, opts.msg_type, "default")
            self._tf = self.domain.writer("/tf", TF_MESSAGE, "tf")
            self._tf_static = self.domain.writer("/tf_static", TF_MESSAGE, "static")
            self._states = self.domain.writer(opts.states_topic, JOINT_STATE, "sensor")
            self._commands = self.domain.reader(opts.command_topic, JOINT_STATE, "default")
        except BaseException:
            self.domain.close()
            raise

    # -- what the rig asks ----------------------------------------------------------------

    @property
    def block_ns(self) -> int:
        """Scenario time one slice spans [ns]."""
        return self._block_ns

    @property
    def stream_start(self) -> float:
        """time.monotonic() when the current (or last) stream started: scenario time 0."""
        return self._t_start

    @property
    def packets_sent(self) -> int:
        return self.messages_sent

    def attach(self, rig: _Rig) -> None:
        """The rig whose turret the joint states, /tf and goals are."""
        self._rig = rig

    # -- life cycle -----------------------------------------------------------------------

    def start(self) -> Self:
        if self._thread is None:
            if self.options.tf:
                self._static()
            self._thread = threading.Thread(target=self._run, name="emulated-ros2", daemon=True)
            self._thread.start()
        return self

    def close(self) -> None:
        """Stop the thread (it wakes at least every 5 ms) and leave the domain."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=1.0)
        self.domain.close()

    def _run(self) -> None:
        next_state = time.monotonic()
        try:
            while not self._stop.is_set():
                now = time.monotonic()
                self._take_commands(now)
                self._watch_subscribers(now)
                if self.sampling:
                    self._stream(now)
                if now >= next_state:
                    self._publish_state(now)
                    next_state = max(next_state + 1.0 / self.options.state_hz, now)
                wake = min(next_state, self._next_due())
                self._commands.wait(min(max(wake - time.monotonic(), 0.0), TICK_S))
        except DronetrackError as exc:  # a DDS write failed: the device stops streaming
            self.error = exc
            self.sampling = False

    # -- the turret -----------------------------------------------------------------------

    def _take_commands(self, now: float) -> None:
        rig = self._rig
        for raw in self._commands.drain():
            try:
                reading = decode_joint_state(raw)
            except DecodeError:
                self.commands_bad += 1
                continue
            self.commands_taken += 1
            if rig is None:
                continue
            for axis, name in (("pan", self.options.pan), ("tilt", self.options.tilt)):
                angle = reading.position.get(name, math.nan)
                if math.isfinite(angle):
                    rig.command_axis(axis, angle, now)

    def _scenario_ns(self, t: float) -> int:
        return max(round((t - self._t_start) * 1e9), 0) if self.starts else 0

    def _publish_state(self, now: float) -> None:
        rig = self._rig
        if rig is None:
            return
        pan, tilt = rig.turret_at(now)
        rates = rig.turret_rate(now)
        names = (self.options.pan, self.options.tilt)
        self._states.write(encode_joint_state(self._scenario_ns(now), names, (pan, tilt), rates))
        self.states_sent += 1

    def _static(self) -> None:
        links = static_links(self.mount, self.options.frame_id)
        self._tf_static.write(encode_tf(0, links))

    # -- the stream -----------------------------------------------------------------------

    def _reset(self) -> None:
        self._iter: Iterator[PointChunk] | None = None
        self._exhausted = False
        self._made_ns = 0  # the slices made cover scenario time [0, made)
        self._next_period = 0  # the next period to publish
        self._next_tf = 0  # the next /tf sample's index on the state grid
        self._parts: list[PointChunk] = []

    def _watch_subscribers(self, now: float) -> None:
        """Start the stream at the point topic's first subscriber; stop it when every
        subscriber has left (the next one starts the scenario again)."""
        if self._points.matched() == 0:
            self._armed = True
            self.sampling = False
        elif self._armed and not self.sampling:
            self._armed = False
            self._reset()
            self._t_start = now
            self.starts += 1
            self.sampling = True
            src = self.source
            chunks: Iterable[PointChunk] = src() if callable(src) else src
            self._iter = iter(chunks)

    def _next_due(self) -> float:
        """time.monotonic() of the stream's next event (a slice or period to make)."""
        if not self.sampling:
            return math.inf
        next_ns = min(self._made_ns, (self._next_period + 1) * self.period_ns)
        return self._t_start + next_ns * 1e-9

    def _stream(self, now: float) -> None:
        s_ns = round((now - self._t_start) * 1e9)
        while not self._exhausted and self._made_ns <= s_ns:
            assert self._iter is not None
            chunk = next(self._iter, None)
            if chunk is None:
                self._exhausted = True
                break
            self._parts.append(chunk)
            self.points_built += len(chunk.t_ns)
            end = chunk.end_ns
            if end is None:
                end = int(chunk.t_ns[-1]) + 1 if len(chunk.t_ns) else self._made_ns
            self._made_ns = max(self._made_ns, end)
        reached = min(s_ns, self._made_ns)
        if self.options.tf:
            self._publish_tf(reached)
        while (self._next_period + 1) * self.period_ns <= reached or (
            self._exhausted and self._next_period * self.period_ns < self._made_ns
        ):
            self._publish_period()
        if self._exhausted and self._next_period * self.period_ns >= self._made_ns:
            self.sampling = False  # the scenario has been streamed

    def _publish_tf(self, reached_ns: int) -> None:
        rig = self._rig
        if rig is None:
            return
        step_ns = round(1e9 / self.options.state_hz)
        last = reached_ns // step_ns
        first = max(self._next_tf, last - MAX_TF_CATCH_UP + 1)
        for m in range(first, last + 1):
            stamp = m * step_ns
            pan, tilt = rig.turret_at(self._t_start + stamp * 1e-9)
            self._tf.write(encode_tf(stamp, joint_links(pan, tilt, self.mount)))
            self.tf_sent += 1
        self._next_tf = max(self._next_tf, last + 1)

    def _publish_period(self) -> None:
        """Publish period k = ``_next_period``: the points made with t < (k+1)T."""
        k = self._next_period
        start, end = k * self.period_ns, (k + 1) * self.period_ns
        mine: list[PointChunk] = []
        rest: list[PointChunk] = []
        for c in self._parts:
            cut = int(np.searchsorted(c.t_ns, end))
            if cut:
                mine.append(_part(c, slice(0, cut)))
            if cut < len(c.t_ns):
                rest.append(_part(c, slice(cut, None)))
        self._parts = rest
        xyz = np.concatenate([c.xyz for c in mine]) if mine else np.zeros((0, 3))
        t_ns = np.concatenate([c.t_ns for c in mine]) if mine else np.zeros(0, np.int64)
        refl = np.concatenate([c.reflectivity for c in mine]) if mine else np.zeros(0, np.uint8)
        line = np.concatenate([_lines(c) for c in mine]) if mine else np.zeros(0, np.uint8)
        keep = t_ns >= start  # a point before its period cannot be sent: none should be
        xyz, t_ns, refl, line = xyz[keep], t_ns[keep], refl[keep], line[keep]
        fid = self.options.frame_id
        if self.options.pointcloud2:
            t_rel = ((t_ns - start) * 1e-9).astype(np.float64)
            intensity = refl.astype(np.float64)
            raw = encode_points(start, fid, xyz, t_rel, intensity, line.astype(np.float64))
        else:
            raw = custom_msg(start, fid, xyz, t_ns, refl, line)
        self._points.write(raw)
        self.messages_sent += 1
        self._next_period = k + 1


def _part(c: PointChunk, sel: slice) -> PointChunk:
    line = None if c.line is None else c.line[sel]
    return PointChunk(c.xyz[sel], c.t_ns[sel], c.reflectivity[sel], line=line)


def _lines(c: PointChunk) -> NDArray[np.uint8]:
    return np.zeros(len(c.t_ns), np.uint8) if c.line is None else c.line
