"""The per-frame log of a tracking run and its summary (``metrics.json``)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.eval.metrics import (
    CORRECT_RADIUS_M,
    detection_gaps,
    first_lock,
    first_visible,
    points_by_distance,
    rmse,
    scored_tracking,
    timing,
)
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
# frame's update used a measurement, and how far the measurement it used lay from
# the truth (see ``TrackLog.meas_error``).
EXTRA_COLUMNS = ("pos_var", "vel_var", "measured", "meas_error_m")


@dataclass(slots=True)
class TrackLog:
    """One row per tracking frame.  Ground truth may be NaN (recordings without it)."""

    t: list[float] = field(default_factory=list)
    gt: list[FloatArray] = field(default_factory=list)
    est: list[FloatArray] = field(default_factory=list)
    tracked: list[bool] = field(default_factory=list)
    sigma: list[float] = field(default_factory=list)
    n_points: list[int] = field(default_factory=list)
    n_target_points: list[int] = field(default_factory=list)  # -1: unknown
    range_m: list[float] = field(default_factory=list)
    pan: list[float] = field(default_factory=list)
    tilt: list[float] = field(default_factory=list)
    step_ms: list[float] = field(default_factory=list)
    flags: list[str] = field(default_factory=list)
    pos_var: list[float] = field(default_factory=list)  # P(x, x) of a Kalman filter [m²]
    vel_var: list[float] = field(default_factory=list)  # P(vx, vx) [(m/s)²]
    measured: list[bool] = field(default_factory=list)  # the filter used a measurement
    # Distance [m] from the true position to the measurement the frame's update used:
    # a Kalman filter's z, or the foreground point nearest the truth for a particle
    # filter (which weighs every point); NaN without an update or without truth.
    meas_error: list[float] = field(default_factory=list)

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
    ) -> None:
        self.t.append(t)
        self.gt.append(np.asarray(gt, dtype=np.float64))
        self.est.append(np.asarray(est, dtype=np.float64))
        self.tracked.append(bool(tracked))
        self.sigma.append(float(sigma))
        self.n_points.append(int(n_points))
        self.n_target_points.append(int(n_target_points))
        self.range_m.append(float(range_m))
        self.pan.append(float(pan))
        self.tilt.append(float(tilt))
        self.step_ms.append(float(step_ms))
        self.flags.append(";".join(flags))
        self.pos_var.append(float(pos_var))
        self.vel_var.append(float(vel_var))
        self.measured.append(bool(measured))
        self.meas_error.append(float(meas_error))

    def __len__(self) -> int:
        return len(self.t)

    def arrays(self) -> dict[str, NDArray[Any]]:
        """The log as arrays keyed by the frames.csv column names."""
        n = len(self)
        gt = np.array(self.gt).reshape(n, 3)
        est = np.array(self.est).reshape(n, 3)
        return {
            "t": np.array(self.t, dtype=np.float64),
            "gt_x": gt[:, 0],
            "gt_y": gt[:, 1],
            "gt_z": gt[:, 2],
            "est_x": est[:, 0],
            "est_y": est[:, 1],
            "est_z": est[:, 2],
            "tracked": np.array(self.tracked, dtype=bool),
            "sigma_particles": np.array(self.sigma, dtype=np.float64),
            "n_points": np.array(self.n_points, dtype=np.int64),
            "n_target_points": np.array(self.n_target_points, dtype=np.int64),
            "range_m": np.array(self.range_m, dtype=np.float64),
            "pan_rad": np.array(self.pan, dtype=np.float64),
            "tilt_rad": np.array(self.tilt, dtype=np.float64),
            "step_ms": np.array(self.step_ms, dtype=np.float64),
            "pos_var": np.array(self.pos_var, dtype=np.float64),
            "vel_var": np.array(self.vel_var, dtype=np.float64),
            "measured": np.array(self.measured, dtype=bool),
            "meas_error_m": np.array(self.meas_error, dtype=np.float64),
            "flags": np.array(self.flags, dtype=object),
        }

    def summary(self, radius: float = CORRECT_RADIUS_M, min_consecutive: int = 0) -> dict[str, Any]:
        """The run's metrics (metrics.json); those needing ground truth only when it exists.

        ``radius``: an estimate within this distance of the truth is correct;
        ``min_consecutive``: a run with a shorter longest stretch of correct frames scores
        0 coverage and 0 distance (see ``scored_tracking``).  ``dronetrack compare``'s
        table reads the same definitions (``experiments/compare/runner.py``).
        """
        a = self.arrays()
        out: dict[str, Any] = {"frames": len(self)}
        steps = timing(a["step_ms"])
        out.update({f"step_ms_{k}": v for k, v in steps.items()})
        tracked = a["tracked"]
        out["tracked_pct"] = 100.0 * float(tracked.mean()) if len(self) else 0.0
        out["first_lock_s"] = float(a["t"][np.argmax(tracked)]) if tracked.any() else None
        out["bad_frames"] = _flag_counts(self.flags)
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


def _flag_counts(flags: list[str]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for row in flags:
        for flag in filter(None, row.split(";")):
            counts[flag] = counts.get(flag, 0) + 1
    return counts
