"""Seed 003's CSV logs of a run as a sink, one folder per run (the files and their
columns: ``formats/seed003_logs.py``)."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from dronetrack.formats.seed003_logs import LOG_COLUMNS
from dronetrack.types import Sample, StepResult

__all__ = ["StrategyLogger"]

_HEADERS = LOG_COLUMNS


class StrategyLogger:
    """Streams a run's tracking frames' logs to ``folder`` (a run loop's sink), then
    ``close`` adds the controller's state transitions."""

    def __init__(self, folder: Path) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        self.folder = folder
        self._files: dict[str, TextIO] = {}
        self._writers: dict[str, Any] = {}
        for name, header in _HEADERS.items():
            fh = (folder / name).open("w", newline="")
            self._files[name] = fh
            self._writers[name] = csv.writer(fh)
            self._writers[name].writerow(header)
        self._seq = 0

    def write(self, sample: Sample, result: StepResult) -> None:
        """Log one tracking frame (the background scan's are not logged)."""
        if result.phase != "track":
            return
        t = f"{result.t:.6f}"
        pts = result.foreground
        if len(pts):
            rows = np.column_stack([pts, np.full(len(pts), self._seq)])
            self._writers["filtered_points.csv"].writerows(
                [t, f"{x:.4f}", f"{y:.4f}", f"{z:.4f}", int(s)] for x, y, z, s in rows
            )
        est = result.estimate
        if est is not None:
            if est.measurement is not None:
                self._writers["centroids.csv"].writerow([t, *(f"{v:.4f}" for v in est.measurement)])
            var = est.variance if est.variance is not None else np.full(6, np.nan)
            state = [*est.position, *est.velocity, *var]
            self._writers["ekf.csv"].writerow([t, *(f"{v:.6g}" for v in state)])
        self._seq += 1

    def close(self, controller: object) -> None:
        """Write the controller's state transitions (if it keeps them) and close the files."""
        for tr in getattr(controller, "transitions", ()):
            t, before, after, strategy = tr
            self._writers["states.csv"].writerow([f"{t:.6f}", before, after, strategy])
        for fh in self._files.values():
            fh.close()
