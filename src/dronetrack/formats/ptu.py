"""The ASCII command set of FLIR (Directed Perception) pan-tilt units: PTU-D46, the
E Series (PTU-E46) and their kin.

Facts (PTU-D46 User's Manual v2.14.0 §4.2-4.5; FLIR E Series Command Reference
Manual; research notes ``live_devices.md`` §5):

* A command is letters, an optional signed integer value, then a delimiter, a space
  or a carriage return: ``PP`` queries the pan position, ``PP1500`` sets it.  Input
  may be upper or lower case.
* Replies end with a carriage return (line feed too on the units seen by third-party
  drivers; both are taken here): ``*`` for a command carried out, ``* <result>``
  for a query (terse mode, ``FT``; verbose mode, ``FV``, words the result:
  ``* Current pan position is 0``), ``! <message>`` for a command refused, e.g.
  ``! Maximum allowable Pan position is 3090``.  ``!P`` / ``!T``, sent at any time,
  say that the pan / tilt axis hit a limit (a reset prints ``!T!T!P!P*``).
* With echo on (``EE``, the power-up default of the D46) the unit echoes what it
  receives before its reply; ``ED`` turns it off.
* Positions are integers; ``PR`` / ``TR`` give the arc-seconds per position (the D46:
  ``* 185.1428``, 0.0514°), so θ = p · r · π / (180 · 3600).  Speeds ``PS``/``TS``
  are positions/s, accelerations ``PA``/``TA`` positions/s², limits ``PN``, ``PX``,
  ``TN``, ``TX`` positions, the speed bound ``PU``/``TU`` positions/s.
* The serial line powers up at 9600 baud, 8 data bits, no parity, one stop bit: ten
  bit times a byte.

Sign convention.  The unit's tilt grows upwards (the D46's ``TX`` is 31° up, ``TN``
47° down); a turret's tilt here grows downwards (tilt negative looks up, as the
docs/index.md's conventions say), so θ_tilt = −p · r; pan keeps the unit's sign (positive
to the left, counter-clockwise seen from above).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from dronetrack.errors import DecodeError

__all__ = [
    "ARCSEC",
    "AXIS_SIGN",
    "BAUD_RATES",
    "DEFAULT_BAUD",
    "DELIMITERS",
    "CommandSplitter",
    "Reply",
    "angle_to_position",
    "byte_time",
    "parse_number",
    "parse_reply",
    "position_to_angle",
    "split_lines",
]

ARCSEC = math.pi / (180.0 * 3600.0)  # one second of arc [rad]
DEFAULT_BAUD = 9600
# The standard rates a URI may name; which of them a unit takes is its manual's ``@``
# command's business (the power-up rate, 9600, always).
BAUD_RATES = (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200)
DELIMITERS = b" \r\n"  # a command ends at a space or a carriage return (a line feed too)
AXIS_SIGN = {"pan": 1, "tilt": -1}  # turret angle = sign · position · resolution
_LIMIT_RUN = re.compile(r"^(?:!P|!T)+")


def byte_time(baud: int) -> float:
    """Seconds a byte takes on an 8N1 line: a start bit, 8 data bits, a stop bit."""
    return 10.0 / baud


@dataclass(frozen=True, slots=True)
class Reply:
    """One reply line: ``ok`` (``*``) with its ``value`` (the text after ``* ``, empty
    for a plain command), or not ok with the unit's ``message``; ``limit_hits``: the
    ``!P``/``!T`` markers that came before it."""

    ok: bool
    value: str = ""
    message: str = ""
    limit_hits: str = ""


def parse_reply(line: str) -> Reply | None:
    """The reply in one line of the unit's output, or None for a line without one (an
    echo, or limit markers alone).  Echoed text before the ``*`` or ``!`` is skipped."""
    text = line.strip("\r\n")
    hits = ""
    found = _LIMIT_RUN.match(text.lstrip())
    if found:
        hits = found.group(0)
        text = text.lstrip()[found.end() :]
    star, bang = text.find("*"), text.find("!")
    if star < 0 and bang < 0:
        return None
    if bang < 0 or 0 <= star < bang:
        return Reply(True, text[star + 1 :].strip(), limit_hits=hits)
    return Reply(False, message=text[bang + 1 :].strip(), limit_hits=hits)


def split_lines(buffer: bytes) -> tuple[list[str], bytes]:
    """The complete lines in ``buffer`` (ended by CR, LF or CR LF; empty ones dropped),
    decoded as ASCII (undecodable bytes replaced), and the incomplete rest."""
    end = max(buffer.rfind(b"\r"), buffer.rfind(b"\n"))
    if end < 0:
        return [], buffer
    done, rest = buffer[: end + 1], buffer[end + 1 :]
    lines = [s for s in re.split(rb"[\r\n]+", done) if s.strip()]
    return [s.decode("ascii", "replace") for s in lines], rest


def parse_number(reply: Reply, what: str) -> float:
    """The number a terse query answered; DecodeError naming ``what`` if the value is
    not one (e.g. the unit is in verbose mode)."""
    try:
        value = float(reply.value)
    except ValueError:
        raise DecodeError(f"{what}: expected a number, got {reply.value!r}") from None
    if not math.isfinite(value):
        raise DecodeError(f"{what}: expected a finite number, got {reply.value!r}")
    return value


def position_to_angle(position: float, resolution_arcsec: float, axis: str) -> float:
    """A unit's position → the turret's angle [rad]: θ = s · p · r · π / (180 · 3600)."""
    return AXIS_SIGN[axis] * position * resolution_arcsec * ARCSEC


def angle_to_position(angle: float, resolution_arcsec: float, axis: str) -> int:
    """The turret's angle [rad] → the nearest position: p = round(s · θ / (r · ARCSEC))."""
    return round(AXIS_SIGN[axis] * angle / (resolution_arcsec * ARCSEC))


class CommandSplitter:
    """The unit's side of the line: bytes in, commands out.  ``feed`` returns each
    complete command (its text, upper-cased, without the delimiter) with the index
    in the fed bytes of its delimiter; empty commands (delimiters in a row) are
    skipped.  A command longer than ``max_length`` is cut there and returned whole
    at its delimiter, marked with a trailing ``…`` so that it is refused."""

    def __init__(self, max_length: int = 64) -> None:
        self.max_length = max_length
        self._partial = bytearray()
        self._overlong = False

    def feed(self, data: bytes) -> list[tuple[str, int]]:
        out: list[tuple[str, int]] = []
        for i, byte in enumerate(data):
            if byte in DELIMITERS:
                if self._partial or self._overlong:
                    text = self._partial.decode("ascii", "replace").upper()
                    out.append((text + ("…" if self._overlong else ""), i))
                self._partial.clear()
                self._overlong = False
            elif len(self._partial) < self.max_length:
                self._partial.append(byte)
            else:
                self._overlong = True
        return out

    @property
    def pending(self) -> bool:
        return bool(self._partial)
