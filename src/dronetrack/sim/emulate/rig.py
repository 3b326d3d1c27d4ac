"""A whole rig emulated in real time: the simulator behind a LiDAR on UDP (a Livox, or
a Velodyne VLP-16: ``lidars``) and a pan-tilt turret on a pseudo-terminal (two XM430
servos, or a FLIR PTU speaking its ASCII commands), for ``dronetrack live`` (or any
host) to drive with no hardware.

Clock.  Scenario time s starts when the host starts sampling: s = τ − τ₀, with τ the
host's ``time.monotonic()`` and τ₀ the moment the device took the start command (a
VLP-16, which takes none: the moment its first packet reached a host).  The
device's packets carry s too (nanoseconds since sampling started, no time
synchronisation), so the point times, the truth file and the servos share one time
base.  Another start after a stop runs the scenario again from the start, on a fresh
world built the same way.

Points.  The world is stepped in slices of one device block (whole packets, about
20 ms: ``StreamingDevice.block_ns``; the world's integration time is set to it).  The
device asks for a slice just before its first packet is due, and each slice says how
far it covers (``PointChunk.end_ns``), so a slice is made at τ₀ + s₀ − one packet,
with the turret's goals known then, and its points leave at their own times.  One
slice takes 1-2 ms to make for the Avia (the world's ray casting; 1.1 ms median).

Turret.  The two servos' joints (``SimJoint``, a ``servos.JointModel``) are the
world's own turret plant (``sim.turret.TurretPlant``): a goal the host writes to a
servo is queued on that axis of the plant, stamped with the scenario time it arrives
at, and acts after the axis's latency as in ``simulate``.  Present position is the
plant's pointing at the scenario time of the read, interpolated in the path the plant
took (``TurretTimeline``), the same path the slices' sensor poses came from; present
velocity is the slope of that path over ±10 ms.  While sampling, the plant runs ahead
of the clock by at most a slice (the slices move it); a read the slices have not
reached yet gets the newest pointing.  Before the first start of sampling the servos
move as real ones do, on an idle clock from the rig's start (s = s₀ + τ − τ_start,
s₀ the world's start time): a goal acts after the axis's latency and reads follow
the move, so a host can drive the turret before its LiDAR samples.  At the first
start the plant's clock is set back to s₀ with its state kept (angles, rates and
queued goals), and the run carries on from where the turret is.  After the stream
ends, or after a stop, reads move the plant on to their own time; a plant at rest
jumps there rather than integrating the wait.  The profile velocity and acceleration the host
writes are kept in the control table but do not change the simulated dynamics, which
are the scenario's turret preset's.  Protocol errors are the servo emulator's
(``servos``).  A PTU (``ptu``) drives the same two joints: a ``PP``/``TP`` goal is
queued on the plant the same way, and a position query answers the same path.

Truth.  With a truth file, each start rewrites it: a header ``t,x,y,z`` and one row
per slice end (and one at s = 0): the target's true position [m] in the world frame at
scenario time t [s], written and flushed as each slice is made.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import IO, Any, Protocol, Self

import numpy as np

from dronetrack.config.rig import TurretSpec
from dronetrack.errors import ConfigError, DeviceError
from dronetrack.formats.ptu import DEFAULT_BAUD
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.emulate.lidars import (
    DEVICES,
    LidarModel,
    LivoxModel,
    lidar_device,
    livox_device,
)
from dronetrack.sim.emulate.livox_stream import PointChunk, PointSource, frame_chunks
from dronetrack.sim.emulate.ptu import EmulatedPtu
from dronetrack.sim.emulate.ptu_link import PtyPtuLink
from dronetrack.sim.emulate.pty_link import PtyLink
from dronetrack.sim.emulate.servos import PtyServoLink, ServoBus, turret_bus
from dronetrack.sim.emulate.timeline import TurretTimeline
from dronetrack.sim.world import FrameTruth, SimWorld
from dronetrack.types import Frame

__all__ = [
    "DEVICES",
    "DeviceFactory",
    "EmulatedRig",
    "LidarModel",
    "LivoxModel",
    "RigDevice",
    "SimJoint",
    "lidar_device",
    "livox_device",
]


class RigDevice(Protocol):
    """What the rig needs of its LiDAR: ``livox_stream.StreamingDevice`` or the ROS 2
    driver of ``sim.emulate.ros2``.  It calls its source at each start of sampling."""

    @property
    def block_ns(self) -> int: ...

    @property
    def stream_start(self) -> float: ...

    sampling: bool
    points_built: int

    @property
    def packets_sent(self) -> int: ...

    def start(self) -> Any: ...

    def close(self) -> None: ...


DeviceFactory = Callable[[PointSource], RigDevice]
WorldFactory = Callable[[float], SimWorld]  # slice length [s] → a fresh world


class SimJoint:
    """One axis of the rig's simulated turret as a servo's joint (``servos.JointModel``);
    t is the servo bus's clock (time.monotonic)."""

    def __init__(self, rig: EmulatedRig, axis: str) -> None:
        if axis not in ("pan", "tilt"):
            raise ConfigError(f"a turret axis is 'pan' or 'tilt', not {axis!r}")
        self.rig = rig
        self.axis = axis
        self._index = 0 if axis == "pan" else 1
        self.profile_rate = 0.0  # as the host wrote them; the dynamics are the preset's
        self.profile_accel = 0.0

    def profile(self, rate: float, accel: float, t: float) -> None:
        self.profile_rate, self.profile_accel = rate, accel

    def goal(self, angle: float, t: float) -> None:
        self.rig.command_axis(self.axis, angle, t)

    def position(self, t: float) -> float:
        return self.rig.turret_at(t)[self._index]

    def velocity(self, t: float) -> float:
        return self.rig.turret_rate(t)[self._index]


