"""``--publish ros2``: a run published on ROS 2 as it goes, for RViz (over DDS,
``sources.ros2.dds``; no ROS install).

Every frame, in the ``world`` frame (RViz's fixed frame):

| topic | type | QoS |
|---|---|---|
| ``/dronetrack/estimate`` | geometry_msgs/PointStamped (while estimating) | reliable, 10 |
| ``/dronetrack/track`` | nav_msgs/Path, the last ``TRAIL_LENGTH`` estimates | reliable, 10 |
| ``/dronetrack/particles`` | sensor_msgs/PointCloud2, at most 2,000 particles | best effort, 5 |
| ``/dronetrack/foreground`` | sensor_msgs/PointCloud2, the tracker's input | best effort, 5 |
| ``/dronetrack/points`` | sensor_msgs/PointCloud2, the frame's returns | best effort, 5 |
| ``/dronetrack/tracks`` | visualization_msgs/MarkerArray, every object's track | reliable, 10 |

The clouds have the livox_ros_driver2 layout (x, y, z, intensity, tag, line,
timestamp).  Stamps are the host's wall clock when the frame is published, so RViz
(without sim time) shows them at once; no /tf is published, so a rig's own tree is
left alone.

``/dronetrack/tracks`` comes from the first frame with a track layer on (none
before).  Per track, marker id = track id: in namespace ``tracks`` a sphere in its
class colour (``sinks.view.TRACK_RGB``) as wide as twice its position sigma
(0.3-10 m), in ``track_labels`` a text ``<id> <class> p=<p_drone>`` (`` locked``
after it on the track the turret's tracker holds) 1 m high above it; in
``track_locked``, id 0, a translucent green sphere around the locked track (deleted
while none is).  A gone track's markers are deleted (action DELETE).  Marker is
ROS 2 Humble's (with the texture and mesh_file fields).
"""

from __future__ import annotations

import time

from dronetrack.formats.ros.msgs import (
    MARKER_ARRAY,
    PATH,
    POINT_STAMPED,
    POINTCLOUD2,
    MarkerSpec,
    encode_marker_array,
    encode_path,
    encode_point_stamped,
    encode_points,
)
from dronetrack.sinks.view import (
    LOCKED_RGB,
    WORLD_FRAME,
    EstimateTrail,
    ShownTracks,
    TrackUpdate,
    ViewFrame,
    subsample_particles,
    track_label,
    track_size,
    xyz,
)
from dronetrack.sources.ros2.dds import DdsDomain

__all__ = ["TOPICS", "Ros2Publisher", "track_markers"]

TOPICS = {
    "estimate": ("/dronetrack/estimate", POINT_STAMPED),
    "track": ("/dronetrack/track", PATH),
    "particles": ("/dronetrack/particles", POINTCLOUD2),
    "foreground": ("/dronetrack/foreground", POINTCLOUD2),
    "points": ("/dronetrack/points", POINTCLOUD2),
    "tracks": ("/dronetrack/tracks", MARKER_ARRAY),
}
TRACK_NS, LABEL_NS, LOCKED_NS = "tracks", "track_labels", "track_locked"
_ALPHA = 0.6
_HALO_ALPHA = 0.3
_HALO_SCALE = 1.8  # the locked track's halo against its sphere
_TEXT_M = 1.0  # label height [m]


def _rgba(rgb: tuple[int, int, int], alpha: float) -> tuple[float, float, float, float]:
    r, g, b = (c / 255.0 for c in rgb)
    return (r, g, b, alpha)


def track_markers(update: TrackUpdate) -> list[MarkerSpec]:
    """The markers of one frame's tracks (see the module docstring): the gone ones'
    deletions first, then a sphere and a label per track, then the locked halo."""
    out = [MarkerSpec(ns, ident, "delete") for ident in update.gone for ns in (TRACK_NS, LABEL_NS)]
    halo = MarkerSpec(LOCKED_NS, 0, "delete")
    for t in update.tracks:
        d = track_size(t.sigma)
        x, y, z = t.position
        out.append(MarkerSpec(TRACK_NS, t.id, "sphere", t.position, d, _rgba(t.rgb, _ALPHA)))
        above = (x, y, z + d / 2 + _TEXT_M)
        text = track_label(t)
        out.append(MarkerSpec(LABEL_NS, t.id, "text", above, _TEXT_M, _rgba(t.rgb, 1.0), text))
        if t.locked:
            halo = MarkerSpec(
                LOCKED_NS, 0, "sphere", t.position, _HALO_SCALE * d, _rgba(LOCKED_RGB, _HALO_ALPHA)
            )
    return [*out, halo]


class Ros2Publisher:
    """A viewer sink (``sinks.view.ViewerSink``) that publishes each frame on ROS 2
    domain ``domain_id`` (None: ROS_DOMAIN_ID, else 0); ``close`` leaves the domain."""

    def __init__(self, domain_id: int | None = None) -> None:
        self.domain = DdsDomain(domain_id)
        self._writers = {
            key: self.domain.writer(
                topic, msg_type, "sensor" if msg_type == POINTCLOUD2 else "default"
            )
            for key, (topic, msg_type) in TOPICS.items()
        }
        self._trail = EstimateTrail()
        self._shown = ShownTracks()
        self.frames = 0
        self._closed = False

    def log(self, frame: ViewFrame) -> None:
        """Publish one frame (see the module docstring)."""
        stamp = time.time_ns()
        w = self._writers
        trail = self._trail.update(frame.estimate)
        if frame.estimate is not None:
            w["estimate"].write(encode_point_stamped(stamp, WORLD_FRAME, frame.estimate))
        w["track"].write(encode_path(stamp, WORLD_FRAME, trail))
        particles = subsample_particles(frame.particles)
        w["particles"].write(encode_points(stamp, WORLD_FRAME, particles))
        w["foreground"].write(
            encode_points(stamp, WORLD_FRAME, xyz(frame.foreground, "foreground"))
        )
        w["points"].write(encode_points(stamp, WORLD_FRAME, xyz(frame.points, "points")))
        update = self._shown.update(frame.tracks)
        if update is not None:
            w["tracks"].write(encode_marker_array(stamp, WORLD_FRAME, track_markers(update)))
        self.frames += 1

    def close(self) -> None:
        """Leave the domain; closing twice does nothing."""
        if self._closed:
            return
        self._closed = True
        self.domain.close()
