"""What every recording reader gives the replay: frames, ground truth and a summary.

A reader turns a recording (a ROS bag, an MCAP file, a folder of ``.pcd`` files,
a ``.las``/``.laz`` file, seed 003's CSV logs) into the pipeline's ``Frame``
objects.  Times inside are seconds relative to the recording's ``origin`` (an
absolute time, e.g. Unix seconds), so float64 keeps microseconds.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np

from dronetrack.errors import InputError
from dronetrack.geometry.geodesy import SiteFrame
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sources.truth import TIME_TOL_S, GroundTruth
from dronetrack.types import Frame

__all__ = [
    "PointFileRecording",
    "Recording",
    "RecordingInfo",
    "ReplayOptions",
    "TopicInfo",
    "frame_period",
    "identity_pose_warning",
    "sensor_pose",
    "truth_overlap_warning",
]


DEFAULT_PERIOD_S = 0.1  # a frame period when nothing else gives one [s]
# What truth times that miss the recording may be in: (name, seconds per unit,
# counted from the recording's start or absolute), tried in this order.
TIME_UNITS: tuple[tuple[str, float, bool], ...] = (
    ("absolute seconds", 1.0, False),
    ("milliseconds from the start", 1e-3, True),
    ("absolute milliseconds", 1e-3, False),
    ("absolute microseconds", 1e-6, False),
    ("absolute nanoseconds", 1e-9, False),
)


@dataclass(frozen=True, slots=True)
class TopicInfo:
    """One topic (or stream) of a recording."""

    topic: str
    msgtype: str
    count: int


@dataclass(frozen=True, slots=True)
class RecordingInfo:
    """What ``dronetrack info`` prints."""

    path: Path
    kind: str  # "ros1", "ros2-sqlite3", "ros2-mcap", "mcap", "pcd", "las", "field-logs"
    start: float  # absolute time of the first message [s] (Unix seconds for bags)
    duration_s: float
    topics: tuple[TopicInfo, ...]


@dataclass(frozen=True, slots=True)
class ReplayOptions:
    """How to read a recording; None means "choose automatically" or "not given"."""

    lidar_topic: str | None = None
    gt_topic: str | None = None
    pose_frame: str | None = None  # the fixed frame of the /tf tree to track in
    sensor_pose: FloatArray | None = None  # (4, 4) world_T_sensor when there is no /tf
    gt_origin: tuple[float, float, float] | None = None  # NavSatFix ENU origin (lat°, lon°, alt m)
    gt_heading_deg: float = 0.0  # ENU rotated about z by this, to align with the world frame
    # A site's world frame on the Earth ([site]): NavSatFix truth in it, when no
    # gt_origin is given
    gt_site: SiteFrame | None = None
    period_s: float | None = None  # frame period when the recording does not say
    timestamps: Path | None = None  # a .pcd folder's timestamps file


class Recording(Protocol):
    """A recording opened for replay.

    ``frames`` yields frames in time order with points in the sensor frame and
    world_T_sensor poses; a message that cannot be decoded is skipped, logged
    and counted in ``skipped`` (by reason), never silently dropped.
    """

    path: Path
    origin: float  # absolute time [s] of t = 0
    period: float  # frame period [s]
    ground_truth: GroundTruth | None
    config_text: str | None  # a dronetrack scenario (TOML) the recording carries, if any
    skipped: Counter[str]
    # What replay must say of the sensor's pose: none was found and the sensor is taken
    # as fixed at the origin, or a bag's /tf gives it and --sensor-pose is ignored.
    pose_warning: str | None

    def frames(self) -> Iterator[Frame]:
        """The LiDAR frames, in time order."""
        ...

    def info(self) -> RecordingInfo:
        """Topics, types, counts and duration."""
        ...


class PointFileRecording:
    """What the readers of point files (PCD, LAS, CSV logs) share: they carry no ground
    truth and no configuration, and count what they skip."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self.ground_truth: GroundTruth | None = None
        self.config_text: str | None = None
        self.skipped: Counter[str] = Counter()
        self.pose_warning: str | None = None


