"""Where a FLIR pan-tilt unit is: ``ptu://DEVICE?baud=9600&poll_hz=20`` on a serial
line, or ``ptu://HOST:PORT?poll_hz=20`` over TCP (the E Series' Ethernet port).

Every query key is optional; the values shown are the defaults: the unit's power-up
9600 baud (8N1; serial only), its present position read 20 times a second by a
thread of its own (``poll_hz=0``: read once a frame, in the frame's path), e.g.
``ptu:///dev/ttyUSB0``, ``ptu:///dev/ttyUSB0?baud=38400`` or
``ptu://192.168.1.110:4000``.  A DEVICE is an absolute path or a Windows ``COMn``; a
HOST:PORT ends in ``:`` and a port number, with IPv6 addresses in brackets
(``ptu://[fe80::1]:4000``).

At 9600 baud a byte takes 1.04 ms: one read of both positions (``PP TP`` and two
replies, about 24 bytes) holds the line for about 24 ms, so the default 20 reads a
second leave half the line to the frames' commands.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

from dronetrack.actuators.uri_query import query_values
from dronetrack.errors import ConfigError
from dronetrack.formats.ptu import BAUD_RATES, DEFAULT_BAUD

__all__ = ["DEFAULT_POLL_HZ", "MAX_POLL_HZ", "SCHEME", "PtuUri", "parse_ptu_uri"]

SCHEME = "ptu://"
DEFAULT_POLL_HZ = 20.0
MAX_POLL_HZ = 200.0
_COM_PORT = re.compile(r"^COM[0-9]+$", re.IGNORECASE)
_HOST_PORT = re.compile(r"^(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):(?P<port>[0-9]+)$")


@dataclass(frozen=True, slots=True)
class PtuUri:
    """A unit on a serial ``device`` at ``baud``, or at ``host``:``port`` over TCP
    (``device`` None); how often its position is read [Hz] (0: once a frame)."""

    device: str | None
    host: str | None = None
    port: int | None = None
    baud: int = DEFAULT_BAUD
    poll_hz: float = DEFAULT_POLL_HZ

    @property
    def where(self) -> str:
        """The device path, or HOST:PORT."""
        return self.device if self.device is not None else f"{self.host}:{self.port}"

    @property
    def name(self) -> str:
        """The unit as errors name it."""
        return (
            f"FLIR PTU on {self.device}" if self.device is not None else f"FLIR PTU at {self.where}"
        )


def parse_ptu_uri(uri: str) -> PtuUri:
    """``ptu://DEVICE?baud=B&poll_hz=F`` or ``ptu://HOST:PORT?poll_hz=F``; ConfigError
    with one line naming the problem otherwise."""
    if not uri.startswith(SCHEME):
        raise ConfigError(f"a FLIR PTU is ptu://DEVICE or ptu://HOST:PORT, got {uri!r}")
    where, _, query = uri[len(SCHEME) :].partition("?")
    if not where:
        raise ConfigError(f"FLIR PTU URI {uri!r} names no serial device or HOST:PORT")
    values = query_values(uri, query, "FLIR PTU URI", ("baud", "poll_hz"))
    found = _HOST_PORT.match(where)
    host = port = None
    device: str | None = where
    if found is not None:
        device, host, port = None, found.group("host").strip("[]"), int(found.group("port"))
        if not 1 <= port <= 65535:
            raise ConfigError(f"FLIR PTU URI {uri!r}: port {port} is not in 1-65535")
        if "baud" in values:
            raise ConfigError(f"FLIR PTU URI {uri!r}: baud is for a serial line, not TCP")
    elif not (where.startswith("/") or _COM_PORT.match(where)):
        raise ConfigError(
            f"FLIR PTU URI {uri!r}: give a serial device's path (ptu:///dev/ttyUSB0) or "
            "HOST:PORT (ptu://192.168.1.110:4000)"
        )
    try:
        baud = int(values.get("baud", DEFAULT_BAUD))
    except ValueError:
        raise ConfigError(
            f"FLIR PTU URI {uri!r}: baud={values['baud']!r} is not an integer"
        ) from None
    try:
        poll_hz = float(values.get("poll_hz", DEFAULT_POLL_HZ))
    except ValueError:
        raise ConfigError(
            f"FLIR PTU URI {uri!r}: poll_hz={values['poll_hz']!r} is not a number"
        ) from None
    if baud not in BAUD_RATES:
        raise ConfigError(
            f"FLIR PTU URI {uri!r}: baud {baud} is not a standard rate "
            f"({', '.join(map(str, BAUD_RATES))})"
        )
    if not (poll_hz == 0 or (math.isfinite(poll_hz) and 1 <= poll_hz <= MAX_POLL_HZ)):
        raise ConfigError(
            f"FLIR PTU URI {uri!r}: poll_hz {poll_hz:g} is neither 0 (read once a frame) "
            f"nor in 1-{MAX_POLL_HZ:g} Hz"
        )
    return PtuUri(device, host, port, baud, poll_hz)
