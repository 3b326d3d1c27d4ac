"""``--publish ros2``: a run published on ROS 2 as it goes, for RViz (over DDS,
``sources.dds``; no ROS install).

Every frame, in the ``world`` frame (RViz's fixed frame):

| topic | type | QoS |
|---|---|---|
| ``/dronetrack/estimate`` | geometry_msgs/PointStamped (while estimating) | reliable, 10 |
| ``/dronetrack/track`` | nav_msgs/Path, the last ``TRAIL_LENGTH`` estimates | reliable, 10 |
| ``/dronetrack/particles`` | sensor_msgs/PointCloud2, at most 2,000 particles | best effort, 5 |
| ``/dronetrack/foreground`` | sensor_msgs/PointCloud2, the tracker's input | best effort, 5 |
| ``/dronetrack/points`` | sensor_msgs/PointCloud2, the frame's returns | best effort, 5 |

The clouds have the livox_ros_driver2 layout (x, y, z, intensity, tag, line,
timestamp).  Stamps are the host's wall clock when the frame is published, so RViz
(without sim time) shows them at once; no /tf is published, so a rig's own tree is
left alone.
"""

from __future__ import annotations

import time

from dronetrack.formats.ros2_msgs import (
    PATH,
    POINT_STAMPED,
    POINTCLOUD2,
    encode_path,
    encode_point_stamped,
    encode_points,
)
from dronetrack.sinks.view import WORLD_FRAME, EstimateTrail, ViewFrame, subsample_particles, xyz
from dronetrack.sources.dds import DdsDomain

__all__ = ["PUBLISH_CHOICES", "TOPICS", "Ros2Publisher"]

PUBLISH_CHOICES = ("ros2",)
TOPICS = {
    "estimate": ("/dronetrack/estimate", POINT_STAMPED),
    "track": ("/dronetrack/track", PATH),
    "particles": ("/dronetrack/particles", POINTCLOUD2),
    "foreground": ("/dronetrack/foreground", POINTCLOUD2),
    "points": ("/dronetrack/points", POINTCLOUD2),
}


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
        self.frames += 1

    def close(self) -> None:
        """Leave the domain; closing twice does nothing."""
        if self._closed:
            return
        self._closed = True
        self.domain.close()
