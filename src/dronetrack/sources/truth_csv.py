"""``--truth``: a target's true positions from a CSV of t,x,y,z [s, m], read whole for a
recording (``read_truth_csv``) or as it grows beside a live run (``TruthFile``:
``dronetrack emulate`` writes it row by row), and looked up on a live run's clock
(``RunTruth``: the rows are in the sensor's time base, the run's clock starts at its
first point)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from dronetrack.errors import InputError
from dronetrack.formats.tables import missing_columns
from dronetrack.sources.assembly import NS
from dronetrack.sources.truth import GroundTruth, RecordedTruth

__all__ = ["TRUTH_COLUMNS", "RunTruth", "TruthFile", "read_truth_csv"]

TRUTH_COLUMNS = ("t", "x", "y", "z")


def _truth_value(cells: list[str], index: int, name: str) -> float:
    """Column ``name`` (at ``index``) of a truth row as a finite number; ValueError
    saying what is wrong with it."""
    if index >= len(cells):
        raise ValueError(
            f"{len(cells)} value(s), too few for column {name} (column {index + 1} of the header)"
        )
    try:
        value = float(cells[index])
    except ValueError:
        raise ValueError(f"{name} is {cells[index]!r}, not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{name} is {cells[index]!r}, not a finite number")
    return value


class TruthFile:
    """``--truth``: a CSV of t,x,y,z [s, m] read as it grows (``dronetrack emulate``
    writes it row by row while the run goes).  ``ground_truth`` reads the rows added
    since the last call (a line is taken once it is complete) and gives them all;
    None while there are none.  InputError names the file and line of a bad header,
    a value that is not a finite number, or a time that goes back."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        if not self.path.is_file():
            raise InputError(f"truth CSV not found: {self.path}")
        self._offset = 0
        self._rest = b""
        self._line = 0
        self._columns: list[int] | None = None
        # rows (t, x, y, z) in a buffer that doubles when full, so a frame's new rows
        # cost their own parsing only, however long the run (amortised O(1) a row)
        self._rows = np.empty((256, 4), np.float64)
        self._n = 0
        self._built: GroundTruth | None = None
        self.ground_truth()  # check what is there already

    def _parse(self, line: str) -> None:
        self._line += 1
        cells = [c.strip() for c in line.strip().lstrip("\ufeff").split(",")]
        if cells == [""]:
            return
        if self._columns is None:
            names = [c.lower() for c in cells]
            missing = [c for c in TRUTH_COLUMNS if c not in names]
            if missing:
                header = line.lstrip("\ufeff")
                raise InputError(missing_columns("truth CSV", self.path, missing, header))
            self._columns = [names.index(c) for c in TRUTH_COLUMNS]
            return
        where = f"truth CSV {self.path} line {self._line}"
        pairs = zip(self._columns, TRUTH_COLUMNS, strict=True)
        try:
            row = [_truth_value(cells, i, name) for i, name in pairs]
        except ValueError as err:
            raise InputError(f"{where}: {err}: {line.strip()!r}") from None
        if self._n and row[0] < self._rows[self._n - 1, 0]:
            raise InputError(
                f"{where}: t must not decrease; it goes back from "
                f"{self._rows[self._n - 1, 0]:g} to {row[0]:g} s"
            )
        if self._n == len(self._rows):
            self._rows = np.concatenate([self._rows, np.empty_like(self._rows)])
        self._rows[self._n] = row
        self._n += 1

    def ground_truth(self) -> GroundTruth | None:
        try:
            with self.path.open("rb") as fh:
                fh.seek(self._offset)
                data = fh.read()
                self._offset = fh.tell()
        except OSError as exc:
            raise InputError(f"truth CSV {self.path}: {exc}") from exc
        *lines, self._rest = (self._rest + data).split(b"\n")
        before = self._n
        for line in lines:
            self._parse(line.decode("utf-8", "replace"))
        if not self._n:
            return None
        if self._built is None or self._n != before:
            # views of the first n rows: rows added later go past them, and a grown
            # buffer is a new array, so a GroundTruth given out never changes
            a = self._rows[: self._n]
            self._built = GroundTruth(a[:, 0], a[:, 1:])
        return self._built


def read_truth_csv(path: Path) -> GroundTruth:
    """A whole truth CSV (t,x,y,z, as ``TruthFile`` reads it) as ground truth, for
    ``track --truth``; InputError if it has no rows."""
    truth = TruthFile(path).ground_truth()
    if truth is None:
        raise InputError(f"truth CSV {path} has no rows")
    return truth


class RunTruth:
    """``--truth`` looked up on a live run's clock: the target's positions in the
    sensor's time base (a ``TruthFile`` is read as it grows), shifted by the time t₀ of
    the run's start on that base; a return within ``radius`` [m] of the true position
    counts as the target's."""

    def __init__(self, truth: GroundTruth | TruthFile, radius: float) -> None:
        self.truth = truth
        self.radius = radius
        self._shifted: tuple[GroundTruth, GroundTruth] | None = None  # (given, shifted)

    def at(self, t: float, t0_ns: int) -> RecordedTruth | None:
        """The truth at ``t`` [s] on the run's clock, whose 0 is ``t0_ns`` on the
        sensor's; None while there is none."""
        g = self.truth.ground_truth() if isinstance(self.truth, TruthFile) else self.truth
        if g is None:
            return None
        if self._shifted is None or self._shifted[0] is not g:
            self._shifted = (g, GroundTruth(g.t - t0_ns / NS, g.position, g.max_gap_s))
        shifted = self._shifted[1]
        return RecordedTruth(shifted, shifted.at(t)[0], self.radius)
