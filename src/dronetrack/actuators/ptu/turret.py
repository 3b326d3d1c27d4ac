"""A FLIR pan-tilt unit (PTU-E46, PTU-D46 and kin) driven over its ASCII command set.

Addressed as ``ptu://DEVICE?baud=9600&poll_hz=20`` (serial) or ``ptu://HOST:PORT``
(TCP; ``ptu_uri``), e.g. ``ptu:///dev/ttyUSB0``.  The command set and the sign
convention (the unit's tilt grows upwards, the turret's downwards) are in
``formats.ptu``; the line, one transaction at a time, in ``ptu_line``.

Opening: a bare delimiter (it ends any half-typed command left on the unit), then
echo off and terse feedback (``ED``, ``FT``), independent position control and
immediate execution (``CI``, ``I``); the resolutions (``PR``, ``TR``, arc-seconds
per position), the unit's position limits (``PN``, ``PX``, ``TN``, ``TX``) and
speed bounds (``PU``, ``TU``) are read; the turret preset's rate and acceleration
are written as the axes' speed and acceleration (``PS``/``TS`` = ω / r, capped at
the bound; ``PA``/``TA`` = α / r); the present positions become the goals.

Goals.  Each axis's goals are clamped to the positions inside both the preset's
joint limits and the unit's own (``limits``), so the unit never refuses one; a
frame's command sends ``PP``/``TP`` for the axes whose goal changed (none if
neither did) and waits for the unit's ``*`` to each, in the caller's thread (a
refusal fails that frame's command).  A rate command ω becomes the goal one horizon
ahead of the measured position, q* = q + ω T, as for the Dynamixel turret.

Reading.  ``state`` queries both positions in one transaction (``PP TP``), stamped
when the unit had the queries (``ptu_line``); the rates are the slope from the
previous reading, ω = (q − q') / (t − t'), 0 for the first or after a gap over
``RATE_GAP_S``.  With ``poll_hz`` > 0 a thread of the turret's own reads it
(``state_poller.StatePoller``), and from ``readings`` to the next command the
poller starts no read, as for the Dynamixel turret.  Closing stops the poller,
sets the goals to the present positions and closes the line.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

from dronetrack.actuators.goals import goal_angles
from dronetrack.actuators.ptu.line import PtuLine, open_line
from dronetrack.actuators.ptu.uri import DEFAULT_POLL_HZ, PtuUri, parse_ptu_uri
from dronetrack.actuators.state_poller import StatePoller
from dronetrack.config.rig import AxisSpec, TurretSpec, make_turret
from dronetrack.errors import ConfigError, DecodeError, DeviceError
from dronetrack.formats.ptu import (
    ARCSEC,
    AXIS_SIGN,
    Reply,
    angle_to_position,
    parse_number,
    position_to_angle,
)
from dronetrack.types import TurretCommand, TurretState

__all__ = [
    "HOLD_S",
    "RATE_GAP_S",
    "STALE_PERIODS",
    "AxisSetup",
    "PtuTurret",
    "PtuUri",
    "goal_limits",
    "parse_ptu_uri",
]

RATE_GAP_S = 0.5  # readings further apart than this give no rate
STALE_PERIODS = 5  # a polled reading older than this many periods is stale
HOLD_S = 0.05  # after ``readings``, no poll starts for this long at most (or until a command)
AXES = ("pan", "tilt")


@dataclass(frozen=True, slots=True)
class AxisSetup:
    """What opening found and set on one axis: resolution [arc-seconds/position], the
    unit's limits and the goal limits used [positions], the speed bound and the
    speed and acceleration written [positions/s, positions/s²]."""

    resolution_arcsec: float
    unit_limits: tuple[int, int]
    limits: tuple[int, int]
    max_speed: int
    speed: int
    accel: int

    @property
    def resolution(self) -> float:
        """[rad/position]"""
        return self.resolution_arcsec * ARCSEC


def goal_limits(axis: AxisSpec, name: str, arcsec: float, unit: tuple[int, int]) -> tuple[int, int]:
    """The widest position range inside both the axis's joint limits [rad] (through the
    sign convention) and the unit's own; ConfigError if they do not overlap."""
    r = AXIS_SIGN[name] * arcsec * ARCSEC  # θ = r · p
    a, b = sorted((axis.lower / r, axis.upper / r))
    lo, hi = max(math.ceil(a - 1e-9), unit[0]), min(math.floor(b + 1e-9), unit[1])
    if lo > hi:
        raise ConfigError(
            f"the {name} axis limits {math.degrees(axis.lower):.1f}° to "
            f"{math.degrees(axis.upper):.1f}° and the unit's ({unit[0]} to {unit[1]} positions "
            f"of {arcsec:g}″) do not overlap"
        )
    return lo, hi


