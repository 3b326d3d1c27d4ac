"""Reading a TOML file (scenarios, configurations, sweep grids) with one-line errors,
and the numbers a configuration writes to one.

TOML files must be UTF-8 (TOML 1.0, §"Spec").  A file in another encoding, such as a
Latin-1 ``°`` in a comment, gets an error that names the file, the byte, its offset
and its line, instead of Python's ``UnicodeDecodeError``.

A value a run derives by arithmetic (a frame period from nanosecond stamps, a σ of
eq. (11), an angle turned to degrees) carries binary rounding noise:
0.09999999999999999 for 0.1.  ``tidy_model`` takes it out; the functions that write
derived values into a configuration (``resolve_scenario``, ``resolve_pipeline``) end
with it, so the configuration a run uses, and writes to config.toml, reads 0.1 and
re-runs the same.  A value whose digits are real (0.26666666666666666) is left alone.
"""

from __future__ import annotations

import math
import tomllib
from pathlib import Path
from typing import Any, TypeVar

from pydantic import BaseModel, ValidationError

from dronetrack.errors import ConfigError

__all__ = ["format_validation_error", "read_toml", "tidy_float", "tidy_model"]

DIGITS = 12  # significant digits of the short form a noisy value is replaced by
NOISE_ULPS = 4  # how far from it, in units in the last place, counts as noise

Model = TypeVar("Model", bound=BaseModel)


def tidy_float(x: float) -> float:
    """``x``, or the number of ``DIGITS`` significant digits nearest to it when that is
    within ``NOISE_ULPS`` units in the last place (0.1 for 0.09999999999999999)."""
    if not math.isfinite(x) or x == 0.0:
        return x
    short = float(f"{x:.{DIGITS}g}")
    return short if abs(short - x) <= NOISE_ULPS * math.ulp(x) else x


def _tidy(value: Any) -> Any:
    if isinstance(value, BaseModel):
        return tidy_model(value)
    if type(value) is float:
        return tidy_float(value)
    if isinstance(value, tuple | list):
        return type(value)(_tidy(v) for v in value)
    if isinstance(value, dict):
        return {k: _tidy(v) for k, v in value.items()}
    return value


def tidy_model(model: Model) -> Model:
    """``model`` with every float in it, nested sections included, through ``tidy_float``."""
    return model.model_copy(update={name: _tidy(value) for name, value in model})


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


def format_validation_error(err: ValidationError, source: str) -> str:
    """One line naming the first bad key and why."""
    first = err.errors()[0]
    key = ".".join(str(p) for p in first["loc"]) or "(top level)"
    if first["type"] == "extra_forbidden":
        msg = f"{source}: unknown key '{key}'"
    elif not first["loc"] and first["type"] == "value_error":
        # A check across sections names its keys itself.
        msg = f"{source}: {first['msg'].removeprefix('Value error, ')}"
    else:
        msg = f"{source}: {key}: {first['msg'].removeprefix('Value error, ')}"
    more = len(err.errors()) - 1
    return msg + (f" (and {more} more problem{'s' if more > 1 else ''})" if more else "")
