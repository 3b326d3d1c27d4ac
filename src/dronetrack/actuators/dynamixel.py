"""A pan-tilt turret of two DYNAMIXEL XM430-W350 servos, driven through the official
DYNAMIXEL SDK (``pip install 'dronetrack[live]'``) over Protocol 2.0.

Addressed as ``dynamixel://DEVICE?baud=1000000&pan=1&tilt=2`` (the values shown are
the defaults: the WidowX XM430 turret's pan ID 1 and tilt ID 2 at 1 Mbit/s), e.g.
``dynamixel:///dev/ttyUSB0`` or ``dynamixel:///dev/ttyDXL?baud=57600``.

Angles: θ = (p − 2048) · 2π / 4096 for position ticks p, so tick 2048 is 0 rad and
θ grows counter-clockwise seen from the horn (the servo's Normal drive mode).  An
axis whose positive direction must be the other way is reversed on the servo
itself (Drive Mode bit 0, which Interbotix sets on the WidowX tilt); opening the
turret keeps that bit.

Opening, for each servo: ping (it must answer as model 1020, XM430-W350); torque
off; position control mode (3) and a velocity-based profile (Drive Mode bit 2
cleared); the joint limits of the turret preset written as the servo's position
limits; the preset's rate and acceleration as the profile; torque on, which makes
the servo hold where it is.  ``command`` clamps every goal to the joint limits
before it leaves (the servo's limits are a second guard) and sync-writes both
goals in one packet; ``state`` sync-reads present velocity and position (addresses
128–135) in one round trip.  A rate command becomes a position goal one horizon
ahead of the measured position: q* = q + ω T.
"""

from __future__ import annotations

import contextlib
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

from dronetrack.config.rig import AxisSpec, TurretSpec, make_turret
from dronetrack.errors import ConfigError, DeviceError, MissingExtraError
from dronetrack.formats.dynamixel import (
    ADDR,
    ERROR_NAMES,
    TICKS_PER_REV,
    Err,
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
    "DynamixelTurret",
    "DynamixelUri",
    "ServoReport",
    "axis_tick_limits",
    "parse_dynamixel_uri",
    "probe_servos",
]

MODEL_XM430_W350 = 1020
SCHEME = "dynamixel://"
# The baud rates the SDK's PortHandler accepts (others make setBaudRate fail).
SDK_BAUD_RATES = (
    9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600,
    1000000, 1152000, 2000000, 2500000, 3000000, 3500000, 4000000,
)  # fmt: skip
_PRESENT_BLOCK = 8  # present velocity (128, 4 B) and present position (132, 4 B)
_TIME_BASED_PROFILE = 0x04  # Drive Mode bit 2


@dataclass(frozen=True, slots=True)
class DynamixelUri:
    """Where the turret's servos are: serial device, baud rate, pan and tilt IDs."""

    device: str
    baud: int = 1_000_000
    pan_id: int = 1
    tilt_id: int = 2


def parse_dynamixel_uri(uri: str) -> DynamixelUri:
    """``dynamixel://DEVICE?baud=B&pan=ID&tilt=ID`` (query keys optional); ConfigError
    with one line naming the problem otherwise."""
    if not uri.startswith(SCHEME):
        raise ConfigError(f"a Dynamixel turret is dynamixel://DEVICE?baud=…, got {uri!r}")
    device, _, query = uri[len(SCHEME) :].partition("?")
    if not device:
        raise ConfigError(f"Dynamixel turret URI {uri!r} names no serial device")
    values: dict[str, int] = {}
    for part in query.split("&") if query else []:
        key, eq, text = part.partition("=")
        if not eq or not key:
            raise ConfigError(f"Dynamixel turret URI {uri!r}: {part!r} is not key=value")
        if key not in ("baud", "pan", "tilt"):
            raise ConfigError(
                f"Dynamixel turret URI {uri!r}: unknown key {key!r} (baud, pan, tilt)"
            )
        if key in values:
            raise ConfigError(f"Dynamixel turret URI {uri!r}: {key} given twice")
        try:
            values[key] = int(text)
        except ValueError:
            raise ConfigError(
                f"Dynamixel turret URI {uri!r}: {key}={text!r} is not an integer"
            ) from None
    out = DynamixelUri(
        device,
        values.get("baud", 1_000_000),
        values.get("pan", 1),
        values.get("tilt", 2),
    )
    if out.baud not in SDK_BAUD_RATES:
        raise ConfigError(
            f"Dynamixel turret URI {uri!r}: baud {out.baud} is not one the DYNAMIXEL SDK "
            f"supports ({', '.join(map(str, SDK_BAUD_RATES))})"
        )
    for name, ident in (("pan", out.pan_id), ("tilt", out.tilt_id)):
        if not 0 <= ident <= 252:
            raise ConfigError(f"Dynamixel turret URI {uri!r}: {name} ID {ident} is not in 0–252")
    if out.pan_id == out.tilt_id:
        raise ConfigError(f"Dynamixel turret URI {uri!r}: pan and tilt share ID {out.pan_id}")
    return out


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


