"""The options of ``track`` (replay): the recording, its topics and frames, where the
sensor stood and where the truth is, and how they are read (``replay_options``)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import numpy as np
import typer

from dronetrack.errors import ConfigError

if TYPE_CHECKING:
    from dronetrack.sources.recordings.recording import ReplayOptions

__all__ = [
    "BackgroundFromOption",
    "BackgroundOption",
    "GtHeadingOption",
    "GtOriginOption",
    "GtTopicOption",
    "LidarTopicOption",
    "PeriodOption",
    "PoseFrameOption",
    "RecordingArgument",
    "RecordingConfigOption",
    "SensorPoseOption",
    "TimestampsOption",
    "TruthOption",
    "replay_options",
]


def _floats(text: str | None, n: int, option: str) -> tuple[float, ...] | None:
    """``n`` comma-separated numbers, or None."""
    if text is None:
        return None
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != n or not all(np.isfinite(values)):
        raise ConfigError(f"{option} takes {n} comma-separated numbers, got {text!r}")
    return values


def _sensor_pose(text: str | None) -> np.ndarray | None:
    """world_T_sensor from "x,y,z,roll,pitch,yaw" (metres, degrees; R = Rz Ry Rx)."""
    from dronetrack.geometry.transforms import make_pose, rot_x, rot_y, rot_z

    values = _floats(text, 6, "--sensor-pose")
    if values is None:
        return None
    x, y, z, roll, pitch, yaw = values
    R = rot_z(np.radians(yaw)) @ rot_y(np.radians(pitch)) @ rot_x(np.radians(roll))
    pose: np.ndarray = make_pose(R, (x, y, z))
    return pose


def replay_options(
    lidar_topic: str | None,
    gt_topic: str | None,
    pose_frame: str | None,
    sensor_pose: str | None,
    gt_origin: str | None,
    gt_heading: float,
    period: float | None,
    timestamps: Path | None,
) -> ReplayOptions:
    """How ``track`` reads its recording, from the command line's text."""
    from dronetrack.sources.recordings.recording import ReplayOptions

    origin = _floats(gt_origin, 3, "--gt-origin")
    return ReplayOptions(
        lidar_topic=lidar_topic,
        gt_topic=gt_topic,
        pose_frame=pose_frame,
        sensor_pose=_sensor_pose(sensor_pose),
        gt_origin=(origin[0], origin[1], origin[2]) if origin else None,
        gt_heading_deg=gt_heading,
        period_s=period,
        timestamps=timestamps,
    )


RecordingArgument = Annotated[
    Path,
    typer.Argument(
        help="A ROS 1 bag, a ROS 2 bag folder, an MCAP or .db3 file, a PCD file or a folder "
        "of them, a LAS/LAZ file, a Livox Viewer .lvx or .lvx2 file, or a folder of seed "
        "003's CSV logs; files are recognised by their content, whatever their name."
    ),
]
LidarTopicOption = Annotated[
    str | None,
    typer.Option("--lidar-topic", help="Point topic or LVX LiDAR.", show_default="the only one"),
]
GtTopicOption = Annotated[
    str | None,
    typer.Option(
        "--gt-topic", help="NavSatFix or PoseStamped ground truth.", show_default="the only one"
    ),
]
PoseFrameOption = Annotated[
    str | None,
    typer.Option("--pose-frame", help="The /tf frame to track in.", show_default="the tree's root"),
]
BackgroundOption = Annotated[
    Path | None, typer.Option("--background", help="Load this background model (.npz).")
]
BackgroundFromOption = Annotated[
    float | None,
    typer.Option(
        "--background-from", min=0.0, help="Build the background from the first S seconds."
    ),
]
RecordingConfigOption = Annotated[
    Path | None,
    typer.Option(
        "--config", help="A scenario/config .toml.", show_default="the recording's own, if any"
    ),
]
SensorPoseOption = Annotated[
    str | None,
    typer.Option(
        "--sensor-pose", help="Fixed sensor pose x,y,z,roll,pitch,yaw (m, deg) without /tf."
    ),
]
GtOriginOption = Annotated[
    str | None,
    typer.Option("--gt-origin", help="NavSatFix ENU origin lat,lon,alt (deg, deg, m)."),
]
GtHeadingOption = Annotated[
    float, typer.Option("--gt-heading", help="Yaw of the world x axis from east (deg).")
]
PeriodOption = Annotated[
    float | None,
    typer.Option(
        "--period",
        min=1e-4,
        help="Frame period in s; a bag's points are re-cut by their times to it.",
        show_default="from the stamps",
    ),
]
TimestampsOption = Annotated[
    Path | None, typer.Option("--timestamps", help="A .pcd folder's timestamps file.")
]
TruthOption = Annotated[
    Path | None,
    typer.Option(
        "--truth",
        help="Ground truth from a CSV with columns t,x,y,z (t in s from the recording's "
        "start, x, y, z in m in the world frame), instead of the recording's own.",
    ),
]
