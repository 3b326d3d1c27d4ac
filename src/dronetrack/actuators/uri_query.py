"""The query of a turret's URI (``?key=value&…``) as a dictionary, checked."""

from __future__ import annotations

from dronetrack.errors import ConfigError

__all__ = ["query_values"]


def query_values(uri: str, query: str, what: str, allowed: tuple[str, ...]) -> dict[str, str]:
    """``query``'s key=value pairs; ConfigError naming ``what`` (e.g. "FLIR PTU URI") and
    ``uri`` for a part that is not key=value, a key not in ``allowed``, or one given twice."""
    values: dict[str, str] = {}
    for part in query.split("&") if query else []:
        key, eq, text = part.partition("=")
        if not eq or not key:
            raise ConfigError(f"{what} {uri!r}: {part!r} is not key=value")
        if key not in allowed:
            raise ConfigError(f"{what} {uri!r}: unknown key {key!r} ({', '.join(allowed)})")
        if key in values:
            raise ConfigError(f"{what} {uri!r}: {key} given twice")
        values[key] = text
    return values
