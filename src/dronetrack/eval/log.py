"""The per-frame log of a tracking run and its summary (``metrics.json``)."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.eval.metrics import (
    CORRECT_RADIUS_M,
    acquisition_metrics,
    detection_gaps,
    first_lock,
    first_visible,
    points_by_distance,
    rmse,
    scored_tracking,
    timing,
)
from dronetrack.eval.objects import ObjectsLog
from dronetrack.eval.tracks import TracksLog
from dronetrack.geometry.transforms import FloatArray

__all__ = ["EXTRA_COLUMNS", "FRAME_COLUMNS", "TrackLog"]

# The frames.csv contract, in this order (more columns may follow).
FRAME_COLUMNS = (
    "t",
    "gt_x",
    "gt_y",
    "gt_z",
    "est_x",
    "est_y",
    "est_z",
    "tracked",
    "sigma_particles",
    "n_points",
    "n_target_points",
    "range_m",
    "pan_rad",
    "tilt_rad",
    "step_ms",
)
# Written after ``flags``: a Kalman filter's x and v_x variances, whether the
# frame's update used a measurement, how far the measurement it used lay from
# the truth (see ``TrackLog.meas_error``), and the detect stage's clusters and
# confirmed candidates (-1: acquisition off).
EXTRA_COLUMNS = (
    "pos_var",
    "vel_var",
    "measured",
    "meas_error_m",
    "n_candidates",
    "n_confirmed",
    "latency_ms",
)


# One row of the log; ``append`` writes one per frame into a block that doubles as
# it fills, so a run of n frames costs O(n) copies in all.
_ROW = np.dtype(
    [
        ("t", np.float64),
        ("gt", np.float64, (3,)),
        ("est", np.float64, (3,)),
        ("tracked", np.bool_),
        ("sigma", np.float64),
        ("n_points", np.int64),
        ("n_target_points", np.int64),  # -1: unknown
        ("range_m", np.float64),
        ("pan", np.float64),
        ("tilt", np.float64),
        ("step_ms", np.float64),
        ("flags", object),  # the frame's flags joined by ';'
        ("pos_var", np.float64),  # P(x, x) of a Kalman filter [m²]
        ("vel_var", np.float64),  # P(vx, vx) [(m/s)²]
        ("measured", np.bool_),  # the filter used a measurement
        # Distance [m] from the true position to the measurement the frame's update
        # used: a Kalman filter's z, or the foreground point nearest the truth for a
        # particle filter (which weighs every point); NaN without an update or truth.
        ("meas_error", np.float64),
        ("n_candidates", np.int64),  # clusters the detect stage found (-1: not run)
        ("n_confirmed", np.int64),  # confirmed candidates among them (-1: not run)
        ("latency_ms", np.float64),  # a live frame's last point to its command (NaN)
    ]
)
_INITIAL_ROWS = 128


class _Column:
    """A field of ``TrackLog``: a read-only view of the rows appended so far."""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, log: TrackLog, owner: type | None = None) -> NDArray[Any]:
        view = log._rows[self.name][: log._n]
        view.flags.writeable = False
        return view


class TrackLog:
    """One row per tracking frame, held as arrays.  Ground truth may be NaN.

    Each field (``t``, ``gt`` (n, 3), ``est`` (n, 3), ``tracked``, ``sigma``,
    ``n_points``, ``n_target_points``, ``range_m``, ``pan``, ``tilt``, ``step_ms``,
    ``flags``, ``pos_var``, ``vel_var``, ``measured``, ``meas_error``) reads as a
    read-only view of the rows appended so far.
    """

    __slots__ = ("_n", "_rows", "objects", "tracks")

    def __init__(self) -> None:
        self._rows = np.zeros(_INITIAL_ROWS, dtype=_ROW)
        self._n = 0
        self.tracks = TracksLog()  # every object's track, frame by frame (tracks.csv)
        self.objects = ObjectsLog()  # every object's truth, where the source knows it

    def append(
        self,
        *,
        t: float,
        gt: FloatArray,
        est: FloatArray,
        tracked: bool,
        sigma: float,
        n_points: int,
        n_target_points: int,
        range_m: float,
        pan: float,
        tilt: float,
        step_ms: float,
        flags: tuple[str, ...] = (),
        pos_var: float = float("nan"),
        vel_var: float = float("nan"),
        measured: bool = False,
        meas_error: float = float("nan"),
        n_candidates: int = -1,
        n_confirmed: int = -1,
        latency_ms: float = float("nan"),
    ) -> None:
        if self._n == len(self._rows):
            grown = np.zeros(2 * len(self._rows), dtype=_ROW)
            grown[: self._n] = self._rows
            self._rows = grown
        row = self._rows[self._n]
        row["t"] = t
        row["gt"] = np.asarray(gt, dtype=np.float64).reshape(3)
        row["est"] = np.asarray(est, dtype=np.float64).reshape(3)
        row["tracked"] = bool(tracked)
        row["sigma"] = sigma
        row["n_points"] = int(n_points)
        row["n_target_points"] = int(n_target_points)
        row["range_m"] = range_m
        row["pan"] = pan
        row["tilt"] = tilt
        row["step_ms"] = step_ms
        row["flags"] = ";".join(flags)
        row["pos_var"] = pos_var
        row["vel_var"] = vel_var
        row["measured"] = bool(measured)
        row["meas_error"] = meas_error
        row["n_candidates"] = int(n_candidates)
        row["n_confirmed"] = int(n_confirmed)
        row["latency_ms"] = latency_ms
        self._n += 1

    def __len__(self) -> int:
        return self._n

    def row(self, i: int) -> np.void:
        """Row ``i`` (negative counts from the end) as a record with the fields above."""
        if not -self._n <= i < self._n:
            raise IndexError(f"row {i} of a log of {self._n}")
        record: np.void = self._rows[i % self._n].copy()
        return record

    t = _Column()
    gt = _Column()
    est = _Column()
    tracked = _Column()
    sigma = _Column()
    n_points = _Column()
    n_target_points = _Column()
    range_m = _Column()
    pan = _Column()
    tilt = _Column()
    step_ms = _Column()
    flags = _Column()
    pos_var = _Column()
    vel_var = _Column()
    measured = _Column()
    meas_error = _Column()
    n_candidates = _Column()
    n_confirmed = _Column()
    latency_ms = _Column()

    def arrays(self) -> dict[str, NDArray[Any]]:
        """The log as arrays keyed by the frames.csv column names (read-only views)."""
        gt, est = self.gt, self.est
        return {
            "t": self.t,
            "gt_x": gt[:, 0],
            "gt_y": gt[:, 1],
            "gt_z": gt[:, 2],
            "est_x": est[:, 0],
            "est_y": est[:, 1],
            "est_z": est[:, 2],
            "tracked": self.tracked,
            "sigma_particles": self.sigma,
            "n_points": self.n_points,
            "n_target_points": self.n_target_points,
            "range_m": self.range_m,
            "pan_rad": self.pan,
            "tilt_rad": self.tilt,
            "step_ms": self.step_ms,
            "pos_var": self.pos_var,
            "vel_var": self.vel_var,
            "measured": self.measured,
            "meas_error_m": self.meas_error,
            "n_candidates": self.n_candidates,
            "n_confirmed": self.n_confirmed,
            "latency_ms": self.latency_ms,
            "flags": self.flags,
        }

    def summary(
        self,
        radius: float = CORRECT_RADIUS_M,
        min_consecutive: int = 0,
        in_field: NDArray[np.bool_] | None = None,
        reach_m: float | None = None,
    ) -> dict[str, Any]:
        """The run's metrics (metrics.json); those needing ground truth only when it exists.

        ``radius``: an estimate within this distance of the truth is correct;
        ``min_consecutive``: a run with a shorter longest stretch of correct frames scores
        0 coverage and 0 distance (see ``scored_tracking``); ``in_field`` (one per row):
        the drone is inside the field of regard (the acquisition figures count only
        those frames as visible); ``reach_m``: the sensor's reach for the drone, from
        which ``acquire_in_reach_s`` counts.  ``dronetrack compare``'s table reads the same
        definitions (``experiments/compare/runner.py``).
        """
        a = self.arrays()
        out: dict[str, Any] = {"frames": len(self)}
        steps = timing(a["step_ms"])
        out.update({f"step_ms_{k}": v for k, v in steps.items()})
        latency = a["latency_ms"][np.isfinite(a["latency_ms"])]
        if len(latency):  # a live run: the frame's last point to its turret command
            out["latency_ms_p50"] = float(np.percentile(latency, 50))
            out["latency_ms_p99"] = float(np.percentile(latency, 99))
        tracked = a["tracked"]
        out["tracked_pct"] = 100.0 * float(tracked.mean()) if len(self) else 0.0
        out["first_lock_s"] = float(a["t"][np.argmax(tracked)]) if tracked.any() else None
        out["bad_frames"] = _flag_counts(a["flags"])
        gt = np.column_stack([a["gt_x"], a["gt_y"], a["gt_z"]])
        if len(self) == 0 or not np.any(np.all(np.isfinite(gt), axis=1)):
            return out
        est = np.column_stack([a["est_x"], a["est_y"], a["est_z"]])
        err = est - gt
        out["correct_radius_m"] = radius
        out["coverage_pct"], out["max_tracking_distance_m"] = scored_tracking(
            err, a["range_m"], radius, a["meas_error_m"], min_consecutive
        )
        # rmse_m (eq. 13): over the frames from the first lock on (tracked or not), as the
        # reference windows its accuracy runs after the filter has locked.
        r = rmse(err[first_lock(tracked) :])
        out.update(
            {
                "rmse_m": r.value,
                "rmse_ci95_m": list(r.ci95),
                "rmse_xyz_m": list(r.per_axis),
                "rmse_frames": r.n,
            }
        )
        r_tracked = rmse(err[tracked])
        out["rmse_tracked_m"] = r_tracked.value
        out.update(
            acquisition_metrics(
                a["t"],
                err,
                tracked,
                a["n_target_points"],
                radius,
                in_field,
                a["range_m"],
                reach_m,
            )
        )
        # Frames whose foreground reached the tracker (seed 003's detections).
        out["n_detections"] = int(np.count_nonzero(a["n_points"] > 0))
        counts = a["n_target_points"]
        if np.all(counts >= 0):
            # rmse_from_visible_m: from the first frame whose foreground holds returns
            # from the drone (seed 000's Table IV windows)
            visible = rmse(err[first_visible(a["n_points"], counts) :])
            out["rmse_from_visible_m"] = visible.value
            detected = counts > 0
            gaps = detection_gaps(a["t"], detected)
            out["target_points_total"] = int(counts.sum())
            # The reference's "max return distance": the furthest frame with returns.
            out["max_return_distance_m"] = (
                float(a["range_m"][detected].max()) if detected.any() else None
            )
            out["detections"] = int(detected.sum())
            out["detection_gap_s"] = {
                "min": float(gaps.min()) if len(gaps) else None,
                "max": float(gaps.max()) if len(gaps) else None,
                "mean": float(gaps.mean()) if len(gaps) else None,
            }
            out["points_by_distance"] = points_by_distance(a["range_m"], counts)
        return out


def _flag_counts(flags: NDArray[Any]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for row in flags:
        for flag in filter(None, row.split(";")):
            counts[flag] = counts.get(flag, 0) + 1
    return counts
