"""The data passed between the stages: LiDAR frames, detections, track estimates and
turret commands.

Times are float64 seconds from the start of a run; lengths are metres; angles
are radians.
"""

from __future__ import annotations

from dronetrack.types.detections import Candidates, Detections
from dronetrack.types.frames import Frame
from dronetrack.types.steps import Phase, Sample, StepResult
from dronetrack.types.tracks import TRACK_CLASSES, TrackEstimate, Tracks
from dronetrack.types.truth import OBJECT_KINDS, ObjectKind, ObjectTruth, Truth, truth_objects
from dronetrack.types.turret import TurretCommand, TurretState

__all__ = [
    "OBJECT_KINDS",
    "TRACK_CLASSES",
    "Candidates",
    "Detections",
    "Frame",
    "ObjectKind",
    "ObjectTruth",
    "Phase",
    "Sample",
    "StepResult",
    "TrackEstimate",
    "Tracks",
    "Truth",
    "TurretCommand",
    "TurretState",
    "truth_objects",
]