class PtuTurret:
    """The Actuator of a FLIR pan-tilt unit on ``line``; see the module docstring.

    ``clock`` (seconds) stamps each measured state; ``rate_horizon`` T [s] turns a rate
    command ω into the goal q + ω T; ``poll_hz``: how often the poller reads the
    positions (0: no poller).  DeviceError names the unit for any refusal, time-out or
    failing line; ConfigError if the preset's limits miss the unit's.
    """

    def __init__(
        self,
        line: PtuLine,
        *,
        turret: TurretSpec | None = None,
        clock: Callable[[], float] = time.monotonic,
        rate_horizon: float = 0.1,
        poll_hz: float = DEFAULT_POLL_HZ,
    ) -> None:
        self.line = line
        self.turret = turret if turret is not None else make_turret("ptu-e46")
        self.clock = clock
        self.rate_horizon = rate_horizon
        self.poller = StatePoller(self.state, poll_hz, name=self.name) if poll_hz > 0 else None
        self._state_lock = threading.Lock()
        self._last: TurretState | None = None
        try:
            self.axes = self._configure()
            here = self.line.transact(["PP", "TP"], "read the positions")
            self.goals = [
                round(self._number(r, f"{c}P")) for r, c in zip(here.replies, "PT", strict=True)
            ]
        except BaseException:
            line.close()
            raise

    @classmethod
    def from_uri(
        cls,
        uri: str,
        *,
        turret: TurretSpec | None = None,
        clock: Callable[[], float] = time.monotonic,
        rate_horizon: float = 0.1,
    ) -> PtuTurret:
        where = parse_ptu_uri(uri)
        line = open_line(where, clock)
        return cls(
            line, turret=turret, clock=clock, rate_horizon=rate_horizon, poll_hz=where.poll_hz
        )

    @property
    def name(self) -> str:
        return self.line.name

    def _number(self, reply: Reply, command: str) -> float:
        try:
            return parse_number(reply, f"{self.name}: {command}")
        except DecodeError as exc:
            raise DeviceError(str(exc)) from None

    def _configure(self) -> tuple[AxisSetup, AxisSetup]:
        line = self.line
        with line.lock:
            line.interrupt()
            for command, what in (("ED", "echo off"), ("FT", "terse feedback")):
                line.transact([command], what)
            line.transact(["CI", "I"], "position control, immediate execution")
            asked = ["PR", "TR", "PN", "PX", "TN", "TX", "PU", "TU"]
            got = line.transact(asked, "read resolution and limits")
            v = {c: self._number(r, c) for r, c in zip(got.replies, asked, strict=True)}
            setups = []
            writes = []
            for name, spec, p in zip(AXES, (self.turret.pan, self.turret.tilt), "PT", strict=True):
                arcsec = v[f"{p}R"]
                if not arcsec > 0:
                    raise DeviceError(f"{self.name}: {p}R: resolution {arcsec:g}″ is not positive")
                unit = (int(v[f"{p}N"]), int(v[f"{p}X"]))
                limits = goal_limits(spec, name, arcsec, unit)
                # PS = ω / r [positions/s] (1 at least, the bound at most); PA = α / r
                r = arcsec * ARCSEC
                bound = int(v[f"{p}U"])
                speed = max(1, min(round(spec.rate / r), bound))
                accel = max(1, round(spec.accel / r))
                setups.append(AxisSetup(arcsec, unit, limits, bound, speed, accel))
                writes += [f"{p}S{speed}", f"{p}A{accel}"]
            line.transact(writes, "write speed and acceleration")
        return setups[0], setups[1]

    # -- the Actuator ----------------------------------------------------------------

    def _goal(self, axis: int, angle: float) -> int:
        """The goal [positions] for ``angle`` [rad] inside the axis's limits; a non-finite
        angle keeps the axis's previous goal."""
        if not math.isfinite(angle):
            return self.goals[axis]
        setup = self.axes[axis]
        lo, hi = setup.limits
        return min(max(angle_to_position(angle, setup.resolution_arcsec, AXES[axis]), lo), hi)

    def _send_goals(self, goals: tuple[int, int], *, every: bool = False) -> None:
        """Send the goals that differ from the last sent (``every``: both) and wait for
        the unit's answers; lets the poller read again."""
        changed = [
            f"{p}P{g}"
            for p, g, old in zip("PT", goals, self.goals, strict=True)
            if every or g != old
        ]
        try:
            if changed:
                self.line.transact(changed, "position goals")
                self.goals = list(goals)
        finally:
            if self.poller is not None:
                self.poller.release()

    def command(self, command: TurretCommand) -> None:
        """Send the goals that changed and wait for the unit's ``*`` (real time: the stamp
        is not waited for)."""
        newest = self.poller.newest if self.poller is not None else None
        goal = goal_angles(command, newest, self.state, self.rate_horizon)
        self._send_goals((self._goal(0, goal[0]), self._goal(1, goal[1])))

    def state(self) -> TurretState:
        """Both positions [rad], read now in one transaction, and the rates since the
        previous reading [rad/s]."""
        with self._state_lock:
            got = self.line.transact(["PP", "TP"], "read the positions")
            q = [
                position_to_angle(self._number(r, f"{p}P"), s.resolution_arcsec, name)
                for r, p, s, name in zip(got.replies, "PT", self.axes, AXES, strict=True)
            ]
            stamp = 0.5 * (got.seen[0] + got.seen[1])
            last, rates = self._last, (0.0, 0.0)
            if last is not None and 0 < stamp - last.stamp <= RATE_GAP_S:
                dt = stamp - last.stamp
                rates = ((q[0] - last.pan) / dt, (q[1] - last.tilt) / dt)
            self._last = TurretState(stamp, q[0], q[1], rates[0], rates[1])
            return self._last

    @property
    def reads_missed(self) -> int:
        """The poller's reads that got no answer (0 without a poller)."""
        return self.poller.misses if self.poller is not None else 0

    @property
    def stale_s(self) -> float:
        """How old the newest polled reading may be when a frame needs the pose."""
        return STALE_PERIODS * self.poller.period_s if self.poller is not None else 0.0

    def readings(self, until: float = -math.inf, timeout_s: float = 1.0) -> list[TurretState]:
        """The states read since the last call, oldest first, once the newest is no more
        than ``stale_s`` older than ``until`` (waiting up to ``timeout_s``; the poller
        starts on the first call).  Without a poller: one ``state`` now."""
        if self.poller is None:
            return [self.state()]
        self.poller.start()
        got = self.poller.take(until - self.stale_s, timeout_s)
        self.poller.hold(HOLD_S)  # until the frame's command (``_send_goals``)
        return got

    # -- closing ---------------------------------------------------------------------

    def close(self) -> None:
        """Stop the poller, hold the present positions (goals = present) and close the
        line; the line is closed even when holding fails (the DeviceError is raised)."""
        if self.poller is not None:
            self.poller.stop()
        if self.line.closed:
            return
        try:
            now = self.state()
            self._send_goals((self._goal(0, now.pan), self._goal(1, now.tilt)), every=True)
        finally:
            self.line.close()

    def __enter__(self) -> PtuTurret:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
