"""Seed 003's CSV logs of a run, one folder per run:

- ``filtered_points.csv``: ``t,x,y,z,seq``, the points that passed the filters
  (world frame) and the frame's sequence number;
- ``centroids.csv``: ``t,x,y,z``, the centroid each frame's EKF update used;
- ``states.csv``: ``t,from_state,to_state,strategy``, the scan controller's
  state transitions;
- ``ekf.csv``: ``t,x,y,z,vx,vy,vz,P11,P22,P33,P44,P55,P66``, the filter state and
  the diagonal of its covariance after every frame.
"""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any, TextIO

import numpy as np

from dronetrack.types import Sample, StepResult

__all__ = ["StrategyLogger"]

_HEADERS = {
    "filtered_points.csv": ("t", "x", "y", "z", "seq"),
    "centroids.csv": ("t", "x", "y", "z"),
    "states.csv": ("t", "from_state", "to_state", "strategy"),
    "ekf.csv": ("t", "x", "y", "z", "vx", "vy", "vz", *(f"P{i}{i}" for i in range(1, 7))),
}


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
