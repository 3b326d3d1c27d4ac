"""One frame as a source delivers it, and what the pipeline made of it."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from dronetrack.geometry.transforms import FloatArray
from dronetrack.types.detections import Candidates, Detections
from dronetrack.types.frames import Frame
from dronetrack.types.tracks import TrackEstimate, Tracks
from dronetrack.types.truth import Truth
from dronetrack.types.turret import TurretCommand, TurretState

__all__ = ["Phase", "Sample", "StepResult"]


Phase = Literal["scan", "track"]


@dataclass(frozen=True, slots=True)
class Sample:
    """One frame as a source delivers it, with what the source knows besides the points.

    turret: the turret's measured joint state at the frame's end, if the source knows it
        (a recording knows only the sensor pose, which is in the frame).
    received: a live source's ``time.perf_counter()`` when the frame's last point
        arrived, from which the run loop measures the latency to the turret command.
    """

    frame: Frame
    truth: Truth | None = None
    turret: TurretState | None = None
    received: float | None = None


@dataclass(frozen=True, slots=True)
class StepResult:
    """What the pipeline made of one frame."""

    t: float  # frame end [s]
    phase: Phase
    estimate: TrackEstimate | None  # None while scanning
    n_points: int  # points left after background subtraction and outlier removal
    n_returns: int  # points in the frame
    command: TurretCommand | None
    step_ms: float  # wall time spent in step()
    flags: tuple[str, ...] = ()
    foreground: FloatArray = field(default_factory=lambda: np.empty((0, 3)))
    periods: int = 0  # filter periods this frame advanced (0: repeated or older)
    # (N, 3) every point of the frame in the world frame; empty if it could not be placed
    world: FloatArray = field(default_factory=lambda: np.empty((0, 3)))
    # The detect stage's clusters in the foreground, and the confirmed candidates
    # among its tentative tracks (None when acquisition is off, and while scanning)
    detections: Detections | None = None
    candidates: Candidates | None = None
    # A live frame's time from its last point's arrival to its turret command being
    # sent [ms] (``pipeline.run``); NaN for sources that are not live.
    latency_ms: float = math.nan
    # Every object's track (``track.multi``; None when acquisition is off, and while
    # scanning)
    tracks: Tracks | None = None
