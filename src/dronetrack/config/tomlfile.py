"""Reading a TOML file (scenarios, configurations, sweep grids) with one-line errors.

TOML files must be UTF-8 (TOML 1.0, §"Spec").  A file in another encoding, such as a
Latin-1 ``°`` in a comment, gets an error that names the file, the byte, its offset
and its line, instead of Python's ``UnicodeDecodeError``.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from dronetrack.errors import ConfigError

__all__ = ["read_toml"]


def read_toml(path: Path, what: str, error: type[ConfigError] = ConfigError) -> dict[str, Any]:
    """The table in the TOML file ``path``; ``error`` (a ``ConfigError``) with a one-line
    message naming ``what`` and the file when it is missing, unreadable, not UTF-8 or
    not TOML."""
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise error(f"{what} not found: {path}") from None
    except IsADirectoryError:
        raise error(f"{what} {path} is a folder, not a TOML file") from None
    except OSError as err:
        raise error(f"{what} {path}: cannot read it ({err.strerror})") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        line = raw.count(b"\n", 0, err.start) + 1
        raise error(
            f"{path}: not UTF-8 text: byte 0x{raw[err.start]:02x} at byte offset {err.start} "
            f"(line {line}); TOML files must be UTF-8, so save it in that encoding"
        ) from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise error(f"{path}: invalid TOML: {err}") from None
