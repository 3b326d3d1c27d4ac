"""The SAPIENT messages of a LiDAR edge node (and a fusion node's acknowledgements),
built from plain values.

Units follow ``fields``: WGS-84 locations in degrees and metres with their 1σ errors
in the same units, range-bearings in degrees and metres from true north, velocities
east, north and up [m/s], confidences in 0-1.  The Registration is built in
``registration``, the look-at Task and its reading in ``tasks``; their names are here
too, so that ``messages`` is the one module to import.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from dronetrack.formats.sapient.fields import (
    DEG_M,
    TRUE_NORTH,
    RangeBearing,
    envelope,
    metres_to_degrees,
    new_ulid,
    timestamp,
    wgs84_location,
)
from dronetrack.formats.sapient.registration import registration
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0 import (
    alert_ack_pb2,
    alert_pb2,
    status_report_pb2,
    task_ack_pb2,
)
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)
from dronetrack.formats.sapient.tasks import LookAt, LookAtPoint, look_at, look_at_task

__all__ = [
    "LookAt",
    "LookAtPoint",
    "RangeBearing",
    "alert",
    "alert_ack",
    "detection_report",
    "envelope",
    "look_at",
    "look_at_task",
    "metres_to_degrees",
    "new_ulid",
    "registration",
    "registration_ack",
    "status_report",
    "task_ack",
    "timestamp",
    "wgs84_location",
]


def registration_ack(
    node_id: str, t_unix_s: float, accepted: bool, reason: str | None = None
) -> SapientMessage:
    """A fusion node's answer to a Registration."""
    msg = envelope(node_id, t_unix_s)
    msg.registration_ack.acceptance = accepted
    if reason:
        msg.registration_ack.ack_response_reason.append(reason)
    return msg


def status_report(
    node_id: str,
    t_unix_s: float,
    *,
    report_id: str,
    location: tuple[float, float, float],
    pointing: RangeBearing | None,
    field_of_view_deg: tuple[float, float],
    mode: str = "default",
    ok: bool = True,
    new: bool = True,
    active_task: str | None = None,
    notes: Sequence[tuple[str, str]] = (),
) -> SapientMessage:
    """A StatusReport: where the node is (lat°, lon°, alt m), where its sensor looks
    (a range-bearing cone ``field_of_view_deg`` wide about ``pointing``), its mode,
    its state (``ok``: SYSTEM_OK, else SYSTEM_WARNING; ``new``: INFO_NEW, else
    INFO_UNCHANGED), the task it is doing, and any ``notes`` as information statuses:
    (type, value), the type a StatusType without its prefix (``ptz_status``,
    ``not_detecting``, ``other`` ...; ``ValueError`` for another)."""
    msg = envelope(node_id, t_unix_s)
    status = msg.status_report
    status.report_id = report_id
    status.system = (
        status_report_pb2.StatusReport.SYSTEM_OK
        if ok
        else status_report_pb2.StatusReport.SYSTEM_WARNING
    )
    status.info = (
        status_report_pb2.StatusReport.INFO_NEW
        if new
        else status_report_pb2.StatusReport.INFO_UNCHANGED
    )
    status.mode = mode
    if active_task is not None:
        status.active_task_id = active_task
    status.node_location.CopyFrom(wgs84_location(*location))
    if pointing is not None:
        cone = status.field_of_view.range_bearing
        cone.azimuth, cone.elevation, cone.range = (
            pointing.azimuth,
            pointing.elevation,
            pointing.range,
        )
        cone.horizontal_extent, cone.vertical_extent = field_of_view_deg
        cone.coordinate_system, cone.datum = DEG_M, TRUE_NORTH
    for kind, value in notes:
        status.status.add(
            status_level=status_report_pb2.StatusReport.STATUS_LEVEL_INFORMATION_STATUS,
            status_type=status_report_pb2.StatusReport.StatusType.Value(
                f"STATUS_TYPE_{kind.upper()}"
            ),
            status_value=value,
        )
    return msg