def identity_pose_warning(path: Path, frame_id: str | None = None) -> str:
    """What replay says when nothing gives the sensor's pose: it assumes the identity."""
    where = f"no /tf for its LiDAR frame {frame_id!r}" if frame_id else "no sensor pose"
    return (
        f"{path.name} has {where}, and no --sensor-pose was given: the sensor is taken as "
        "fixed at the world origin, looking along x (the identity pose); give "
        "--sensor-pose x,y,z,roll,pitch,yaw (m, deg) if it was elsewhere"
    )


def sensor_pose(options: ReplayOptions) -> FloatArray | None:
    """options.sensor_pose checked to be (4, 4) world_T_sensor, or None (identity)."""
    if options.sensor_pose is None:
        return None
    pose = np.asarray(options.sensor_pose, dtype=np.float64)
    if pose.shape != (4, 4):
        raise InputError(f"sensor_pose must be (4, 4), got {pose.shape}")
    return pose


def frame_period(options: ReplayOptions, t: FloatArray | None) -> float:
    """options.period_s, else the median of the positive steps of the frame times ``t``
    (repeated or out-of-order stamps say nothing of the rate), else ``DEFAULT_PERIOD_S``."""
    if options.period_s is not None:
        if not options.period_s > 0:
            raise InputError(f"period_s must be > 0, got {options.period_s}")
        return float(options.period_s)
    if t is not None and len(t) > 1:
        steps = np.diff(np.asarray(t, dtype=np.float64))
        steps = steps[steps > 0]
        if len(steps):
            return float(np.median(steps))
    return DEFAULT_PERIOD_S


def _span(start: float, end: float, origin: float) -> str:
    """``start`` to ``end`` [s from the recording's start], and as stamped if that differs."""
    text = f"{start:.3f} to {end:.3f} s from its start"
    if origin != 0:
        text += f" ({origin + start:.3f} to {origin + end:.3f} s as stamped)"
    return text


def _unit_hint(t: FloatArray, start: float, end: float, origin: float) -> str:
    """What the truth times ``t`` look like when, read in another unit or from another
    zero (``TIME_UNITS``), they would fit the frames' span [start, end]: at least half
    of them inside it, over at least a tenth of its length; else ""."""
    first, last = float(t[0]), float(t[-1])
    for name, unit, relative in TIME_UNITS:
        if not relative and origin == 0:
            continue
        shift = 0.0 if relative else origin
        lo, hi = first * unit - shift, last * unit - shift
        inside = min(hi, end) - max(lo, start)
        if hi - lo >= 0.1 * (end - start) and inside >= 0.5 * (hi - lo):
            steps = [f"divide by {1 / unit:g}"] if unit != 1.0 else []
            steps += [] if relative else [f"subtract the start, {origin:.3f} s"]
            return f"; they look like {name} ({' and '.join(steps)})"
    return ""


def truth_overlap_warning(
    truth: GroundTruth, start: float, end: float, origin: float, truth_file: Path | None = None
) -> str | None:
    """The warning when no truth sample falls inside the frames' span [start, end] (s
    from the recording's start, whose time is ``origin``), so no frame can be scored;
    None when some does.  ``truth_file``: the CSV the truth came from (its t as given),
    None for the recording's own."""
    first, last = float(truth.t[0]), float(truth.t[-1])
    if last >= start - TIME_TOL_S and first <= end + TIME_TOL_S:
        return None
    head = (
        "no truth sample falls inside the recording's time span, so no frame is scored: "
        f"the recording spans {_span(start, end, origin)}"
    )
    if truth_file is None:
        return f"{head}; its ground truth spans {_span(first, last, origin)}"
    return (
        f"{head}; {truth_file.name}'s t spans {first:.3f} to {last:.3f} s as given, and "
        "--truth takes t in seconds from the recording's start"
        + _unit_hint(truth.t, start, end, origin)
    )
