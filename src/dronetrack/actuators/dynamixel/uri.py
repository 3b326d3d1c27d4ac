"""Where a DYNAMIXEL turret is: ``dynamixel://DEVICE?baud=1000000&pan=1&tilt=2&poll_hz=100``.

Every query key is optional; the values shown are the defaults: the WidowX XM430
turret's pan ID 1 and tilt ID 2 at 1 Mbit/s, its present position read 100 times
a second by a thread of its own (``poll_hz=0``: read once a frame, in the frame's
path), e.g. ``dynamixel:///dev/ttyUSB0`` or ``dynamixel:///dev/ttyDXL?baud=57600``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from dronetrack.actuators.uri_query import query_values
from dronetrack.errors import ConfigError

__all__ = [
    "DEFAULT_POLL_HZ",
    "MAX_POLL_HZ",
    "SDK_BAUD_RATES",
    "DynamixelUri",
    "parse_dynamixel_uri",
]

SCHEME = "dynamixel://"
# The baud rates the SDK's PortHandler accepts (others make setBaudRate fail).
SDK_BAUD_RATES = (
    9600, 19200, 38400, 57600, 115200, 230400, 460800, 500000, 576000, 921600,
    1000000, 1152000, 2000000, 2500000, 3000000, 3500000, 4000000,
)  # fmt: skip
DEFAULT_POLL_HZ = 100.0
MAX_POLL_HZ = 1000.0
_INT_KEYS = ("baud", "pan", "tilt")


@dataclass(frozen=True, slots=True)
class DynamixelUri:
    """Where the turret's servos are: serial device, baud rate, pan and tilt IDs, and
    how often their present position is read [Hz] (0: once a frame)."""

    device: str
    baud: int = 1_000_000
    pan_id: int = 1
    tilt_id: int = 2
    poll_hz: float = DEFAULT_POLL_HZ


def _value(uri: str, key: str, text: str) -> float:
    try:
        return int(text) if key in _INT_KEYS else float(text)
    except ValueError:
        kind = "an integer" if key in _INT_KEYS else "a number"
        raise ConfigError(f"Dynamixel turret URI {uri!r}: {key}={text!r} is not {kind}") from None


def parse_dynamixel_uri(uri: str) -> DynamixelUri:
    """``dynamixel://DEVICE?baud=B&pan=ID&tilt=ID&poll_hz=F`` (query keys optional);
    ConfigError with one line naming the problem otherwise."""
    if not uri.startswith(SCHEME):
        raise ConfigError(f"a Dynamixel turret is dynamixel://DEVICE?baud=…, got {uri!r}")
    device, _, query = uri[len(SCHEME) :].partition("?")
    if not device:
        raise ConfigError(f"Dynamixel turret URI {uri!r} names no serial device")
    given = query_values(uri, query, "Dynamixel turret URI", (*_INT_KEYS, "poll_hz"))
    values = {key: _value(uri, key, text) for key, text in given.items()}
    out = DynamixelUri(
        device,
        int(values.get("baud", 1_000_000)),
        int(values.get("pan", 1)),
        int(values.get("tilt", 2)),
        float(values.get("poll_hz", DEFAULT_POLL_HZ)),
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
    if not (out.poll_hz == 0 or (math.isfinite(out.poll_hz) and 1 <= out.poll_hz <= MAX_POLL_HZ)):
        raise ConfigError(
            f"Dynamixel turret URI {uri!r}: poll_hz {out.poll_hz:g} is neither 0 (read once "
            f"a frame) nor in 1–{MAX_POLL_HZ:g} Hz"
        )
    return out
