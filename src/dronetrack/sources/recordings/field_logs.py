"""Seed 003's CSV logs of a run as a recording (the folder ``sinks/strategy_logs.py``
writes; its files and columns: ``formats/seed003_logs.py``).

The folder holds ``filtered_points.csv`` (``t,x,y,z,seq``: the points that passed
the filters, in the world frame [m], and the frame's sequence number), and
usually ``centroids.csv``, ``states.csv`` and ``ekf.csv``.  Only the points are
replayed:

- one frame per sequence number from the first to the last logged; the logger
  writes no row for a frame without points, so a missing number is an empty
  frame, at a time interpolated between its neighbours;
- ``t`` is the frame's end, so a frame's ``stamp`` is t − period and its
  ``duration`` the period (``ReplayOptions.period_s``, else the median time step
  per sequence number, else 0.1 s); every point is at the stamp;
- the points are already in the world frame, so the pose is the identity and
  ``ReplayOptions.sensor_pose`` is ignored;
- ``origin`` is the first frame's stamp in the log's own time (run seconds for a
  simulated run), so frame times start at 0;
- rows that do not parse (e.g. a line cut short when the run stopped) are
  skipped, logged and counted in ``skipped["bad_row"]``.

``ekf.csv`` is the tracker's own estimate, not ground truth: ``ground_truth`` is None.
"""

from __future__ import annotations

import csv
import logging
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import RecordingError
from dronetrack.formats.seed003_logs import LOG_COLUMNS, POINTS_FILE
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sources.frames import fixed_pose_frame
from dronetrack.sources.recordings.recording import (
    PointFileRecording,
    RecordingInfo,
    ReplayOptions,
    TopicInfo,
    frame_period,
)
from dronetrack.types import Frame

__all__ = ["POINTS_FILE", "FieldLogRecording", "read_points_csv"]

log = logging.getLogger(__name__)

_COLUMNS = LOG_COLUMNS[POINTS_FILE]


def _parse_row(row: list[str], columns: list[int]) -> list[float] | None:
    """t, x, y, z, seq of one row, or None if a value is missing, not finite or seq is
    not an integer."""
    try:
        values = [float(row[i]) for i in columns]
    except (ValueError, IndexError):
        return None
    if not all(math.isfinite(v) for v in values) or values[4] != round(values[4]):
        return None
    return values


def read_points_csv(path: Path) -> tuple[FloatArray, list[int]]:
    """The rows (M, 5) ``t, x, y, z, seq`` of a ``filtered_points.csv`` and the line
    numbers of the rows that do not parse; RecordingError if the file does not read."""
    rows: list[list[float]] = []
    bad: list[int] = []
    try:
        with path.open(newline="") as fh:
            reader = csv.reader(fh)
            header = [name.strip() for name in next(reader, [])]
            missing = [c for c in _COLUMNS if c not in header]
            if missing:
                raise RecordingError(
                    f"{path} lacks the columns {', '.join(missing)} "
                    f"(its header: {','.join(header) or 'none'})"
                )
            columns = [header.index(c) for c in _COLUMNS]
            for row in reader:
                if not any(cell.strip() for cell in row):
                    continue
                values = _parse_row(row, columns)
                if values is None:
                    bad.append(reader.line_num)
                else:
                    rows.append(values)
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise RecordingError(f"cannot read {path}: {exc}") from None
    table = np.array(rows, dtype=np.float64).reshape(len(rows), len(_COLUMNS))
    return table, bad


def _csv_summary(path: Path) -> tuple[str, int]:
    """``csv(<header>)`` and the number of non-blank rows after the header."""
    try:
        with path.open(newline="") as fh:
            reader = csv.reader(fh)
            header = next(reader, [])
            rows = sum(1 for row in reader if any(cell.strip() for cell in row))
    except (OSError, UnicodeDecodeError, csv.Error):
        return "csv/unreadable", 0
    return f"csv({','.join(header)})", rows


class FieldLogRecording(PointFileRecording):
    """A folder of seed 003's CSV logs replayed as frames (see the module docstring)."""

    def __init__(self, path: Path, options: ReplayOptions | None = None) -> None:
        super().__init__(path)
        options = options or ReplayOptions()
        if not self.path.is_dir():
            raise RecordingError(f"{self.path} is not a folder")
        points_file = self.path / POINTS_FILE
        if not points_file.is_file():
            raise RecordingError(f"{self.path} has no {POINTS_FILE}: not a seed 003 log folder")
        if options.sensor_pose is not None:
            log.info("%s: points are in the world frame; sensor_pose is ignored", self.path.name)
        table, bad = read_points_csv(points_file)
        if bad:
            self.skipped["bad_row"] += len(bad)
            log.warning(
                "skipping %d rows of %s that do not parse (first at line %d)",
                len(bad),
                points_file,
                bad[0],
            )
        order = np.argsort(table[:, 4], kind="stable")
        self._xyz: FloatArray = table[order, 1:4]
        seq = table[order, 4].astype(np.int64)
        logged, self._starts = np.unique(seq, return_index=True)
        self._ends = np.append(self._starts[1:], len(seq))
        self._logged = logged
        if len(logged):
            self.seqs: NDArray[np.int64] = np.arange(logged[0], logged[-1] + 1)
            ends = np.interp(self.seqs, logged, table[order, 0][self._starts])
        else:
            self.seqs = np.empty(0, np.int64)
            ends = np.empty(0)
        self.period = frame_period(options, ends)
        self._by_time = np.argsort(ends, kind="stable")
        first = float(ends.min()) if len(ends) else self.period
        self.origin = first - self.period
        self._stamps: FloatArray = ends - first

    def frames(self) -> Iterator[Frame]:
        """One frame per sequence number, in time order; empty for numbers without rows."""
        for k in self._by_time.tolist():
            i = int(np.searchsorted(self._logged, self.seqs[k]))
            if i < len(self._logged) and self._logged[i] == self.seqs[k]:
                points = self._xyz[self._starts[i] : self._ends[i]]
            else:
                points = np.empty((0, 3))
            yield fixed_pose_frame(float(self._stamps[k]), self.period, points)

    def info(self) -> RecordingInfo:
        """Each CSV of the folder as a topic, counting its rows."""
        topics = tuple(TopicInfo(f.name, *_csv_summary(f)) for f in sorted(self.path.glob("*.csv")))
        duration = float(np.ptp(self._stamps)) if len(self._stamps) else 0.0
        return RecordingInfo(self.path, "field-logs", self.origin, duration, topics)
