"""Look-at Tasks: the one a fusion node sends (``look_at_task``) and what an edge node
reads from one (``look_at``).

A look-at's ``LocationOrRangeBearing`` is either a location list (its points' centre
is looked at) or a range-bearing cone (its axis).  Locations in latitude and
longitude (degrees or radians) on the WGS-84 ellipsoid, and bearings from true north
(degrees or radians, metres or kilometres) are read, in the node's units (degrees
and metres); UTM, geoid altitudes and bearings from magnetic, grid or platform north
are refused with the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dronetrack.formats.sapient.fields import (
    DEG_M,
    LAT_LNG_DEG_M,
    TRUE_NORTH,
    WGS84_E,
    RangeBearing,
    envelope,
)
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0 import (
    location_pb2,
    range_bearing_pb2,
    task_pb2,
)
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)

__all__ = ["DEFAULT_LOOK_AT_RANGE_M", "LookAt", "LookAtPoint", "look_at", "look_at_task"]

Task = task_pb2.Task
DEFAULT_LOOK_AT_RANGE_M = 100.0  # a range-bearing look-at without a range looks this far
_LAT_LNG_RAD_M = location_pb2.LOCATION_COORDINATE_SYSTEM_LAT_LNG_RAD_M
_DATUM_UNSET = location_pb2.LOCATION_DATUM_UNSPECIFIED
# A range-bearing coordinate system: (degrees per unit of angle, metres per unit of range)
_RB_UNITS = {
    DEG_M: (1.0, 1.0),
    range_bearing_pb2.RANGE_BEARING_COORDINATE_SYSTEM_RADIANS_M: (math.degrees(1.0), 1.0),
    range_bearing_pb2.RANGE_BEARING_COORDINATE_SYSTEM_DEGREES_KM: (1.0, 1000.0),
    range_bearing_pb2.RANGE_BEARING_COORDINATE_SYSTEM_RADIANS_KM: (math.degrees(1.0), 1000.0),
}


@dataclass(frozen=True, slots=True)
class LookAtPoint:
    """A look-at location: latitude, longitude [°] and, if given, altitude [m] above the
    WGS-84 ellipsoid."""

    latitude: float
    longitude: float
    altitude: float | None


@dataclass(frozen=True, slots=True)
class LookAt:
    """A look-at task read from a Task: where (a point, or a range-bearing from the
    node), or ``stop`` (the task's look-at ends)."""

    task_id: str
    point: LookAtPoint | None = None
    bearing: RangeBearing | None = None
    stop: bool = False


def look_at_task(
    node_id: str,
    destination: str,
    t_unix_s: float,
    task_id: str,
    point: tuple[float, float, float | None] | None = None,
    bearing: RangeBearing | None = None,
) -> SapientMessage:
    """A Task from ``node_id`` to ``destination``: start looking at ``point`` (lat°,
    lon°, alt m or None) or along ``bearing`` (from the destination, true north)."""
    if (point is None) == (bearing is None):
        raise ValueError("a look-at task needs a point or a bearing, not both")
    msg = envelope(node_id, t_unix_s, destination)
    task = msg.task
    task.task_id, task.task_name = task_id, "look at"
    task.control = Task.CONTROL_START
    where = task.command.look_at
    if point is not None:
        lat, lon, alt = point
        location = where.location_list.locations.add(
            x=lon, y=lat, coordinate_system=LAT_LNG_DEG_M, datum=WGS84_E
        )
        if alt is not None:
            location.z = alt
    else:
        assert bearing is not None
        cone = where.range_bearing
        cone.azimuth, cone.elevation, cone.range = bearing.azimuth, bearing.elevation, bearing.range
        cone.coordinate_system, cone.datum = DEG_M, TRUE_NORTH
    return msg


def look_at(task: task_pb2.Task) -> LookAt | str:
    """The look-at a Task asks for, or why it cannot be done (a one-line reason).

    CONTROL_STOP or CONTROL_PAUSE ends the look-at (``LookAt.stop``); CONTROL_START
    needs a ``look_at`` command.  A location list's look-at is its points' centre; a
    range-bearing cone's, its axis (``DEFAULT_LOOK_AT_RANGE_M`` when it gives no range,
    elevation 0° when it gives none).
    """
    task_id = task.task_id
    if task.control in (Task.CONTROL_STOP, Task.CONTROL_PAUSE):
        return LookAt(task_id, stop=True)
    if task.control != Task.CONTROL_START:
        return "the task has no control: give CONTROL_START, CONTROL_STOP or CONTROL_PAUSE"
    if not task.HasField("command"):
        return "the task has no command: this node takes a look_at command only"
    kind = task.command.WhichOneof("command")
    if kind != "look_at":
        return f"the command {kind} is not done by this node: it takes look_at only"
    where = task.command.look_at
    which = where.WhichOneof("fov_oneof")
    if which == "location_list":
        return _centre(task_id, list(where.location_list.locations))
    if which == "range_bearing":
        return _axis(task_id, where.range_bearing)
    return "the look_at command gives no location list or range-bearing cone"


def _centre(task_id: str, points: list[location_pb2.Location]) -> LookAt | str:
    """The look-at of a location list: the mean of its points."""
    if not points:
        return "the look_at location list is empty"
    if any(p.coordinate_system not in (LAT_LNG_DEG_M, _LAT_LNG_RAD_M) for p in points):
        return "the look_at locations are not latitude and longitude (LAT_LNG_DEG_M or _RAD_M)"
    if any(p.datum not in (WGS84_E, _DATUM_UNSET) and p.HasField("z") for p in points):
        return "the look_at altitudes are not above the WGS-84 ellipsoid (LOCATION_DATUM_WGS84_E)"
    scale = [1.0 if p.coordinate_system == LAT_LNG_DEG_M else math.degrees(1.0) for p in points]
    alts = [p.z for p in points if p.HasField("z")]
    return LookAt(
        task_id,
        point=LookAtPoint(
            float(np.mean([p.y * s for p, s in zip(points, scale, strict=True)])),
            float(np.mean([p.x * s for p, s in zip(points, scale, strict=True)])),
            float(np.mean(alts)) if alts else None,
        ),
    )


def _axis(task_id: str, cone: range_bearing_pb2.RangeBearingCone) -> LookAt | str:
    """The look-at of a range-bearing cone: its axis, in degrees and metres."""
    units = _RB_UNITS.get(cone.coordinate_system)
    if units is None:
        return "the look_at bearing has no units (RANGE_BEARING_COORDINATE_SYSTEM_...)"
    if cone.datum != TRUE_NORTH:
        return "the look_at bearing is not from true north (RANGE_BEARING_DATUM_TRUE)"
    if not cone.HasField("azimuth"):
        return "the look_at bearing has no azimuth"
    degrees, metres = units
    return LookAt(
        task_id,
        bearing=RangeBearing(
            cone.azimuth * degrees,
            cone.elevation * degrees if cone.HasField("elevation") else 0.0,
            cone.range * metres if cone.HasField("range") else DEFAULT_LOOK_AT_RANGE_M,
        ),
    )
