"""Small numeric CSV tables with a header row."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from dronetrack.errors import DronetrackError
from dronetrack.geometry.transforms import FloatArray

__all__ = ["missing_columns", "read_csv_columns"]


def missing_columns(what: str, path: Path, missing: Sequence[str], header: str) -> str:
    """The one line saying that the CSV ``path`` lacks the columns ``missing``, with the
    header it has (a file without one shows its first row here)."""
    return (
        f"{what} {path} is missing column(s): {', '.join(missing)}; its header is "
        f"{header.strip()!r}"
    )


def read_csv_columns(
    path: Path, columns: Sequence[str], error: type[DronetrackError], what: str
) -> FloatArray:
    """The named columns (matched case-insensitively) of a CSV file, as an (N, k) array.

    Raises ``error`` with a one-line message naming ``what`` and the problem: a
    missing file or column, a value that is not a number, or no rows.  NaN and
    infinity are returned as read; the caller decides whether they are allowed.
    """
    if not path.is_file():
        raise error(f"{what} not found: {path}")
    with path.open("r", encoding="utf-8-sig", errors="replace") as f:
        line = f.readline()
    header = [h.strip().lower() for h in line.strip().split(",")]
    missing = [c for c in columns if c.lower() not in header]
    if missing:
        raise error(missing_columns(what, path, missing, line))
    cols = [header.index(c.lower()) for c in columns]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "input contained no data"
            data = np.loadtxt(
                path, delimiter=",", skiprows=1, usecols=cols, ndmin=2, encoding="utf-8-sig"
            )
    except ValueError as err:
        raise error(f"{what} {path} has a value that is not a number: {err}") from None
    if len(data) == 0:
        raise error(f"{what} {path} has no rows")
    return np.asarray(data, dtype=np.float64)
