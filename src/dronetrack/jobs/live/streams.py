"""The LiDAR clients a live run opens by URI (``livox://``, ``livox2://``,
``velodyne://``); ``OPEN_TIMEOUT_S`` (``sources.live``) is how long one has to answer."""

from __future__ import annotations

from typing import Protocol

from dronetrack.config.run import SensorConfig
from dronetrack.errors import ConfigError
from dronetrack.sources.live import OPEN_TIMEOUT_S, PointStream

__all__ = ["OPEN_TIMEOUT_S", "OpenStream", "open_point_stream"]


class OpenStream(PointStream, Protocol):
    """A point stream that is opened (connected and sampling) before it is read."""

    def open(self, timeout_s: float = 3.0) -> None: ...


def _with_host(uri: str, host_ip: str | None) -> str:
    """``uri`` with ``host=host_ip`` added (``--host-ip``); ConfigError if the URI
    already names another host."""
    if host_ip is None:
        return uri
    from urllib.parse import parse_qsl, urlsplit

    given = dict(parse_qsl(urlsplit(uri).query, keep_blank_values=True)).get("host")
    if given is not None:
        if given != host_ip:
            raise ConfigError(f"--host-ip {host_ip} and the LiDAR URI's host={given} disagree")
        return uri
    return f"{uri}{'&' if '?' in uri else '?'}host={host_ip}"


def open_point_stream(
    uri: str, host_ip: str | None = None, sensor: SensorConfig | None = None
) -> OpenStream:
    """The (not yet opened) client of a ``livox://``, ``livox2://`` or ``velodyne://``
    LiDAR (a VLP-16's points in the frame of ``sensor``'s mount); ConfigError for a bad
    URI or ``--host-ip``."""
    if uri.startswith("livox://"):
        from dronetrack.sources.livox.sdk1 import LivoxClient

        return LivoxClient(_with_host(uri, host_ip))
    if uri.startswith("livox2://"):
        from dronetrack.sources.livox.sdk2 import Livox2Client

        return Livox2Client(_with_host(uri, host_ip))
    if uri.startswith("velodyne://"):
        from dronetrack.jobs.live.velodyne import velodyne_client

        return velodyne_client(_with_host(uri, host_ip), sensor)
    raise ConfigError(
        f"--lidar {uri!r}: give livox://IP (Avia, Mid-40/70, Horizon, Tele), livox2://IP "
        "(Mid-360), velodyne://[IP:]PORT (VLP-16), ros2:///TOPIC (a ROS 2 point topic) or "
        "file://RECORDING"
    )