class EmulatedRig:
    """The simulator in real time behind an emulated LiDAR and two emulated XM430
    servos, or with ``ptu`` (a turret preset) an emulated FLIR PTU paced at
    ``ptu_baud``, on a pseudo-terminal (see the module docstring).

    ``make_world(slice_s)`` builds the scenario's world with integration time
    ``slice_s`` (called once now and again at each restart of sampling);
    ``make_device(source)`` the LiDAR (``lidar_device``); ``duration_s``: scenario time
    streamed from the start of sampling; ``serial_link``: a symlink to the servos'
    pseudo-terminal; ``truth``: the truth CSV.  ``start`` opens the servo link and
    starts the device; ``close`` stops both and closes the truth file.

    ``on_slice(frame, truth)`` sees each slice as it is made (in the device's thread).
    ``servos`` False opens no pseudo-terminal: a device that takes the turret's goals
    itself (``sim.emulate.ros2``) calls ``command_axis``, ``turret_at`` and
    ``turret_rate``.

    Events: ``started`` (a host started sampling), ``finished`` (the stream of
    ``duration_s`` has been sent).  Counters: ``slices``, ``points`` (returns made),
    ``truth_rows``, ``starts``.
    """

    def __init__(
        self,
        make_world: WorldFactory,
        make_device: DeviceFactory,
        *,
        duration_s: float,
        serial_link: Path | str | None = None,
        truth: Path | str | None = None,
        pan_id: int = 1,
        tilt_id: int = 2,
        clock: Callable[[], float] = time.monotonic,
        on_slice: Callable[[Frame, FrameTruth], None] | None = None,
        ptu: TurretSpec | None = None,
        ptu_baud: int = DEFAULT_BAUD,
        servos: bool = True,
    ) -> None:
        if not duration_s > 0:
            raise ConfigError(f"the emulated run needs a positive duration, got {duration_s} s")
        self.duration_s = float(duration_s)
        self.serial_link = Path(serial_link) if serial_link is not None else None
        self.truth_path = Path(truth) if truth is not None else None
        self.started = threading.Event()
        self.finished = threading.Event()
        self.on_slice = on_slice
        self.slices = 0
        self.points = 0
        self.truth_rows = 0
        self.starts = 0
        self._lock = threading.RLock()
        self._anchor: float | None = None
        self._clock = clock
        self._idle_from = clock()  # τ_start: the idle clock's origin (reset by start)
        self._make_world = make_world
        self._truth: IO[str] | None = None
        self.timeline = TurretTimeline()
        self.device = make_device(self._stream)
        self.slice_s = self.device.block_ns * 1e-9
        try:
            self.world = make_world(self.slice_s)
            if not math.isclose(self.world.integration_time, self.slice_s, rel_tol=1e-12):
                raise ConfigError(
                    f"the emulated world steps {self.world.integration_time} s, not the "
                    f"device's block of {self.slice_s} s"
                )
            self._fresh = True
            self._t_start = self.world.plant.time  # s₀
            self._reset_timeline()
            self._open_truth()
        except BaseException:
            self.device.close()
            raise
        self.bus: ServoBus = turret_bus(
            pan_id, tilt_id, clock=clock, pan=SimJoint(self, "pan"), tilt=SimJoint(self, "tilt")
        )
        self.ptu = (
            EmulatedPtu.from_turret(ptu, SimJoint(self, "pan"), SimJoint(self, "tilt"), clock)
            if ptu is not None
            else None
        )
        self.ptu_baud = ptu_baud
        self.link: PtyLink | None = None
        self._servos = servos
        self._running = False

    # -- life cycle ---------------------------------------------------------------------

    def start(self) -> Self:
        """Open the turret's pseudo-terminal (and its link; not with ``servos`` False, when
        the device drives the turret itself) and start the device; if either fails, the
        rig is closed."""
        if not self._running:
            if self._anchor is None:
                self._idle_from = self._clock()
            try:
                if self._servos and self.ptu is not None:
                    self.link = PtyPtuLink(self.ptu, self.serial_link, baud=self.ptu_baud)
                elif self._servos:
                    self.link = PtyServoLink(self.bus, self.serial_link)
                self.device.start()
            except BaseException:
                self.close()
                raise
            self._running = True
        return self

    def close(self) -> None:
        """Stop the device and the servo link (removing the link) and close the truth
        file; safe to call twice."""
        self.device.close()
        if self.link is not None:
            self.link.close()
        with self._lock:
            if self._truth is not None:
                self._truth.close()
                self._truth = None

    def __enter__(self) -> Self:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    @property
    def address(self) -> tuple[str, int]:
        """(ip, port) of the device's command socket."""
        ip, port = self.device.address  # type: ignore[attr-defined]
        return str(ip), int(port)

    @property
    def serial_device(self) -> str:
        """The path a host opens for the turret: the link if asked for, else the pty."""
        if self.link is None:
            raise DeviceError("the emulated rig is not started")
        return self.link.device

    @property
    def turret_uri(self) -> str:
        """The ``--turret`` URI a host opens: ``ptu://PATH`` (with ``?baud=`` unless the
        unit's power-up 9600) or ``dynamixel://PATH``."""
        if self.ptu is None:
            return f"dynamixel://{self.serial_device}"
        baud = "" if self.ptu_baud == DEFAULT_BAUD else f"?baud={self.ptu_baud}"
        return f"ptu://{self.serial_device}{baud}"

    # -- the clock --------------------------------------------------------------------

    def scenario_time(self, t: float | None = None) -> float | None:
        """Scenario time [s] at monotonic time ``t`` (now if None); None before sampling."""
        anchor = self._anchor
        if anchor is None:
            return None
        return (time.monotonic() if t is None else t) - anchor

    def _stamp(self, t: float) -> float:
        """The scenario time of a servo exchange at ``t``: on the idle clock before the
        first start of sampling, s₀ + (t − τ_start); never before 0 after it."""
        if self._anchor is None:
            return self._t_start + max(t - self._idle_from, 0.0)
        return max(t - self._anchor, 0.0)

    # -- the turret ---------------------------------------------------------------------

    def _reset_timeline(self) -> None:
        state = self.world.turret_state()
        self.timeline.reset(self.world.plant.time, state.pan, state.tilt)

    def _catch_up(self, s: float) -> None:
        """Outside a stream (before the first, between two, after the last), move the
        plant on to s; at rest, it only moves its clock there."""
        plant = self.world.plant
        if self.device.sampling or not s > plant.time + plant.dt:
            return
        if plant.at_rest:
            state = plant.state()
            plant.rebase(s)
            self.timeline.add(np.array([s]), np.array([state.pan]), np.array([state.tilt]))
            return
        plant.advance(s)
        if plant.last_path is not None:
            self.timeline.add(*plant.last_path)

    def command_axis(self, axis: str, angle: float, t: float) -> None:
        """A goal [rad] a servo took at monotonic time ``t``."""
        with self._lock:
            s = self._stamp(t)
            self._catch_up(s)
            self.world.plant.command_axis(axis, s, angle)

    def turret_at(self, t: float) -> tuple[float, float]:
        """(pan, tilt) pointing [rad] at monotonic time ``t``."""
        with self._lock:
            s = self._stamp(t)
            self._catch_up(s)
            return self.timeline.at(s)

    def turret_rate(self, t: float) -> tuple[float, float]:
        """(pan, tilt) rates [rad/s] at monotonic time ``t``."""
        with self._lock:
            s = self._stamp(t)
            self._catch_up(s)
            return self.timeline.rate(s)

    # -- the stream ---------------------------------------------------------------------

    def _open_truth(self) -> None:
        """(Re)write the truth file's header; DeviceError if it cannot be written."""
        if self.truth_path is None:
            return
        if self._truth is not None:
            self._truth.close()
        try:
            self.truth_path.parent.mkdir(parents=True, exist_ok=True)
            self._truth = self.truth_path.open("w", encoding="ascii")
            self._truth.write("t,x,y,z\n")
            self._truth.flush()
        except OSError as exc:
            raise DeviceError(f"cannot write the truth file {self.truth_path}: {exc}") from exc
        self.truth_rows = 0

    def _write_truth(self, t: float, p: FloatArray) -> None:
        with self._lock:
            if self._truth is None:
                return
            self._truth.write(f"{t:.9f},{p[0]:.6f},{p[1]:.6f},{p[2]:.6f}\n")
            self._truth.flush()
            self.truth_rows += 1

    def _stream(self) -> Iterator[PointChunk]:
        """The device's source, called (in the device's thread) at each start of
        sampling: anchor the clock, take a fresh world after the first run, stream."""
        with self._lock:
            if not self._fresh:
                self.world = self._make_world(self.slice_s)
                self._reset_timeline()
                if self.truth_rows:
                    self._open_truth()
            elif self.world.plant.time != self._t_start:
                # the servos moved on the idle clock: the run starts where they are
                self.world.plant.rebase(self._t_start)
                self._reset_timeline()
            self._fresh = False
            self._anchor = self.device.stream_start
            self.starts += 1
            self.finished.clear()
        self.started.set()
        return self._slices(self.world)

    def _slices(self, world: SimWorld) -> Iterator[PointChunk]:
        """The world's slices as point chunks, each covering up to its end."""
        n = max(1, math.ceil(self.duration_s / self.slice_s - 1e-9))
        self._write_truth(0.0, world.target_position(0.0))
        for _ in range(n):
            with self._lock:
                frame, truth = world.step()
                if world.plant.last_path is not None:
                    self.timeline.add(*world.plant.last_path)
                self.slices += 1
                self.points += len(frame)
            self._write_truth(truth.t, truth.target_position)
            if self.on_slice is not None:
                self.on_slice(frame, truth)
            chunk = next(frame_chunks([frame]))
            yield replace(chunk, end_ns=round(truth.t * 1e9))
        # the device asks again once the last slice's packets have gone
        self.finished.set()