def detection_report(
    node_id: str,
    t_unix_s: float,
    *,
    report_id: str,
    object_id: str,
    location: tuple[float, float, float],
    sigma_enu_m: ArrayLike,
    range_bearing: RangeBearing,
    velocity_enu: ArrayLike,
    velocity_sigma_enu: ArrayLike,
    classification: Sequence[tuple[str, float]],
    track_id: int,
    frame_t: float | None = None,
    confidence: float | None = None,
    state: str | None = None,
    task_id: str | None = None,
    track_info: Sequence[tuple[str, str, float | None]] = (),
) -> SapientMessage:
    """A DetectionReport of one track: its WGS-84 ``location`` with 1σ east, north and
    up errors [m] (carried as degrees of longitude and latitude, and metres), its range
    and bearing from the node with their 1σ errors and the track's own ID, its ENU
    velocity [m/s] with 1σ errors, and its ``classification``: (type, confidence 0-1)
    pairs, the most likely first (``registration`` promises that one only).

    The report's location oneof holds either a location or a range-bearing, and a C2
    system places a track by its location; so the range-bearing goes in ``track_info``
    as ``range_m``, ``azimuth_deg`` (from true north) and ``elevation_deg``, each with
    its error, with ``track_id``, and ``frame_t_s`` (``frame_t``: the time of the
    frame the report comes from on the run's clock [s], which ties it to tracks.csv's
    row).  ``track_info``: more (type, value, error or None) entries after them.
    ``confidence``: the detection's confidence (0-1); ``state``: e.g. ``lost`` at a
    track's end; ``task_id``: the task the node is doing."""
    msg = envelope(node_id, t_unix_s)
    report = msg.detection_report
    report.report_id, report.object_id = report_id, object_id
    if task_id is not None:
        report.task_id = task_id
    if state is not None:
        report.state = state
    report.location.CopyFrom(wgs84_location(*location, sigma_enu=sigma_enu_m))
    if confidence is not None:
        report.detection_confidence = confidence
    rb = range_bearing
    entries: list[tuple[str, str, float | None]] = [
        ("range_m", f"{rb.range:.3f}", rb.range_error),
        ("azimuth_deg", f"{rb.azimuth:.3f}", rb.azimuth_error),
        ("elevation_deg", f"{rb.elevation:.3f}", rb.elevation_error),
        ("track_id", str(track_id), None),
    ]
    if frame_t is not None:
        entries.append(("frame_t_s", f"{frame_t:.6f}", None))
    for kind, text, error in (*entries, *track_info):
        info = report.track_info.add(type=kind, value=text)
        if error is not None and math.isfinite(error):
            info.error = error
    v = np.asarray(velocity_enu, dtype=np.float64)
    s = np.asarray(velocity_sigma_enu, dtype=np.float64)
    vel = report.enu_velocity
    vel.east_rate, vel.north_rate, vel.up_rate = float(v[0]), float(v[1]), float(v[2])
    vel.east_rate_error, vel.north_rate_error, vel.up_rate_error = (float(e) for e in s[:3])
    for cls, p in classification:
        report.classification.add(type=cls, confidence=p)
    return msg


def alert(
    node_id: str,
    t_unix_s: float,
    *,
    alert_id: str,
    active: bool,
    critical: bool,
    description: str,
    location: tuple[float, float, float],
    object_id: str | None,
    region_id: str | None = None,
) -> SapientMessage:
    """An Alert (``active``) or its clear, at ``location``, of the detection
    ``object_id``: CRITICAL and of high priority inside a zone, else a WARNING."""
    msg = envelope(node_id, t_unix_s)
    out = msg.alert
    out.alert_id = alert_id
    out.alert_type = (
        alert_pb2.Alert.ALERT_TYPE_CRITICAL if critical else alert_pb2.Alert.ALERT_TYPE_WARNING
    )
    out.status = (
        alert_pb2.Alert.ALERT_STATUS_ACTIVE if active else alert_pb2.Alert.ALERT_STATUS_CLEAR
    )
    out.description = description
    out.location.CopyFrom(wgs84_location(*location))
    out.priority = (
        alert_pb2.Alert.DISCRETE_PRIORITY_HIGH
        if critical
        else alert_pb2.Alert.DISCRETE_PRIORITY_MEDIUM
    )
    if region_id is not None:
        out.region_id = region_id
    if object_id is not None:
        detection = out.associated_detection.add(node_id=node_id, object_id=object_id)
        detection.timestamp.CopyFrom(timestamp(t_unix_s))
    return msg


def task_ack(
    node_id: str, t_unix_s: float, task_id: str, accepted: bool, reasons: Sequence[str] = ()
) -> SapientMessage:
    """A TaskAck: the task accepted, or rejected with its reasons."""
    msg = envelope(node_id, t_unix_s)
    ack = msg.task_ack
    ack.task_id = task_id
    ack.task_status = (
        task_ack_pb2.TaskAck.TASK_STATUS_ACCEPTED
        if accepted
        else task_ack_pb2.TaskAck.TASK_STATUS_REJECTED
    )
    ack.reason.extend(reasons)
    return msg


def alert_ack(
    node_id: str,
    t_unix_s: float,
    alert_id: str,
    accepted: bool,
    reasons: Sequence[str] = (),
    destination: str | None = None,
) -> SapientMessage:
    """A fusion node's AlertAck: the alert accepted, or rejected with its reasons."""
    msg = envelope(node_id, t_unix_s, destination)
    ack = msg.alert_ack
    ack.alert_id = alert_id
    ack.alert_ack_status = (
        alert_ack_pb2.AlertAck.ALERT_ACK_STATUS_ACCEPTED
        if accepted
        else alert_ack_pb2.AlertAck.ALERT_ACK_STATUS_REJECTED
    )
    ack.reason.extend(reasons)
    return msg
