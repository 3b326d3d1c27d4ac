"""The SAPIENT messages of a LiDAR edge node, built from plain values, and the look-at
task it reads.

Conventions, from the .proto comments: locations are ``LAT_LNG_DEG_M`` on the WGS-84
ellipsoid (x longitude, y latitude [°], z altitude [m]), their errors in the same
units (1σ); range-bearing is ``DEGREES_M`` from true north; velocities are east,
north and up [m/s]; confidences are in 0-1.  Object, report, task and alert IDs are
ULIDs (``new_ulid``).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from google.protobuf.timestamp_pb2 import Timestamp
from numpy.typing import ArrayLike
from ulid import ULID

from dronetrack.formats.sapient import ICD_VERSION
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0 import (
    alert_pb2,
    location_pb2,
    range_bearing_pb2,
    registration_pb2,
    status_report_pb2,
    task_ack_pb2,
    task_pb2,
)
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)

__all__ = [
    "LookAt",
    "LookAtPoint",
    "RangeBearing",
    "alert",
    "detection_report",
    "envelope",
    "look_at",
    "metres_to_degrees",
    "new_ulid",
    "registration",
    "registration_ack",
    "status_report",
    "task_ack",
    "wgs84_location",
]

Reg = registration_pb2.Registration
_LL = location_pb2.LOCATION_COORDINATE_SYSTEM_LAT_LNG_DEG_M
_WGS84 = location_pb2.LOCATION_DATUM_WGS84_E
_DEG_M = range_bearing_pb2.RANGE_BEARING_COORDINATE_SYSTEM_DEGREES_M
_TRUE = range_bearing_pb2.RANGE_BEARING_DATUM_TRUE
WGS84_A = 6378137.0  # the ellipsoid's semi-major axis [m], for errors in degrees only


def new_ulid(rng: np.random.Generator, t_unix_s: float) -> str:
    """A ULID: 48 bits of Unix milliseconds, then 80 random bits from ``rng``."""
    ms = max(0, int(t_unix_s * 1000.0))
    return str(ULID.from_bytes(ms.to_bytes(6, "big") + rng.bytes(10)))


def _stamp(t_unix_s: float) -> Timestamp:
    stamp = Timestamp()
    sec = math.floor(t_unix_s)
    stamp.seconds, stamp.nanos = sec, min(round((t_unix_s - sec) * 1e9), 999_999_999)
    return stamp


def envelope(node_id: str, t_unix_s: float, destination: str | None = None) -> SapientMessage:
    """An empty message from ``node_id``, stamped ``t_unix_s``: fill one content field."""
    msg = SapientMessage(node_id=node_id, timestamp=_stamp(t_unix_s))
    if destination is not None:
        msg.destination_id = destination
    return msg


def metres_to_degrees(lat_deg: float, east_m: float, north_m: float) -> tuple[float, float]:
    """East and north lengths [m] at latitude ``lat_deg`` as degrees of longitude and
    latitude, on a sphere of the ellipsoid's radius a: Δλ = e / (a cos φ), Δφ = n / a
    (for errors, which need no better)."""
    phi = math.radians(lat_deg)
    return (
        math.degrees(east_m / (WGS84_A * max(math.cos(phi), 1e-9))),
        math.degrees(north_m / WGS84_A),
    )


def wgs84_location(
    lat: float, lon: float, alt: float, sigma_enu: ArrayLike | None = None
) -> location_pb2.Location:
    """A WGS-84 Location (x longitude, y latitude [°], z altitude [m]); ``sigma_enu``:
    1σ east, north, up [m], carried as errors in the location's own units."""
    loc = location_pb2.Location(x=lon, y=lat, z=alt, coordinate_system=_LL, datum=_WGS84)
    if sigma_enu is not None:
        east, north, up = (float(a) for a in np.asarray(sigma_enu, dtype=np.float64)[:3])
        loc.x_error, loc.y_error = metres_to_degrees(lat, east, north)
        loc.z_error = up
    return loc


@dataclass(frozen=True, slots=True)
class RangeBearing:
    """Azimuth from true north and elevation [°], range [m], and their 1σ errors."""

    azimuth: float
    elevation: float
    range: float
    azimuth_error: float | None = None
    elevation_error: float | None = None
    range_error: float | None = None