def _io_errors() -> tuple[type[BaseException], ...]:
    """What the SDK's serial layer raises when the line fails: OSError (pyserial's
    SerialException is one) and, on POSIX, termios.error (not an OSError)."""
    try:
        import termios
    except ImportError:
        return (OSError,)
    return (OSError, termios.error)


_IO_ERRORS = _io_errors()


def _sdk() -> Any:
    try:
        import dynamixel_sdk
    except ImportError as exc:
        raise MissingExtraError(
            "the Dynamixel turret needs the official DYNAMIXEL SDK: "
            "pip install 'dronetrack[live]' (dynamixel-sdk, pyserial)"
        ) from exc
    return dynamixel_sdk


def _signed32(value: int) -> int:
    """A 4-byte control-table value as the signed integer it encodes (two's complement)."""
    value &= 0xFFFFFFFF
    return value - (1 << 32) if value & 0x80000000 else value


def _le32(value: int) -> list[int]:
    return list((value & 0xFFFFFFFF).to_bytes(4, "little"))


class DynamixelTurret:
    """The Actuator of a pan-tilt turret of two XM430-W350s; see the module docstring.

    ``clock`` (seconds) stamps each measured state, at the middle of its read.
    ``rate_horizon`` T [s] turns a rate command ω into the goal q + ω T.  Any failed
    or timed-out exchange raises DeviceError naming the device and the servo ID.
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
    ) -> None:
        sdk = _sdk()
        self.device = device
        self.turret = turret if turret is not None else make_turret("widowx")
        self.ids = (pan_id, tilt_id)
        self.clock = clock
        self.rate_horizon = rate_horizon
        self.limits = (axis_tick_limits(self.turret.pan), axis_tick_limits(self.turret.tilt))
        self._ok = sdk.COMM_SUCCESS
        self._port = sdk.PortHandler(device)
        self._ph = sdk.PacketHandler(2.0)
        self._closed = True
        try:
            opened = bool(self._port.openPort()) and bool(self._port.setBaudRate(baud))
        except _IO_ERRORS as exc:
            raise DeviceError(f"Dynamixel turret on {device}: cannot open the port: {exc}") from exc
        if not opened:
            raise DeviceError(f"Dynamixel turret on {device}: cannot open the port at {baud} baud")
        self._closed = False
        try:
            for ident, axis in zip(self.ids, (self.turret.pan, self.turret.tilt), strict=True):
                self._configure(ident, axis)
        except BaseException:
            self._close_port()
            raise
        self._goal_write = sdk.GroupSyncWrite(self._port, self._ph, ADDR.GOAL_POSITION, 4)
        self._present_read = sdk.GroupSyncRead(
            self._port, self._ph, ADDR.PRESENT_VELOCITY, _PRESENT_BLOCK
        )
        for ident in self.ids:
            self._present_read.addParam(ident)
        self.goals = [
            self._read(ident, ADDR.GOAL_POSITION, 4, "goal position") for ident in self.ids
        ]

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
        )

    @property
    def name(self) -> str:
        return f"Dynamixel turret on {self.device}"

    # -- one exchange with one servo -------------------------------------------------

    def _who(self, ident: int) -> str:
        axis = "pan" if ident == self.ids[0] else "tilt"
        return f"Dynamixel turret on {self.device}: servo ID {ident} ({axis})"

    def _exchange(self, ident: int, what: str, call: Callable[[], tuple[Any, ...]]) -> Any:
        """Run one SDK request/response; its value, or DeviceError naming the servo."""
        if self._closed:
            raise DeviceError(f"{self._who(ident)}: {what}: the port is closed")
        try:
            *value, result, error = call()
        except _IO_ERRORS as exc:
            raise DeviceError(f"{self._who(ident)}: {what}: {exc}") from exc
        if result != self._ok:
            raise DeviceError(f"{self._who(ident)}: {what}: {self._ph.getTxRxResult(result)}")
        number = int(error) & 0x7F
        if number:
            name = ERROR_NAMES.get(number, f"error {number}")
            raise DeviceError(f"{self._who(ident)}: {what}: the servo answered {name}")
        if int(error) & Err.ALERT:
            raise DeviceError(
                f"{self._who(ident)}: {what}: hardware alert (read Hardware Error Status, 70)"
            )
        return value[0] if value else None

    def _read(self, ident: int, address: int, size: int, what: str) -> int:
        reader = {1: self._ph.read1ByteTxRx, 4: self._ph.read4ByteTxRx}[size]
        value = self._exchange(ident, f"read {what}", lambda: reader(self._port, ident, address))
        return _signed32(int(value)) if size == 4 else int(value)

    def _write(self, ident: int, address: int, size: int, value: int, what: str) -> None:
        writer = {1: self._ph.write1ByteTxRx, 4: self._ph.write4ByteTxRx}[size]
        data = value & 0xFFFFFFFF
        self._exchange(ident, f"write {what}", lambda: writer(self._port, ident, address, data))

    def _configure(self, ident: int, axis: AxisSpec) -> None:
        model = self._exchange(ident, "ping", lambda: self._ph.ping(self._port, ident))
        if model != MODEL_XM430_W350:
            raise DeviceError(
                f"{self._who(ident)}: model number {model}, not an XM430-W350 ({MODEL_XM430_W350})"
            )
        self._write(ident, ADDR.TORQUE_ENABLE, 1, 0, "torque off")  # unlocks the EEPROM area
        if self._read(ident, ADDR.OPERATING_MODE, 1, "operating mode") != 3:
            self._write(ident, ADDR.OPERATING_MODE, 1, 3, "position control mode")
        drive = self._read(ident, ADDR.DRIVE_MODE, 1, "drive mode")
        if drive & _TIME_BASED_PROFILE:
            self._write(ident, ADDR.DRIVE_MODE, 1, drive & ~_TIME_BASED_PROFILE, "drive mode")
        lo, hi = axis_tick_limits(axis)
        self._write(ident, ADDR.MIN_POSITION, 4, lo, "min position limit")
        self._write(ident, ADDR.MAX_POSITION, 4, hi, "max position limit")
        # Profile velocity v = round(ω / (0.229 · 2π/60)) [0.229 rpm], at least 1 (0 would
        # mean unlimited) and at most the servo's Velocity Limit (44), which caps it anyway.
        # Profile acceleration a = round(α / (214.577 · 2π/3600)) [214.577 rev/min²], ≥ 1.
        v_limit = self._read(ident, ADDR.VELOCITY_LIMIT, 4, "velocity limit")
        velocity = max(1, min(rate_to_units(axis.rate), v_limit))
        self._write(
            ident,
            ADDR.PROFILE_ACCELERATION,
            4,
            max(1, accel_to_units(axis.accel)),
            "profile acceleration",
        )
        self._write(ident, ADDR.PROFILE_VELOCITY, 4, velocity, "profile velocity")
        self._write(ident, ADDR.TORQUE_ENABLE, 1, 1, "torque on")

    # -- the Actuator ----------------------------------------------------------------

    def _goal_ticks(self, axis: int, angle: float) -> int:
        """The goal [ticks] for ``angle`` [rad], inside the axis limits; a non-finite angle
        keeps the axis's previous goal."""
        if not math.isfinite(angle):
            return self.goals[axis]
        lo, hi = self.limits[axis]
        return min(max(rad_to_ticks(angle), lo), hi)

    @property
    def _both(self) -> str:
        return f"Dynamixel turret on {self.device}: servo IDs {self.ids[0]}, {self.ids[1]}"

    def _group_exchange(self, what: str, call: Callable[[], int]) -> int:
        """Run one sync read or write of both servos; the SDK's result code, or
        DeviceError naming both servos when the port is closed or the line fails."""
        if self._closed:
            raise DeviceError(f"Dynamixel turret on {self.device}: the port is closed")
        try:
            return call()
        except _IO_ERRORS as exc:
            raise DeviceError(f"{self._both}: {what}: {exc}") from exc

    def _send_goals(self, ticks: tuple[int, int]) -> None:
        what = "sync write of goal positions"
        self._goal_write.clearParam()
        for ident, value in zip(self.ids, ticks, strict=True):
            self._goal_write.addParam(ident, _le32(value))
        result = self._group_exchange(what, self._goal_write.txPacket)
        if result != self._ok:
            raise DeviceError(f"{self._both}: {what}: {self._ph.getTxRxResult(result)}")
        self.goals = list(ticks)

    def command(self, command: TurretCommand) -> None:
        """Send both goals at once (real time: the stamp is not waited for)."""
        if command.mode == "velocity":
            # q* = q + ω T: one horizon ahead of the measured position
            now = self.state()
            goal = (
                now.pan + command.pan * self.rate_horizon,
                now.tilt + command.tilt * self.rate_horizon,
            )
        elif command.mode == "position":
            goal = (command.pan, command.tilt)
        else:
            raise ConfigError(
                f"turret command mode must be position or velocity, got {command.mode!r}"
            )
        self._send_goals((self._goal_ticks(0, goal[0]), self._goal_ticks(1, goal[1])))

    def _which_fails(self) -> int:
        """The first servo that does not answer a ping (for a failed sync read's message)."""
        for ident in self.ids:
            try:
                self._exchange(ident, "ping", partial(self._ph.ping, self._port, ident))
            except DeviceError:
                return ident
        return -1

    def state(self) -> TurretState:
        """Present positions [rad] and velocities [rad/s] of both servos, in one sync read."""
        what = "sync read of present position"
        t0 = self.clock()
        result = self._group_exchange(what, self._present_read.txRxPacket)
        t1 = self.clock()
        if result != self._ok:
            reason = self._ph.getTxRxResult(result)
            failing = self._which_fails()
            who = self._who(failing) if failing >= 0 else self._both
            raise DeviceError(f"{who}: {what}: {reason}")
        q, w = [], []
        for ident in self.ids:
            try:
                if not self._present_read.isAvailable(ident, ADDR.PRESENT_VELOCITY, _PRESENT_BLOCK):
                    raise IndexError
                velocity = self._present_read.getData(ident, ADDR.PRESENT_VELOCITY, 4)
                position = self._present_read.getData(ident, ADDR.PRESENT_POSITION, 4)
            except IndexError:
                raise DeviceError(
                    f"{self._who(ident)}: sync read of present position returned no data"
                ) from None
            q.append(ticks_to_rad(_signed32(int(position))))
            w.append(units_to_rate(_signed32(int(velocity))))
        return TurretState(0.5 * (t0 + t1), q[0], q[1], w[0], w[1])

    # -- closing ---------------------------------------------------------------------

    def _close_port(self) -> None:
        self._closed = True
        if getattr(self._port, "ser", None) is not None:
            with contextlib.suppress(*_IO_ERRORS):
                self._port.closePort()

    def close(self) -> None:
        """Hold the present position (goal = present, torque stays on) and close the port.
        The port is closed even when holding fails (the DeviceError is then raised)."""
        if self._closed:
            return
        try:
            now = self.state()
            held = [
                min(max(rad_to_ticks(angle), lo), hi)
                for angle, (lo, hi) in zip((now.pan, now.tilt), self.limits, strict=True)
            ]
            self._send_goals((held[0], held[1]))
        finally:
            self._close_port()

    def __enter__(self) -> DynamixelTurret:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


