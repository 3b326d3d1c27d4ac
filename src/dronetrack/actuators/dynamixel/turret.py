"""A pan-tilt turret of two DYNAMIXEL XM430-W350 servos, driven through the official
DYNAMIXEL SDK (``pip install 'dronetrack[live]'``) over Protocol 2.0.

Addressed as ``dynamixel://DEVICE?baud=1000000&pan=1&tilt=2&poll_hz=100`` (the
values shown are the defaults; ``dynamixel_uri``), e.g. ``dynamixel:///dev/ttyUSB0``.

Angles: θ = (p − 2048) · 2π / 4096 for position ticks p, so tick 2048 is 0 rad and
θ grows counter-clockwise seen from the horn (the servo's Normal drive mode).  An
axis whose positive direction must be the other way is reversed on the servo
itself (Drive Mode bit 0, which Interbotix sets on the WidowX tilt); opening the
turret keeps that bit.

Opening, for each servo: ping (it must answer as model 1020, XM430-W350; when it
does not and no servo answers a broadcast ping either, the error says that nothing
answered at the URI's baud rate); torque
off; position control mode (3) and a velocity-based profile (Drive Mode bit 2
cleared); the joint limits of the turret preset written as the servo's position
limits; the preset's rate and acceleration as the profile; torque on, which makes
the servo hold where it is.  ``command`` clamps every goal to the joint limits
before it leaves (the servo's limits are a second guard) and sync-writes both
goals in one packet, in the caller's thread; ``state`` sync-reads present velocity
and position (addresses 128–135) in one round trip.  A rate command becomes a
position goal one horizon ahead of the measured position: q* = q + ω T.

Reading while the frames go.  With ``poll_hz`` > 0 a thread of the turret's own
(``state_poller.StatePoller``) sync-reads the present state ``poll_hz`` times a
second, each reading stamped at the middle of its round trip, and ``readings``
hands the new ones over; the serial port serves one transaction at a time
(``dynamixel_port.ServoPort``'s lock), so a goal write waits at most for the read
under way.  From ``readings`` to the next ``command`` (a frame's work, ``HOLD_S``
at most) the poller starts no read, so the frame's command finds the line free.
With ``poll_hz`` = 0 ``readings`` reads once, there and then.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

from dronetrack.actuators.dynamixel.port import ServoPort, le32, no_servo_answered, signed32
from dronetrack.actuators.dynamixel.probe import ServoReport, probe_servos
from dronetrack.actuators.dynamixel.uri import (
    DEFAULT_POLL_HZ,
    SDK_BAUD_RATES,
    DynamixelUri,
    parse_dynamixel_uri,
)
from dronetrack.actuators.goals import goal_angles
from dronetrack.actuators.state_poller import StatePoller
from dronetrack.config.rig import AxisSpec, TurretSpec, make_turret
from dronetrack.errors import ConfigError, DeviceError
from dronetrack.formats.dynamixel import (
    ADDR,
    TICKS_PER_REV,
    accel_to_units,
    rad_to_ticks,
    rate_to_units,
    ticks_to_rad,
    units_to_rate,
)
from dronetrack.types import TurretCommand, TurretState

__all__ = [
    "MODEL_XM430_W350",
    "SDK_BAUD_RATES",
    "STALE_PERIODS",
    "DynamixelTurret",
    "DynamixelUri",
    "ServoReport",
    "axis_tick_limits",
    "parse_dynamixel_uri",
    "probe_servos",
]

MODEL_XM430_W350 = 1020
_PRESENT_BLOCK = 8  # present velocity (128, 4 B) and present position (132, 4 B)
_TIME_BASED_PROFILE = 0x04  # Drive Mode bit 2
# A polled reading older than this many poll periods is stale: ``readings`` waits for
# a newer one (the poller is behind, or failing).
STALE_PERIODS = 5
# After ``readings`` the poller starts no read until the next command, for this long at
# most: the frame's command does not wait behind a read (a frame that sends none lets
# polling go on after it).
HOLD_S = 0.05


def axis_tick_limits(axis: AxisSpec) -> tuple[int, int]:
    """The widest tick range [p_lo, p_hi] inside the axis limits and the servo's 0–4095:
    θ(p_lo) ≥ lower and θ(p_hi) ≤ upper exactly, whatever the rounding."""
    scale = TICKS_PER_REV / (2.0 * math.pi)
    lo = max(0, math.ceil(axis.lower * scale) + 2048)
    hi = min(TICKS_PER_REV - 1, math.floor(axis.upper * scale) + 2048)
    while ticks_to_rad(lo) < axis.lower:
        lo += 1
    while ticks_to_rad(hi) > axis.upper:
        hi -= 1
    if lo > hi:
        raise ConfigError(f"turret axis limits {axis.lower}, {axis.upper} rad hold no servo tick")
    return lo, hi


class DynamixelTurret:
    """The Actuator of a pan-tilt turret of two XM430-W350s; see the module docstring.

    ``clock`` (seconds) stamps each measured state, at the middle of its read.
    ``rate_horizon`` T [s] turns a rate command ω into the goal q + ω T.
    ``poll_hz``: how often the poller reads the present state (0: no poller).  Any
    failed or timed-out exchange raises DeviceError naming the device and the servo
    ID; the poller's, from ``readings``, after ``state_poller.FAIL_AFTER`` in a row.
    """

    def __init__(
        self,
        device: str,
        *,
        baud: int = 1_000_000,
        pan_id: int = 1,
        tilt_id: int = 2,
        turret: TurretSpec | None = None,
        clock: Callable[[], float] = time.monotonic,
        rate_horizon: float = 0.1,
        poll_hz: float = DEFAULT_POLL_HZ,
    ) -> None:
        self.device = device
        self.turret = turret if turret is not None else make_turret("widowx")
        self.ids = (pan_id, tilt_id)
        self.clock = clock
        self.rate_horizon = rate_horizon
        self.limits = (axis_tick_limits(self.turret.pan), axis_tick_limits(self.turret.tilt))
        self.poller = (
            StatePoller(self.state, poll_hz, name=self.name) if poll_hz > 0 else None
        )  # checks the rate before the port is opened
        self.line = ServoPort(device, baud, self.ids)
        sdk, line = self.line.sdk, self.line
        try:
            for ident, axis in zip(self.ids, (self.turret.pan, self.turret.tilt), strict=True):
                self._configure(ident, axis)
        except BaseException:
            line.close()
            raise
        self._goal_write = sdk.GroupSyncWrite(line.port, line.ph, ADDR.GOAL_POSITION, 4)
        self._present_read = sdk.GroupSyncRead(
            line.port, line.ph, ADDR.PRESENT_VELOCITY, _PRESENT_BLOCK
        )
        for ident in self.ids:
            self._present_read.addParam(ident)
        self.goals = [line.read(i, ADDR.GOAL_POSITION, 4, "goal position") for i in self.ids]

    @classmethod
    def from_uri(
        cls,
        uri: str,
        *,
        turret: TurretSpec | None = None,
        clock: Callable[[], float] = time.monotonic,
        rate_horizon: float = 0.1,
    ) -> DynamixelTurret:
        where = parse_dynamixel_uri(uri)
        return cls(
            where.device,
            baud=where.baud,
            pan_id=where.pan_id,
            tilt_id=where.tilt_id,
            turret=turret,
            clock=clock,
            rate_horizon=rate_horizon,
            poll_hz=where.poll_hz,
        )

    @property
    def name(self) -> str:
        return f"Dynamixel turret on {self.device}"

    def _ping(self, ident: int) -> int:
        """Servo ``ident``'s model number; DeviceError naming the servo, or saying that
        no servo answers at this baud rate when none answers a broadcast ping either."""
        try:
            return self.line.ping(ident)
        except DeviceError:
            if self.line.bus_silent():
                raise DeviceError(no_servo_answered(self.device, self.line.baud)) from None
            raise

    def _configure(self, ident: int, axis: AxisSpec) -> None:
        line = self.line
        model = self._ping(ident)
        if model != MODEL_XM430_W350:
            raise DeviceError(
                f"{line.who(ident)}: model number {model}, not an XM430-W350 ({MODEL_XM430_W350})"
            )
        line.write(ident, ADDR.TORQUE_ENABLE, 1, 0, "torque off")  # unlocks the EEPROM area
        if line.read(ident, ADDR.OPERATING_MODE, 1, "operating mode") != 3:
            line.write(ident, ADDR.OPERATING_MODE, 1, 3, "position control mode")
        drive = line.read(ident, ADDR.DRIVE_MODE, 1, "drive mode")
        if drive & _TIME_BASED_PROFILE:
            line.write(ident, ADDR.DRIVE_MODE, 1, drive & ~_TIME_BASED_PROFILE, "drive mode")
        lo, hi = axis_tick_limits(axis)
        line.write(ident, ADDR.MIN_POSITION, 4, lo, "min position limit")
        line.write(ident, ADDR.MAX_POSITION, 4, hi, "max position limit")
        # Profile velocity v = round(ω / (0.229 · 2π/60)) [0.229 rpm], at least 1 (0 would
        # mean unlimited) and at most the servo's Velocity Limit (44), which caps it anyway.
        # Profile acceleration a = round(α / (214.577 · 2π/3600)) [214.577 rev/min²], ≥ 1.
        v_limit = line.read(ident, ADDR.VELOCITY_LIMIT, 4, "velocity limit")
        velocity = max(1, min(rate_to_units(axis.rate), v_limit))
        accel = max(1, accel_to_units(axis.accel))
        line.write(ident, ADDR.PROFILE_ACCELERATION, 4, accel, "profile acceleration")
        line.write(ident, ADDR.PROFILE_VELOCITY, 4, velocity, "profile velocity")
        line.write(ident, ADDR.TORQUE_ENABLE, 1, 1, "torque on")

    # -- the Actuator ----------------------------------------------------------------

    def _goal_ticks(self, axis: int, angle: float) -> int:
        """The goal [ticks] for ``angle`` [rad], inside the axis limits; a non-finite angle
        keeps the axis's previous goal."""
        if not math.isfinite(angle):
            return self.goals[axis]
        lo, hi = self.limits[axis]
        return min(max(rad_to_ticks(angle), lo), hi)

    def _send_goals(self, ticks: tuple[int, int]) -> None:
        what = "sync write of goal positions"
        line = self.line
        with line.lock:
            self._goal_write.clearParam()
            for ident, value in zip(self.ids, ticks, strict=True):
                self._goal_write.addParam(ident, le32(value))
            result = line.group(what, self._goal_write.txPacket)
        if self.poller is not None:
            self.poller.release()
        if result != line.ok:
            raise DeviceError(f"{line.both}: {what}: {line.result_text(result)}")
        self.goals = list(ticks)

    def command(self, command: TurretCommand) -> None:
        """Send both goals at once (real time: the stamp is not waited for)."""
        # velocity: one horizon ahead of the measured position (actuators.goals)
        newest = self.poller.newest if self.poller is not None else None
        goal = goal_angles(command, newest, self.state, self.rate_horizon)
        self._send_goals((self._goal_ticks(0, goal[0]), self._goal_ticks(1, goal[1])))

    def state(self) -> TurretState:
        """Present positions [rad] and velocities [rad/s] of both servos, in one sync read
        now (in the caller's thread)."""
        what = "sync read of present position"
        line = self.line
        with line.lock:
            t0 = self.clock()
            result = line.group(what, self._present_read.txRxPacket)
            t1 = self.clock()
            if result != line.ok:
                failing = line.first_silent()
                who = line.who(failing) if failing >= 0 else line.both
                raise DeviceError(f"{who}: {what}: {line.result_text(result)}")
            q, w = [], []
            for ident in self.ids:
                try:
                    if not self._present_read.isAvailable(
                        ident, ADDR.PRESENT_VELOCITY, _PRESENT_BLOCK
                    ):
                        raise IndexError
                    velocity = self._present_read.getData(ident, ADDR.PRESENT_VELOCITY, 4)
                    position = self._present_read.getData(ident, ADDR.PRESENT_POSITION, 4)
                except IndexError:
                    raise DeviceError(
                        f"{line.who(ident)}: sync read of present position returned no data"
                    ) from None
                q.append(ticks_to_rad(signed32(int(position))))
                w.append(units_to_rate(signed32(int(velocity))))
        return TurretState(0.5 * (t0 + t1), q[0], q[1], w[0], w[1])

    @property
    def reads_missed(self) -> int:
        """The poller's reads that got no answer (0 without a poller)."""
        return self.poller.misses if self.poller is not None else 0

    @property
    def stale_s(self) -> float:
        """How old (on ``clock``) the newest polled reading may be at the time a caller
        needs the pose: ``STALE_PERIODS`` poll periods (0 without a poller)."""
        return STALE_PERIODS * self.poller.period_s if self.poller is not None else 0.0

    def readings(self, until: float = -math.inf, timeout_s: float = 1.0) -> list[TurretState]:
        """The present states read since the last call, oldest first, stamped on
        ``clock``, once the newest is no more than ``stale_s`` older than ``until``:
        waits up to ``timeout_s`` for the poller (started by the first call).  Without
        a poller: one ``state`` now.  DeviceError if the servos stopped answering."""
        if self.poller is None:
            return [self.state()]
        self.poller.start()
        got = self.poller.take(until - self.stale_s, timeout_s)
        self.poller.hold(HOLD_S)  # until the frame's command (``_send_goals``)
        return got

    # -- closing ---------------------------------------------------------------------

    def close(self) -> None:
        """Stop the poller, hold the present position (goal = present, torque stays on)
        and close the port.  The port is closed even when holding fails (the
        DeviceError is then raised)."""
        if self.poller is not None:
            self.poller.stop()
        if self.line.closed:
            return
        try:
            now = self.state()
            held = [
                min(max(rad_to_ticks(angle), lo), hi)
                for angle, (lo, hi) in zip((now.pan, now.tilt), self.limits, strict=True)
            ]
            self._send_goals((held[0], held[1]))
        finally:
            self.line.close()

    def __enter__(self) -> DynamixelTurret:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