def registration(
    node_id: str,
    t_unix_s: float,
    *,
    name: str,
    short_name: str,
    classes: Sequence[str],
    status_period_s: float,
    field_of_view_deg: tuple[float, float],
    max_range_m: float,
    latency_s: float,
    model: str = "dronetrack",
    version: str = "",
) -> SapientMessage:
    """The node's Registration: a steerable LiDAR that tracks, reports WGS-84
    locations, ENU velocities and ``classes`` with their confidence, and takes look-at
    tasks for an area of interest; ``model`` and ``version`` are its configuration
    data (the sensor and turret, and dronetrack's version)."""
    msg = envelope(node_id, t_unix_s)
    reg = msg.registration
    reg.node_definition.add(node_type=Reg.NODE_TYPE_LIDAR, node_sub_type=["pan-tilt turret"])
    reg.icd_version = ICD_VERSION
    reg.name, reg.short_name = name, short_name
    for kind, value, units in (
        ("Horizontal field of view", f"{field_of_view_deg[0]:g}", "degrees"),
        ("Vertical field of view", f"{field_of_view_deg[1]:g}", "degrees"),
        ("Maximum range", f"{max_range_m:g}", "metres"),
    ):
        reg.capabilities.add(category="LiDAR", type=kind, value=value, units=units)
    status = reg.status_definition
    status.status_interval.units = Reg.TIME_UNITS_SECONDS
    status.status_interval.value = status_period_s
    status.location_definition.location_units = _LL
    status.location_definition.location_datum = _WGS84
    status.field_of_view_definition.range_bearing_units = _DEG_M
    status.field_of_view_definition.range_bearing_datum = _TRUE
    mode = reg.mode_definition.add(mode_name="default", mode_type=Reg.MODE_TYPE_PERMANENT)
    mode.mode_description = "detect, track and classify; the turret follows the chosen drone"
    mode.settle_time.units = Reg.TIME_UNITS_SECONDS
    mode.settle_time.value = 0.0
    mode.maximum_latency.units = Reg.TIME_UNITS_SECONDS
    mode.maximum_latency.value = latency_s
    mode.scan_type = Reg.SCAN_TYPE_STEERABLE
    mode.tracking_type = Reg.TRACKING_TYPE_TRACK
    detection = mode.detection_definition.add()
    detection.location_type.location_units = _LL
    detection.location_type.location_datum = _WGS84
    detection.velocity_type.enu_velocity_units.east_north_rate_units = 1  # SPEED_UNITS_MS
    detection.velocity_type.enu_velocity_units.up_rate_units = 1
    detection.velocity_type.location_datum = _WGS84
    for kind, units in (
        ("range_m", "metres"),
        ("azimuth_deg", "degrees from true north"),
        ("elevation_deg", "degrees"),
        ("track_id", "integer"),
        ("frame_t_s", "seconds on the run's clock"),
    ):
        detection.detection_report.add(
            category=Reg.DETECTION_REPORT_CATEGORY_TRACK, type=kind, units=units
        )
    classified = detection.detection_class_definition.add(
        confidence_definition=Reg.CONFIDENCE_DEFINITION_SINGLE_CLASS
    )
    for cls in classes:
        classified.class_definition.add(type=cls, units="probability (0-1)")
    task = mode.task
    task.concurrent_tasks = 1
    task.region_definition.region_type.append(Reg.REGION_TYPE_AREA_OF_INTEREST)
    area = task.region_definition.region_area.add()
    area.location_units, area.location_datum = _LL, _WGS84
    look = task.command.add(units="location list or range-bearing cone")
    look.type = Reg.COMMAND_TYPE_LOOK_AT
    look.completion_time.units = Reg.TIME_UNITS_SECONDS
    look.completion_time.value = 1.0
    reg.config_data.add(manufacturer="dronetrack developers", model=model, software_version=version)
    return msg


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
    (a range-bearing cone ``field_of_view_deg`` wide about ``pointing``), its mode
    and state, and any ``notes`` (type, value) as information statuses."""
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
        cone.coordinate_system, cone.datum = _DEG_M, _TRUE
    for kind, value in notes:
        status.status.add(
            status_level=status_report_pb2.StatusReport.STATUS_LEVEL_INFORMATION_STATUS,
            status_type=kind,
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
    classification: tuple[str, float],
    track_id: int,
    frame_t: float | None = None,
    confidence: float | None = None,
    state: str | None = None,
    task_id: str | None = None,
) -> SapientMessage:
    """A DetectionReport of one track: its WGS-84 ``location`` with 1σ east, north and
    up errors [m] (as degrees and metres), its range and bearing from the node and the
    track's own ID (as track_info, since the location oneof holds the location), its
    ENU velocity with errors, and its class with its confidence.  ``frame_t``: the
    time of the frame it comes from on the run's clock [s] (track_info ``frame_t_s``),
    which ties it to tracks.csv's row."""
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
    for kind, value, error in (
        ("range_m", rb.range, rb.range_error),
        ("azimuth_deg", rb.azimuth, rb.azimuth_error),
        ("elevation_deg", rb.elevation, rb.elevation_error),
    ):
        info = report.track_info.add(type=kind, value=f"{value:.3f}")
        if error is not None and math.isfinite(error):
            info.error = error
    report.track_info.add(type="track_id", value=str(track_id))
    if frame_t is not None:
        report.track_info.add(type="frame_t_s", value=f"{frame_t:.6f}")
    v = np.asarray(velocity_enu, dtype=np.float64)
    s = np.asarray(velocity_sigma_enu, dtype=np.float64)
    vel = report.enu_velocity
    vel.east_rate, vel.north_rate, vel.up_rate = float(v[0]), float(v[1]), float(v[2])
    vel.east_rate_error, vel.north_rate_error, vel.up_rate_error = (float(e) for e in s[:3])
    cls, p = classification
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
        detection.timestamp.CopyFrom(_stamp(t_unix_s))
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