@dataclass(frozen=True, slots=True)
class ServoReport:
    """What one servo says of itself (``dronetrack info dynamixel://…``): its ID and
    role (pan, tilt, or other: answered a broadcast ping but is not in the URI),
    model number and firmware version from the ping, and for the turret's servos
    the present position [ticks and rad], torque enable and hardware error status;
    ``problem`` when a read failed."""

    ident: int
    role: str
    model: int | None
    firmware: int | None
    position: int | None = None
    torque: bool | None = None
    hardware_error: int | None = None
    problem: str | None = None

    @property
    def angle(self) -> float | None:
        return None if self.position is None else ticks_to_rad(self.position)


def probe_servos(uri: str) -> list[ServoReport]:
    """Ping every servo on the bus (a broadcast ping, then the URI's pan and tilt IDs one
    by one) and read the turret's: model, firmware, present position, torque and
    hardware error.  Changes nothing on the servos.  DeviceError if the port cannot
    be opened; a servo that does not answer is reported with its problem."""
    where = parse_dynamixel_uri(uri)
    sdk = _sdk()
    port, ph = sdk.PortHandler(where.device), sdk.PacketHandler(2.0)
    try:
        opened = bool(port.openPort()) and bool(port.setBaudRate(where.baud))
    except _IO_ERRORS as exc:
        raise DeviceError(f"Dynamixel bus on {where.device}: cannot open the port: {exc}") from exc
    if not opened:
        raise DeviceError(
            f"Dynamixel bus on {where.device}: cannot open the port at {where.baud} baud"
        )
    try:
        found: dict[int, tuple[int, int]] = {}
        try:
            answered, result = ph.broadcastPing(port)
            if result == sdk.COMM_SUCCESS:
                found = {int(i): (int(v[0]), int(v[1])) for i, v in answered.items()}
        except _IO_ERRORS:
            found = {}
        roles = {where.pan_id: "pan", where.tilt_id: "tilt"}
        reports = [_servo_report(sdk, port, ph, i, r, found.get(i)) for i, r in roles.items()]
        reports += [
            ServoReport(i, "other", model, fw)
            for i, (model, fw) in sorted(found.items())
            if i not in roles
        ]
        return reports
    finally:
        with contextlib.suppress(*_IO_ERRORS):
            port.closePort()


