"""Seed 003's CSV logs of a run: one folder per run, one file per log.

The one definition of the files and their columns, for the writer
(``sinks/strategy_logs.py``) and the reader (``sources/recordings/field_logs.py``):

- ``filtered_points.csv``: ``t,x,y,z,seq``, the points that passed the filters
  (world frame [m]) and the frame's sequence number;
- ``centroids.csv``: ``t,x,y,z``, the centroid each frame's EKF update used;
- ``states.csv``: ``t,from_state,to_state,strategy``, the scan controller's
  state transitions;
- ``ekf.csv``: ``t,x,y,z,vx,vy,vz,P11,P22,P33,P44,P55,P66``, the filter state and
  the diagonal of its covariance after every frame.
"""

from __future__ import annotations

__all__ = ["CENTROIDS_FILE", "EKF_FILE", "LOG_COLUMNS", "POINTS_FILE", "STATES_FILE"]

POINTS_FILE = "filtered_points.csv"
CENTROIDS_FILE = "centroids.csv"
STATES_FILE = "states.csv"
EKF_FILE = "ekf.csv"
LOG_COLUMNS: dict[str, tuple[str, ...]] = {
    POINTS_FILE: ("t", "x", "y", "z", "seq"),
    CENTROIDS_FILE: ("t", "x", "y", "z"),
    STATES_FILE: ("t", "from_state", "to_state", "strategy"),
    EKF_FILE: ("t", "x", "y", "z", "vx", "vy", "vz", *(f"P{i}{i}" for i in range(1, 7))),
}