@dataclass(frozen=True, slots=True)
class LookAtPoint:
    """A look-at location: latitude, longitude [°] and, if given, altitude [m]."""

    latitude: float
    longitude: float
    altitude: float | None


@dataclass(frozen=True, slots=True)
class LookAt:
    """A look-at task read from a Task: where (a point, or a range-bearing from the
    node), or ``stop``."""

    task_id: str
    point: LookAtPoint | None = None
    bearing: RangeBearing | None = None
    stop: bool = False


def look_at(task: task_pb2.Task) -> LookAt | str:
    """The look-at a Task asks for, or why it cannot be done (a one-line reason).

    A location list's look-at is its points' centre; a range-bearing cone's, its axis
    (range 100 m when not given).  Only LAT_LNG_DEG_M locations and DEGREES_M
    bearings from true north are read.
    """
    task_id = task.task_id
    if task.control in (task_pb2.Task.CONTROL_STOP, task_pb2.Task.CONTROL_PAUSE):
        return LookAt(task_id, stop=True)
    if task.control != task_pb2.Task.CONTROL_START:
        return "the task has no control: give CONTROL_START, CONTROL_STOP or CONTROL_PAUSE"
    if not task.HasField("command"):
        return "the task has no command: this node takes a look_at command only"
    kind = task.command.WhichOneof("command")
    if kind != "look_at":
        return f"the command {kind} is not done by this node: it takes look_at only"
    where = task.command.look_at
    which = where.WhichOneof("fov_oneof")
    if which == "location_list":
        points = where.location_list.locations
        if not points:
            return "the look_at location list is empty"
        if any(p.coordinate_system != _LL for p in points):
            return "the look_at locations are not LAT_LNG_DEG_M: this node reads degrees only"
        alts = [p.z for p in points if p.HasField("z")]
        return LookAt(
            task_id,
            point=LookAtPoint(
                float(np.mean([p.y for p in points])),
                float(np.mean([p.x for p in points])),
                float(np.mean(alts)) if alts else None,
            ),
        )
    if which == "range_bearing":
        cone = where.range_bearing
        if cone.coordinate_system != _DEG_M or cone.datum != _TRUE:
            return "the look_at bearing is not DEGREES_M from true north"
        if not cone.HasField("azimuth"):
            return "the look_at bearing has no azimuth"
        return LookAt(
            task_id,
            bearing=RangeBearing(
                cone.azimuth,
                cone.elevation if cone.HasField("elevation") else 0.0,
                cone.range if cone.HasField("range") else 100.0,
            ),
        )
    return "the look_at command gives no location list or range-bearing cone"