def _servo_report(
    sdk: Any, port: Any, ph: Any, ident: int, role: str, pinged: tuple[int, int] | None
) -> ServoReport:
    """One of the turret's servos: ping (unless the broadcast ping found it), then reads."""

    def failed(what: str, result: int, error: int) -> str | None:
        if result != sdk.COMM_SUCCESS:
            return f"{what}: {ph.getTxRxResult(result)}"
        if int(error) & 0x7F:
            return f"{what}: the servo answered {ERROR_NAMES.get(int(error) & 0x7F, error)}"
        return None

    try:
        if pinged is None:
            model, result, error = ph.ping(port, ident)
            problem = failed("ping", result, error)
            if problem is not None:
                return ServoReport(ident, role, None, None, problem=problem)
            fw, result, error = ph.read1ByteTxRx(port, ident, ADDR.FIRMWARE_VERSION)
            pinged = (int(model), int(fw) if failed("", result, error) is None else -1)
        model, fw = pinged
        position, result, error = ph.read4ByteTxRx(port, ident, ADDR.PRESENT_POSITION)
        problem = failed("read present position", result, error)
        torque, r2, e2 = ph.read1ByteTxRx(port, ident, ADDR.TORQUE_ENABLE)
        hw, r3, e3 = ph.read1ByteTxRx(port, ident, ADDR.HARDWARE_ERROR)
        problem = problem or failed("read torque enable", r2, e2) or failed("read error", r3, e3)
    except _IO_ERRORS as exc:
        return ServoReport(ident, role, None, None, problem=str(exc))
    return ServoReport(
        ident,
        role,
        model,
        None if fw < 0 else fw,
        _signed32(int(position)) if problem is None else None,
        bool(torque) if problem is None else None,
        int(hw) if problem is None else None,
        problem,
    )
