"""One emulated DYNAMIXEL XM430-W350: its control table and the rules of writing it;
joint motion is delegated to an injected ``JointModel``.

Control table (XM430-W350 e-manual; address, size, access, range):

======  ====  =====  ======================  =========================================
addr    size  area   item                    rule here
======  ====  =====  ======================  =========================================
0       2     EEPROM model number            read-only, 1020
6       1     EEPROM firmware version        read-only
7       1     EEPROM ID                      0–252
8       1     EEPROM baud rate               0–7 (the rate it hears: ``ServoBus``)
9       1     EEPROM return delay time       0–254 (stored only)
10      1     EEPROM drive mode              bits 0, 2, 3 (stored only)
11      1     EEPROM operating mode          0, 1, 3, 4, 5, 16 (motion modelled for 3)
13      1     EEPROM protocol type           1–2 (stored only)
44      4     EEPROM velocity limit          0–1023
48      4     EEPROM max position limit      0–4095
52      4     EEPROM min position limit      0–4095
64      1     RAM    torque enable           0–1; 1 locks the EEPROM area
65      1     RAM    LED                     0–1
68      1     RAM    status return level     0–2
70      1     RAM    hardware error status   read-only; non-zero sets the alert bit
108     4     RAM    profile acceleration    0–32767 (handed to the joint model)
112     4     RAM    profile velocity        0–32767, ≤ velocity limit (else limit error)
116     4     RAM    goal position           min–max position limit (else limit error)
120     2     RAM    realtime tick           read-only, ms modulo 32768
122     1     RAM    moving                  read-only
128     4     RAM    present velocity        read-only, signed, 0.229 rpm
132     4     RAM    present position        read-only, signed, ticks
======  ====  =====  ======================  =========================================

Error numbers, as this emulator gives them: an undefined or read-only address,
or an EEPROM write with torque on → access error (7); a write that covers part
of an item → data length error (5); a value outside an item's own range → data
range error (4); a goal position outside the position limits or a profile
velocity above the velocity limit → data limit error (6); an instruction it does
not implement, or malformed parameters → instruction error (2); a whole packet
with a bad CRC addressed to a present servo → CRC error (3).  A failed write
changes nothing.  The choice between range and limit errors follows the
protocol document's wording; the real firmware's choice was not checked.

On torque on the goal is set to the present position (the servo holds where it
is); with torque off goals are stored but nothing moves.  Reboot answers, then
restores the RAM area's initial values (torque off).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

from dronetrack.formats.dynamixel import (
    ADDR,
    BAUD_RATE_CODES,
    Err,
    rad_to_ticks,
    rate_to_units,
    ticks_to_rad,
    units_to_accel,
    units_to_rate,
)

__all__ = [
    "FIRMWARE_VERSION",
    "MODEL_XM430_W350",
    "Clock",
    "EmulatedXM430",
    "JointModel",
    "RateLimitedJoint",
]

MODEL_XM430_W350 = 1020
FIRMWARE_VERSION = 48
Clock = Callable[[], float]


class JointModel(Protocol):
    """The joint a servo drives: takes goals, reports where it is; angles [rad], t [s]."""

    def profile(self, rate: float, accel: float, t: float) -> None:
        """From time ``t`` on, the profile's velocity [rad/s] and acceleration [rad/s²]
        limits; 0 = unlimited."""
        ...

    def goal(self, angle: float, t: float) -> None:
        """Move toward ``angle`` from time ``t`` on."""
        ...

    def position(self, t: float) -> float: ...

    def velocity(self, t: float) -> float: ...


class RateLimitedJoint:
    """A joint that moves at the profile velocity ω straight to its goal (no acceleration
    phase; ω = 0 steps at once):  q(t) = q₀ + sgn(q* − q₀) · min(|q* − q₀|, ω (t − t₀))."""

    def __init__(self, angle: float = 0.0) -> None:
        self.q0 = angle  # position when the current goal was set [rad]
        self.t0 = 0.0  # time the current goal was set [s]
        self.target = angle  # q* [rad]
        self.rate = 0.0  # ω [rad/s], 0 = unlimited

    def profile(self, rate: float, accel: float, t: float) -> None:
        self.q0, self.t0 = self.position(t), t  # the move so far keeps its old rate
        self.rate = max(rate, 0.0)

    def goal(self, angle: float, t: float) -> None:
        self.q0, self.t0, self.target = self.position(t), t, angle

    def _travel(self, t: float) -> tuple[float, float]:
        """(distance left to cover at the goal's start, distance covered by t)."""
        span = abs(self.target - self.q0)
        if self.rate <= 0.0:
            return span, span
        return span, min(span, self.rate * max(t - self.t0, 0.0))

    def position(self, t: float) -> float:
        span, done = self._travel(t)
        return self.target if done >= span else self.q0 + math.copysign(done, self.target - self.q0)

    def velocity(self, t: float) -> float:
        span, done = self._travel(t)
        if done >= span or self.rate <= 0.0:
            return 0.0
        return math.copysign(self.rate, self.target - self.q0)


@dataclass(frozen=True, slots=True)
class _Item:
    address: int
    size: int
    name: str
    writable: bool
    lo: int = 0
    hi: int = 0
    initial: int = 0
    signed: bool = False

    @property
    def eeprom(self) -> bool:
        return self.address < ADDR.EEPROM_END


_ITEMS = (
    _Item(ADDR.MODEL_NUMBER, 2, "model number", False, initial=MODEL_XM430_W350),
    _Item(2, 4, "model information", False),
    _Item(ADDR.FIRMWARE_VERSION, 1, "firmware version", False, initial=FIRMWARE_VERSION),
    _Item(ADDR.ID, 1, "ID", True, 0, 252, 1),
    _Item(ADDR.BAUD_RATE, 1, "baud rate", True, 0, 7, 1),
    _Item(ADDR.RETURN_DELAY, 1, "return delay time", True, 0, 254, 250),
    _Item(ADDR.DRIVE_MODE, 1, "drive mode", True, 0, 0x0D, 0),
    _Item(ADDR.OPERATING_MODE, 1, "operating mode", True, 0, 16, 3),
    _Item(ADDR.PROTOCOL, 1, "protocol type", True, 1, 2, 2),
    _Item(ADDR.VELOCITY_LIMIT, 4, "velocity limit", True, 0, 1023, 350),
    _Item(ADDR.MAX_POSITION, 4, "max position limit", True, 0, 4095, 4095),
    _Item(ADDR.MIN_POSITION, 4, "min position limit", True, 0, 4095, 0),
    _Item(ADDR.TORQUE_ENABLE, 1, "torque enable", True, 0, 1, 0),
    _Item(ADDR.LED, 1, "LED", True, 0, 1, 0),
    _Item(ADDR.STATUS_RETURN_LEVEL, 1, "status return level", True, 0, 2, 2),
    _Item(ADDR.HARDWARE_ERROR, 1, "hardware error status", False),
    _Item(ADDR.PROFILE_ACCELERATION, 4, "profile acceleration", True, 0, 32767, 0),
    _Item(ADDR.PROFILE_VELOCITY, 4, "profile velocity", True, 0, 32767, 0),
    _Item(ADDR.GOAL_POSITION, 4, "goal position", True, -1048575, 1048575, 2048, True),
    _Item(ADDR.REALTIME_TICK, 2, "realtime tick", False),
    _Item(ADDR.MOVING, 1, "moving", False),
    _Item(ADDR.PRESENT_VELOCITY, 4, "present velocity", False, signed=True),
    _Item(ADDR.PRESENT_POSITION, 4, "present position", False, initial=2048, signed=True),
)
_BY_ADDRESS = {item.address: item for item in _ITEMS}
_TABLE_END = max(item.address + item.size for item in _ITEMS)
_OPERATING_MODES = frozenset({0, 1, 3, 4, 5, 16})
_DRIVE_MODE_BITS = 0x0D  # bit 0 reverse, bit 2 time-based profile, bit 3 torque on by goal


def _owner(address: int) -> _Item | None:
    """The item whose bytes include ``address``."""
    for item in _ITEMS:
        if item.address <= address < item.address + item.size:
            return item
    return None


class EmulatedXM430:
    """One XM430-W350: its control table and the effects of writing it.

    ``online = False`` makes it deaf (unplugged); ``goals`` lists every goal position
    [ticks] it accepted, in order.
    """

    def __init__(self, ident: int = 1, joint: JointModel | None = None) -> None:
        self.values = {item.address: item.initial for item in _ITEMS}
        self.values[ADDR.ID] = ident
        self.joint: JointModel = joint if joint is not None else RateLimitedJoint()
        self.values[ADDR.GOAL_POSITION] = self.values[ADDR.PRESENT_POSITION] = rad_to_ticks(
            self.joint.position(0.0)
        )
        self.online = True
        self.goals: list[int] = []

    @property
    def ident(self) -> int:
        return self.values[ADDR.ID]

    @property
    def baud(self) -> int:
        """The rate it listens and answers at (its Baud Rate item) [baud]."""
        return BAUD_RATE_CODES[self.values[ADDR.BAUD_RATE]]

    @property
    def torque(self) -> bool:
        return self.values[ADDR.TORQUE_ENABLE] == 1

    def error_byte(self, number: int) -> int:
        """The status error byte: ``number`` in bits 0–6, the alert bit if a hardware error."""
        return number | (Err.ALERT if self.values[ADDR.HARDWARE_ERROR] else 0)

    def refresh(self, t: float) -> None:
        """Bring the read-only live items to time ``t``."""
        q, w = self.joint.position(t), self.joint.velocity(t)
        self.values[ADDR.PRESENT_POSITION] = rad_to_ticks(q)
        self.values[ADDR.PRESENT_VELOCITY] = rate_to_units(w)
        self.values[ADDR.MOVING] = int(w != 0.0)
        self.values[ADDR.REALTIME_TICK] = int(t * 1000.0) % 32768

    def read(self, address: int, length: int, t: float) -> tuple[int, bytes]:
        """(error number, bytes) of a READ; gaps between items read as 0."""
        if length < 1 or _owner(address) is None or address + length > _TABLE_END:
            return Err.ACCESS, b""
        self.refresh(t)
        image = bytearray(_TABLE_END)
        for item in _ITEMS:
            value = self.values[item.address]
            image[item.address : item.address + item.size] = value.to_bytes(
                item.size, "little", signed=item.signed
            )
        return Err.NONE, bytes(image[address : address + length])

    def write(self, address: int, data: bytes, t: float) -> int:
        """Write ``data`` from ``address`` (whole items only); the error number, 0 if done."""
        new: dict[int, int] = {}
        at, end = address, address + len(data)
        while at < end:
            item = _BY_ADDRESS.get(at)
            if item is None:
                return Err.DATA_LENGTH if _owner(at) is not None else Err.ACCESS
            if at + item.size > end:
                return Err.DATA_LENGTH
            if not item.writable or (item.eeprom and self.torque):
                return Err.ACCESS
            raw = data[at - address : at - address + item.size]
            new[at] = int.from_bytes(raw, "little", signed=item.signed)
            at += item.size
        if not new:
            return Err.DATA_LENGTH
        for at, value in new.items():
            item = _BY_ADDRESS[at]
            if not item.lo <= value <= item.hi:
                return Err.DATA_RANGE
            if at == ADDR.OPERATING_MODE and value not in _OPERATING_MODES:
                return Err.DATA_RANGE
            if at == ADDR.DRIVE_MODE and value & ~_DRIVE_MODE_BITS:
                return Err.DATA_RANGE
        after = {**self.values, **new}
        if (
            ADDR.GOAL_POSITION in new
            and after[ADDR.OPERATING_MODE] == 3
            and not after[ADDR.MIN_POSITION] <= new[ADDR.GOAL_POSITION] <= after[ADDR.MAX_POSITION]
        ):
            return Err.DATA_LIMIT
        if ADDR.PROFILE_VELOCITY in new and new[ADDR.PROFILE_VELOCITY] > after[ADDR.VELOCITY_LIMIT]:
            return Err.DATA_LIMIT
        for at in sorted(new):  # in address order: profile (108, 112) before goal (116)
            self._apply(at, new[at], t)
        return Err.NONE

    def _apply(self, address: int, value: int, t: float) -> None:
        old = self.values[address]
        self.values[address] = value
        if address == ADDR.TORQUE_ENABLE and value != old:
            here = self.joint.position(t)
            self.joint.goal(here, t)  # torque on: hold here; torque off: coast to a stop here
            if value:
                self.values[ADDR.GOAL_POSITION] = rad_to_ticks(here)
        elif address in (ADDR.PROFILE_VELOCITY, ADDR.PROFILE_ACCELERATION):
            self.joint.profile(
                units_to_rate(self.values[ADDR.PROFILE_VELOCITY]),
                units_to_accel(self.values[ADDR.PROFILE_ACCELERATION]),
                t,
            )
        elif address == ADDR.GOAL_POSITION:
            self.goals.append(value)
            if self.torque:
                self.joint.goal(ticks_to_rad(value), t)

    def reboot(self, t: float) -> None:
        """Restore the RAM area's initial values (torque off, no profile), keep the EEPROM."""
        self.refresh(t)
        here = self.values[ADDR.PRESENT_POSITION]
        for item in _ITEMS:
            if not item.eeprom and item.writable:
                self.values[item.address] = item.initial
        self.values[ADDR.GOAL_POSITION] = here
        self.joint.goal(self.joint.position(t), t)
        self.joint.profile(0.0, 0.0, t)
