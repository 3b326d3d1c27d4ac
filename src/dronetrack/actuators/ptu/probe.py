"""``dronetrack info ptu://…``: what a FLIR pan-tilt unit says of itself.

Nothing that moves the unit or changes its motion settings is sent: a bare
delimiter, echo off and terse feedback (``ED``, ``FT``: how it answers, which the
driver sets anyway), then queries only: the firmware banner (``V``), and per axis
the resolution, limits, speed bound, speed, acceleration and present position.
"""

from __future__ import annotations

import math

from dronetrack.actuators.ptu.line import PtuLine, open_line
from dronetrack.actuators.ptu.uri import parse_ptu_uri
from dronetrack.errors import DecodeError, DeviceError
from dronetrack.formats.ptu import ARCSEC, parse_number, position_to_angle

__all__ = ["probe_ptu", "probe_ptu_line"]

_AXIS_QUERIES = ("R", "N", "X", "U", "S", "A", "P")


def probe_ptu(uri: str) -> list[tuple[str, str]]:
    """(name, value) lines describing the unit ``uri`` names; DeviceError if it cannot
    be reached or does not answer."""
    where = parse_ptu_uri(uri)
    line = open_line(where)
    try:
        rate = f", {where.baud} baud 8N1" if where.device is not None else " (TCP)"
        return [("device", f"{where.name}{rate}"), *probe_ptu_line(line)]
    finally:
        line.close()


def probe_ptu_line(line: PtuLine) -> list[tuple[str, str]]:
    """The firmware line and one line per axis, asked on an open ``line``."""
    line.interrupt()
    line.transact(["ED"], "echo off")
    line.transact(["FT"], "terse feedback")
    try:
        banner = line.transact(["V"], "firmware version").replies[0].value
    except DeviceError as exc:
        if "answered !" not in str(exc):
            raise
        banner = f"unknown ({exc})"
    out = [("firmware", banner or "unknown (empty answer)")]
    for name, letter in (("pan", "P"), ("tilt", "T")):
        asked = [letter + q for q in _AXIS_QUERIES]
        replies = line.transact(asked, f"read the {name} axis").replies
        try:
            v = {
                q: parse_number(r, f"{line.name}: {c}")
                for q, c, r in zip(_AXIS_QUERIES, asked, replies, strict=True)
            }
        except DecodeError as exc:
            raise DeviceError(str(exc)) from None
        out.append((name, _axis_line(name, v)))
    out.append(("convention", "turret angles: pan as the unit's, tilt = −(the unit's), down > 0"))
    return out


def _axis_line(name: str, v: dict[str, float]) -> str:
    arcsec = v["R"]

    def deg(position: float) -> str:
        return f"{math.degrees(position_to_angle(position, arcsec, name)):.1f}°"

    per = math.degrees(arcsec * ARCSEC)
    return (
        f"resolution {arcsec:g}″ a position ({per:.4f}°); "
        f"limits {v['N']:g} to {v['X']:g} ({deg(v['N'])} to {deg(v['X'])}); "
        f"speed {v['S']:g} positions/s ({v['S'] * per:.1f}°/s, bound {v['U']:g}); "
        f"acceleration {v['A']:g} positions/s² ({v['A'] * per:.1f}°/s²); "
        f"present position {v['P']:g} ({deg(v['P'])})"
    )
