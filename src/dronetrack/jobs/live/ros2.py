"""ROS 2 in a live run and in ``dronetrack info``: ``--lidar ros2:///TOPIC`` and
``info ros2://[/TOPIC]``, over one DDS participant (``sources.ros2.dds``).

``Ros2Link`` joins the domain (``--ros-domain-id``, else ``ROS_DOMAIN_ID``, else 0)
and makes the point topic's source (``sources.ros2.topic``) once the topic's type is
known: the URI's ``type=``, else the type its publisher announces.
``probe_ros2`` lists what the domain holds and, for a topic, its message rate.
"""

from __future__ import annotations

import time
from typing import Any

from dronetrack.errors import ConfigError
from dronetrack.formats.ros.names import parse_ros2_uri
from dronetrack.geometry.mount import MountGeometry
from dronetrack.sources.live import TurretReader
from dronetrack.sources.ros2.dds import DdsDomain
from dronetrack.sources.ros2.topic import POINT_TYPES, Ros2Source, point_type
from dronetrack.sources.truth_csv import TruthFile

__all__ = ["Ros2Link", "probe_ros2"]


class Ros2Link:
    """The DDS participant of a ``ros2://TOPIC`` LiDAR; ``close`` leaves the domain."""

    def __init__(self, uri: str, domain_id: int | None = None) -> None:
        self.uri = parse_ros2_uri(uri, "--lidar")
        if self.uri.topic is None:
            raise ConfigError(f"--lidar {uri!r} names no topic: ros2:///livox/lidar")
        if self.uri.msg_type is not None and self.uri.msg_type not in POINT_TYPES:
            raise ConfigError(
                f"--lidar {uri!r}: type {self.uri.msg_type} is not {' or '.join(POINT_TYPES)}"
            )
        self.domain = DdsDomain(domain_id)

    def source(
        self,
        mount: MountGeometry,
        turret: TurretReader | None,
        *,
        period_s: float,
        max_frames: int,
        duration_s: float | None,
        truth_radius: float,
        truth: TruthFile | None = None,
        wait_s: float = 10.0,
    ) -> Ros2Source:
        topic = self.uri.topic
        assert topic is not None
        msg_type = self.uri.msg_type or point_type(self.domain, topic, wait_s)
        return Ros2Source(
            self.domain,
            topic,
            msg_type,
            mount,
            turret,
            period_s=period_s,
            max_frames=max_frames,
            duration_s=duration_s,
            pose_frame=self.uri.frame,
            truth_topic=self.uri.truth,
            truth=truth,
            truth_radius=truth_radius,
            first_s=wait_s,
        )

    def close(self) -> None:
        self.domain.close()


def probe_ros2(
    uri: str, domain_id: int | None = None, wait_s: float = 2.0, sample_s: float = 2.0
) -> list[tuple[str, str]]:
    """``dronetrack info ros2://[/TOPIC]``: (name, value) lines of the ROS 2 topics
    other participants on the domain write or read (after ``wait_s`` of discovery at
    most), and for a topic given its type, publishers, subscribers and message rate
    over ``sample_s`` seconds."""
    target = parse_ros2_uri(uri, "info")
    domain = DdsDomain(domain_id)
    try:
        seen = domain.topics(wait_s)
        lines = [("domain", str(domain.domain_id))]
        if target.topic is None:
            for s in seen:
                lines.append((s.topic, _endpoints(s)))
            if not seen:
                lines.append(("topics", f"none seen within {wait_s:g} s"))
            return lines
        mine = [s for s in seen if s.topic == target.topic]
        if not mine:
            listed = ", ".join(s.topic for s in seen) or "none"
            return [*lines, (target.topic, f"not seen within {wait_s:g} s (topics: {listed})")]
        for s in mine:
            lines.append((target.topic, _endpoints(s)))
        msg_type = target.msg_type or mine[0].msg_type
        lines.append((f"rate over {sample_s:g} s", _rate(domain, target.topic, msg_type, sample_s)))
        return lines
    finally:
        domain.close()


def _endpoints(s: Any) -> str:
    return f"{s.msg_type}, {s.writers} publisher(s), {s.readers} subscriber(s)"


def _rate(domain: DdsDomain, topic: str, msg_type: str, sample_s: float) -> str:
    """Messages and bytes on ``topic`` over ``sample_s`` s (best effort, so any
    publisher's samples come)."""
    try:
        reader = domain.reader(topic, msg_type, "sensor")
    except ConfigError as exc:
        return str(exc)
    stamps: list[float] = []
    size = 0
    end = time.monotonic() + sample_s
    while time.monotonic() < end:
        reader.wait(min(0.05, max(end - time.monotonic(), 0.0)))
        for raw in reader.drain():
            stamps.append(time.monotonic())
            size += len(raw)
    n = len(stamps)
    if n < 2:
        return f"{n} message(s)"
    hz = (n - 1) / (stamps[-1] - stamps[0])
    return f"{n} messages, {hz:.1f} Hz, {size / n / 1000:.1f} kB per message"
