"""The Registration of a LiDAR edge node: what it is, what it reports, and the tasks
it takes."""

from __future__ import annotations

from collections.abc import Sequence

from dronetrack.formats.sapient import ICD_VERSION
from dronetrack.formats.sapient.fields import DEG_M, LAT_LNG_DEG_M, TRUE_NORTH, WGS84_E, envelope
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0 import registration_pb2, velocity_pb2
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)

__all__ = ["REPORTED_INFO", "registration"]

Reg = registration_pb2.Registration
# The track_info entries each DetectionReport carries (messages.detection_report), and
# their units
REPORTED_INFO = (
    ("range_m", "metres"),
    ("azimuth_deg", "degrees from true north"),
    ("elevation_deg", "degrees"),
    ("track_id", "integer"),
    ("frame_t_s", "seconds on the run's clock"),
)


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
    """The node's Registration: a steerable LiDAR (``NODE_TYPE_LIDAR``, one mode,
    ``default``) that tracks, reports WGS-84 locations (``LAT_LNG_DEG_M``,
    ``WGS84_E``), ENU velocities [m/s], and the most likely of ``classes`` with its
    confidence (``CONFIDENCE_DEFINITION_SINGLE_CLASS``), a StatusReport every
    ``status_period_s``, and takes look-at tasks for an area of interest.
    ``field_of_view_deg`` (horizontal, vertical) and ``max_range_m`` are its
    capabilities, ``latency_s`` its maximum latency; ``model`` and ``version`` its
    configuration data (the sensor and turret, and dronetrack's version)."""
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
    status.location_definition.location_units = LAT_LNG_DEG_M
    status.location_definition.location_datum = WGS84_E
    status.field_of_view_definition.range_bearing_units = DEG_M
    status.field_of_view_definition.range_bearing_datum = TRUE_NORTH
    mode = reg.mode_definition.add(mode_name="default", mode_type=Reg.MODE_TYPE_PERMANENT)
    mode.mode_description = "detect, track and classify; the turret follows the chosen drone"
    mode.settle_time.units = Reg.TIME_UNITS_SECONDS
    mode.settle_time.value = 0.0
    mode.maximum_latency.units = Reg.TIME_UNITS_SECONDS
    mode.maximum_latency.value = latency_s
    mode.scan_type = Reg.SCAN_TYPE_STEERABLE
    mode.tracking_type = Reg.TRACKING_TYPE_TRACK
    detection = mode.detection_definition.add()
    detection.location_type.location_units = LAT_LNG_DEG_M
    detection.location_type.location_datum = WGS84_E
    detection.velocity_type.enu_velocity_units.east_north_rate_units = velocity_pb2.SPEED_UNITS_MS
    detection.velocity_type.enu_velocity_units.up_rate_units = velocity_pb2.SPEED_UNITS_MS
    detection.velocity_type.location_datum = WGS84_E
    for kind, units in REPORTED_INFO:
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
    area.location_units, area.location_datum = LAT_LNG_DEG_M, WGS84_E
    look = task.command.add(units="location list or range-bearing cone")
    look.type = Reg.COMMAND_TYPE_LOOK_AT
    look.completion_time.units = Reg.TIME_UNITS_SECONDS
    look.completion_time.value = 1.0
    reg.config_data.add(manufacturer="dronetrack developers", model=model, software_version=version)
    return msg
