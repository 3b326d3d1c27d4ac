"""An emulated FLIR pan-tilt unit (PTU-E46) answering its ASCII command set
(``formats.ptu``); joint motion is delegated to an injected ``JointModel`` per axis
(``xm430.JointModel``: the rig's simulated turret, or a rate-limited joint).

The unit powers up with echo on and verbose feedback, as the D46 manual's examples
show; speeds, accelerations and limits come from a turret preset: the resolution
r = the preset's [arc-seconds/position], the position limits the preset's joint
limits in positions (tilt through the sign convention: the unit's tilt grows
upwards), the speed bound ``PU`` = ω_max / r, the speed ``PS`` = the bound, the
acceleration ``PA`` = α_max / r.  The speed and acceleration the host writes are
handed to the joint models (the rig's keep the preset's dynamics, as the servo
emulator's do).

Commands (case does not matter; replies in terse / verbose feedback):

=============  ================================================================
``PP`` ``TP``  query the present position; with a value, the goal (limits on:
               beyond them ``! Maximum allowable Pan position is 3090`` or
               ``! Minimum …``)
``PS`` ``TS``  query / set the speed [positions/s]: above the bound
               ``! Pan speed cannot exceed N positions/sec``, below the lower
               bound ``! Motor speed cannot be less than N pos/sec``
``PA`` ``TA``  query / set the acceleration [positions/s²] (positive)
``PB`` ``TB``  query / set the base speed (kept, no effect)
``PU`` ``TU``  query the upper speed bound; ``PL`` ``TL`` the lower one
``PN`` ``PX``  query the limits [positions]; ``TN`` ``TX`` the tilt's
``PR`` ``TR``  query the resolution [arc-seconds/position], e.g. ``* 46.4400``
``ED`` ``EE``  echo off / on; ``E`` query
``FT`` ``FV``  terse / verbose feedback; ``F`` query
``LE`` ``LD``  position limits enforced / not; ``L`` query
``CI`` ``I``   independent position control, immediate execution (the modes
               emulated: ``CV`` and ``S`` are refused)
``V``          the firmware banner
=============  ================================================================

Anything else, e.g. ``PO`` (offset) or ``R`` (reset), is answered
``! Illegal command``; a value where none belongs, or one that is not an integer,
``! Illegal argument``.  A query is a command without a value.
"""

from __future__ import annotations

import math
import re
import threading
import time
from dataclasses import dataclass

from dronetrack.config.rig import AxisSpec, TurretSpec
from dronetrack.errors import ConfigError
from dronetrack.formats.ptu import ARCSEC, AXIS_SIGN
from dronetrack.sim.emulate.xm430 import Clock, JointModel, RateLimitedJoint

__all__ = ["FIRMWARE_BANNER", "EmulatedPtu", "PtuAxis", "ptu_axis"]

FIRMWARE_BANNER = "Pan-Tilt Controller v3.0.0 (dronetrack emulated PTU-E46)"
DEFAULT_ACCEL = 2000  # positions/s² before the host sets one (the D46 manual's example)
_MODES = {
    "ED": ("echo", False),
    "EE": ("echo", True),
    "FT": ("terse", True),
    "FV": ("terse", False),
    "LE": ("limits_enabled", True),
    "LD": ("limits_enabled", False),
}
_AXIS_COMMANDS = {a + c for a in "PT" for c in "PSABULNXR"}
_NAMES = _AXIS_COMMANDS | set(_MODES) | {"CI", "CV", "I", "S", "E", "F", "L", "V"}
_INTEGER = re.compile(r"^[-+]?[0-9]+$")


@dataclass
class PtuAxis:
    """One axis of the unit: its joint, resolution [arc-seconds/position], limits,
    speed bounds, speed, base speed [positions/s] and acceleration [positions/s²],
    and the goal [positions]."""

    name: str  # "pan" or "tilt"
    joint: JointModel
    resolution_arcsec: float
    minimum: int
    maximum: int
    max_speed: int
    min_speed: int = 0
    speed: int = 0
    base_speed: int = 0
    accel: int = DEFAULT_ACCEL
    goal: int = 0

    @property
    def title(self) -> str:
        return self.name.capitalize()

    @property
    def per_position(self) -> float:
        """Turret angle per position [rad]: s · r (s the sign convention)."""
        return AXIS_SIGN[self.name] * self.resolution_arcsec * ARCSEC

    def position(self, t: float) -> int:
        """The joint's present position: round(θ / (s · r))."""
        return round(self.joint.position(t) / self.per_position)

    def send_profile(self, t: float) -> None:
        r = self.resolution_arcsec * ARCSEC
        self.joint.profile(self.speed * r, self.accel * r, t)


def ptu_axis(spec: AxisSpec, name: str, joint: JointModel | None = None) -> PtuAxis:
    """An axis of the unit made from a preset's axis (see the module docstring); its
    joint is ``joint`` or a rate-limited one at the axis's start.  ConfigError for a
    preset without a resolution."""
    if not spec.resolution > 0:
        raise ConfigError(f"an emulated PTU needs the {name} axis's resolution, got 0")
    arcsec = round(spec.resolution / ARCSEC, 4)  # the unit reports 4 decimals
    per = AXIS_SIGN[name] * arcsec * ARCSEC
    lo, hi = sorted((spec.lower / per, spec.upper / per))
    bound = math.floor(spec.rate / (arcsec * ARCSEC))
    axis = PtuAxis(
        name,
        joint if joint is not None else RateLimitedJoint(),
        arcsec,
        minimum=math.ceil(lo - 1e-9),
        maximum=math.floor(hi + 1e-9),
        max_speed=bound,
        speed=bound,
        accel=max(1, round(spec.accel / (arcsec * ARCSEC))),
    )
    axis.goal = axis.position(0.0)
    return axis


