"""The run's log as a sink: every tracking frame's truth, estimate and turret, one row each.

``TrackLogSink`` appends to an ``eval.log.TrackLog`` (what the metrics and plots
read) and tells ``on_row`` after each row, so a run folder can stream
``frames.csv`` as the run goes.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from dronetrack.eval.log import TrackLog
from dronetrack.geometry.mount import pointing_angles
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Sample, StepResult, truth_objects

__all__ = ["TrackLogSink", "log_result", "measurement_error"]


class TrackLogSink:
    """Logs every tracking frame (the background scan's frames are not scored)."""

    def __init__(
        self, log: TrackLog | None = None, on_row: Callable[[TrackLog], None] | None = None
    ) -> None:
        self.log = TrackLog() if log is None else log
        self.on_row = on_row

    def write(self, sample: Sample, result: StepResult) -> None:
        if result.phase != "track":
            return
        log_result(self.log, sample, result)
        if self.on_row is not None:
            self.on_row(self.log)


def measurement_error(result: StepResult, gt: FloatArray) -> float:
    """How far the measurement this frame's update used lay from the truth ``gt`` [m]:
    a Kalman filter's z; for a particle filter, which weighs every foreground point, the
    point nearest the truth; NaN when the frame had no update."""
    est = result.estimate
    assert est is not None
    if est.measurement is not None:  # a Kalman filter's z
        return float(np.linalg.norm(est.measurement - gt))
    if est.particles is not None and result.periods > 0 and len(result.foreground):
        return float(np.min(np.linalg.norm(result.foreground - gt, axis=1)))
    return math.nan


def log_result(log: TrackLog, sample: Sample, result: StepResult) -> None:
    """Append a tracking frame's result to ``log``: the truth where the source knows it
    (NaN and -1 returns where not), the turret's measured angles, or without them the
    angles the sensor pose at the frame's end implies."""
    est = result.estimate
    assert est is not None
    frame, truth = sample.frame, sample.truth
    sensor = frame.poses[-1, :3, 3]
    gt = np.full(3, np.nan) if truth is None else truth.target_position
    n_target = -1 if truth is None else truth.target_returns(frame, result.world)
    if sample.turret is not None:
        pan, tilt = sample.turret.pan, sample.turret.tilt
    else:
        p, t = pointing_angles(frame.poses[-1])
        pan, tilt = float(p), float(t)
    if result.tracks is not None:
        log.tracks.append(frame.end, result.tracks)
    objects = truth_objects(truth)
    if objects is not None:
        log.objects.append(frame.end, objects, sensor)
    var = est.variance
    log.append(
        t=frame.end,
        gt=gt,
        est=est.position,
        tracked=est.tracked,
        sigma=est.spread,
        n_points=result.n_points,
        n_target_points=n_target,
        range_m=float(np.linalg.norm(gt - sensor)),
        pan=pan,
        tilt=tilt,
        step_ms=result.step_ms,
        flags=result.flags,
        pos_var=float(var[0]) if var is not None else math.nan,
        vel_var=float(var[3]) if var is not None else math.nan,
        measured=est.measurement is not None,
        meas_error=measurement_error(result, gt),
        n_candidates=-1 if result.detections is None else len(result.detections),
        n_confirmed=-1 if result.candidates is None else len(result.candidates),
        latency_ms=result.latency_ms,
    )