class EmulatedPtu:
    """The unit's command interpreter: ``handle(command, delimiter, t)`` gives the bytes
    it sends back for one command received whole at time ``t`` [s] (on ``clock``,
    the joints' time base).  Every method takes ``lock``, so tests may look while a
    link serves.  Counters: ``commands``, ``refused``."""

    def __init__(self, pan: PtuAxis, tilt: PtuAxis, clock: Clock = time.monotonic) -> None:
        self.axes = {"P": pan, "T": tilt}
        self.clock = clock
        self.echo = True
        self.terse = False
        self.limits_enabled = True
        self.commands = 0
        self.refused = 0
        self.lock = threading.RLock()
        for axis in self.axes.values():
            axis.send_profile(0.0)

    @classmethod
    def from_turret(
        cls,
        turret: TurretSpec,
        pan: JointModel | None = None,
        tilt: JointModel | None = None,
        clock: Clock = time.monotonic,
    ) -> EmulatedPtu:
        """A unit with the preset ``turret``'s axes (``ptu_axis``)."""
        return cls(ptu_axis(turret.pan, "pan", pan), ptu_axis(turret.tilt, "tilt", tilt), clock)

    def handle(self, command: str, delimiter: bytes = b" ", t: float | None = None) -> bytes:
        """The echo (if on) and the reply line to ``command`` (without its delimiter)."""
        with self.lock:
            echo = command.encode("ascii", "replace") + delimiter if self.echo else b""
            reply = self._reply(command.strip().upper(), self.clock() if t is None else t)
            self.commands += 1
            if reply.startswith("!"):
                self.refused += 1
            return echo + reply.encode("ascii") + b"\r\n"

    # -- the commands ---------------------------------------------------------------

    def _reply(self, text: str, t: float) -> str:
        # the command is the longest name the text starts with; the rest is its value
        name = text[:2] if text[:2] in _NAMES else text[:1]
        if name not in _NAMES:
            return "! Illegal command"
        raw = text[len(name) :]
        if raw and not _INTEGER.match(raw):
            return "! Illegal argument"
        value = int(raw) if raw else None
        if name in _AXIS_COMMANDS:
            return self._axis(self.axes[name[0]], name[1], value, t)
        if name in _MODES or name in ("CI", "I"):
            if value is not None:
                return "! Illegal argument"
            if name in _MODES:
                setattr(self, *_MODES[name])
            return "*"
        if value is not None:
            return "! Illegal argument"
        if name == "E":
            return f"* Echoing {'ON' if self.echo else 'OFF'}"
        if name == "F":
            return f"* ASCII {'terse' if self.terse else 'verbose'} mode"
        if name == "L":
            state = "ENABLED" if self.limits_enabled else "DISABLED"
            return f"* Limit bounds are {state}"
        if name == "V":
            return f"* {FIRMWARE_BANNER}"
        return "! Mode not emulated"  # CV, S

    def _say(self, value: object, verbose: str) -> str:
        return f"* {value}" if self.terse else f"* {verbose}"

    def _axis(self, axis: PtuAxis, what: str, value: int | None, t: float) -> str:
        title = axis.title
        if what == "P":
            if value is None:
                now = axis.position(t)
                return self._say(now, f"Current {title} position is {now}")
            return self._goal(axis, value, t)
        if what == "S":
            if value is None:
                return self._say(axis.speed, f"Desired {title} speed is {axis.speed} positions/sec")
            if value > axis.max_speed:
                return f"! {title} speed cannot exceed {axis.max_speed} positions/sec"
            if value < axis.min_speed:
                return f"! Motor speed cannot be less than {axis.min_speed} pos/sec"
            axis.speed = value
            axis.send_profile(t)
            return "*"
        if what == "A":
            if value is None:
                return self._say(
                    axis.accel, f"{title} acceleration is {axis.accel} positions/sec^2"
                )
            if value <= 0:
                return "! Illegal argument"
            axis.accel = value
            axis.send_profile(t)
            return "*"
        if what == "B":
            if value is None:
                base = axis.base_speed
                return self._say(base, f"Current {title} base speed is {base} positions/sec")
            if not 0 <= value <= axis.max_speed:
                return "! Illegal argument"
            axis.base_speed = value
            return "*"
        if value is not None:
            return "! Illegal argument"  # the rest are queries here
        queries: dict[str, tuple[object, str]] = {
            "U": (axis.max_speed, "Maximum {t} speed is {v} positions/sec"),
            "L": (axis.min_speed, "Minimum {t} speed is {v} positions/sec"),
            "N": (axis.minimum, "Minimum {t} position is {v}"),
            "X": (axis.maximum, "Maximum {t} position is {v}"),
            "R": (f"{axis.resolution_arcsec:.4f}", "{v} seconds arc per {t} position"),
        }
        answer, words = queries[what]
        return self._say(answer, words.format(t=title, v=answer))

    def _goal(self, axis: PtuAxis, value: int, t: float) -> str:
        if self.limits_enabled and value > axis.maximum:
            return f"! Maximum allowable {axis.title} position is {axis.maximum}"
        if self.limits_enabled and value < axis.minimum:
            return f"! Minimum allowable {axis.title} position is {axis.minimum}"
        axis.goal = value
        axis.joint.goal(value * axis.per_position, t)
        return "*"

    # -- for tests and the rig ------------------------------------------------------

    def position(self, letter: str, t: float | None = None) -> int:
        """The present position of axis ``letter`` (``P`` or ``T``)."""
        with self.lock:
            return self.axes[letter].position(self.clock() if t is None else t)
