"""ROS 2 names on DDS: topics, message types, ``ros2://`` URIs and the QoS conventions.

A ROS 2 node on any RMW over DDS puts its topic ``/foo/bar`` on the DDS topic
``rt/foo/bar`` and its message type ``pkg/msg/Name`` on the DDS type name
``pkg::msg::dds_::Name_`` (ros2/design, "Topic and Service name mapping to DDS";
rmw_cyclonedds ``namespace_prefix.hpp`` and ``serdata.cpp``).  The samples are XCDR1
with the 4-byte encapsulation header, the bytes rosbags' ``serialize_cdr`` writes.

Topic names follow ros2/design's "Topic and Service Names" rules, here for fully
qualified names (the only kind a process without a node namespace has): they start
with ``/``, are made of tokens ``[A-Za-z_][A-Za-z0-9_]*`` separated by single
slashes, hold no ``__`` and do not end with ``/``.  A relative name (``livox/lidar``)
is taken from the root namespace.  Message types are ``pkg/msg/Name``: a package
name of lower-case letters, digits and single underscores starting with a letter
(REP 144), and a CamelCase message name.

QoS (rmw ``qos_profiles.h``): sensor data is BEST_EFFORT, KEEP_LAST 5, VOLATILE;
everything else RELIABLE, KEEP_LAST 10, VOLATILE; ``/tf_static`` is RELIABLE,
TRANSIENT_LOCAL (tf2's static broadcaster), so a late subscriber gets it; ``tf``
is tf2's listener, RELIABLE KEEP_LAST 100 VOLATILE.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Literal
from urllib.parse import parse_qsl, urlsplit

from dronetrack.errors import ConfigError

__all__ = [
    "ROS2_SCHEME",
    "QosKind",
    "Ros2Uri",
    "check_type_name",
    "dds_topic",
    "dds_type",
    "parse_ros2_uri",
    "ros_topic",
    "ros_topic_name",
    "ros_type",
]

ROS2_SCHEME = "ros2://"
TOPIC_PREFIX = "rt"  # ROS topics; rq/rr are service requests and replies
QosKind = Literal["sensor", "default", "static", "tf"]

_TOKEN = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_PACKAGE = re.compile(r"[a-z][a-z0-9]*(_[a-z0-9]+)*")
_MESSAGE = re.compile(r"[A-Z][A-Za-z0-9]*")


def ros_topic_name(name: str) -> str:
    """``name`` as a fully qualified ROS 2 topic name (a relative one from the root
    namespace); ConfigError naming the rule it breaks."""
    given = name
    if not name:
        raise ConfigError("a ROS 2 topic name must not be empty")
    if not name.startswith("/"):
        name = "/" + name
    if name == "/":
        raise ConfigError("'/' is a namespace, not a ROS 2 topic name")
    if name.endswith("/"):
        raise ConfigError(f"ROS 2 topic name {given!r} must not end with '/'")
    if "//" in name:
        raise ConfigError(f"ROS 2 topic name {given!r} must not repeat '/'")
    if "__" in name:
        raise ConfigError(f"ROS 2 topic name {given!r} must not repeat '_'")
    for token in name[1:].split("/"):
        if not _TOKEN.fullmatch(token):
            raise ConfigError(
                f"ROS 2 topic name {given!r}: {token!r} is not a token (letters, digits and "
                "'_', not starting with a digit)"
            )
    return name


def dds_topic(name: str) -> str:
    """The DDS topic of ROS 2 topic ``name``: ``/foo/bar`` → ``rt/foo/bar``."""
    return TOPIC_PREFIX + ros_topic_name(name)


def ros_topic(dds_name: str) -> str | None:
    """The ROS 2 topic of DDS topic ``dds_name`` (``rt/foo`` → ``/foo``); None for a DDS
    topic that is not a ROS topic (services, DDS-only topics)."""
    if not dds_name.startswith(TOPIC_PREFIX + "/"):
        return None
    try:
        return ros_topic_name(dds_name[len(TOPIC_PREFIX) :])
    except ConfigError:
        return None


def check_type_name(name: str) -> tuple[str, str]:
    """(package, message) of a ROS 2 message type ``pkg/msg/Name`` (``pkg/Name`` is
    taken as ``pkg/msg/Name``); ConfigError if it is not one."""
    parts = name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or parts[1] != "msg":
        raise ConfigError(f"ROS 2 message type {name!r} is not pkg/msg/Name")
    pkg, _, msg = parts
    if not _PACKAGE.fullmatch(pkg):
        raise ConfigError(
            f"ROS 2 message type {name!r}: package {pkg!r} must be lower-case letters, digits "
            "and single '_', starting with a letter"
        )
    if not _MESSAGE.fullmatch(msg):
        raise ConfigError(f"ROS 2 message type {name!r}: {msg!r} is not a CamelCase name")
    return pkg, msg


def dds_type(name: str) -> str:
    """The DDS type name of ROS 2 message type ``pkg/msg/Name``:
    ``pkg::msg::dds_::Name_``."""
    pkg, msg = check_type_name(name)
    return f"{pkg}::msg::dds_::{msg}_"


def ros_type(dds_name: str) -> str | None:
    """``pkg/msg/Name`` of DDS type name ``pkg::msg::dds_::Name_``; None if it is not a
    ROS 2 message type."""
    parts = dds_name.split("::")
    if len(parts) != 4 or parts[1:3] != ["msg", "dds_"] or not parts[3].endswith("_"):
        return None
    name = f"{parts[0]}/msg/{parts[3][:-1]}"
    try:
        check_type_name(name)
    except ConfigError:
        return None
    return name


@dataclass(frozen=True, slots=True)
class Ros2Uri:
    """``ros2:///TOPIC[?type=pkg/msg/Name&truth=/TOPIC&frame=NAME]``: a topic (None for
    ``ros2://``, the whole domain), an optional message type, a ground-truth topic
    (``geometry_msgs/PoseStamped``) and the /tf frame poses are given in."""

    topic: str | None
    msg_type: str | None = None
    truth: str | None = None
    frame: str | None = None


def parse_ros2_uri(uri: str, option: str = "--lidar") -> Ros2Uri:
    """The topic and type of a ``ros2://`` URI; ConfigError for a bad one."""
    if not uri.startswith(ROS2_SCHEME):
        raise ConfigError(f"{option} {uri!r} is not a ros2:// URI")
    parts = urlsplit(uri)
    if parts.netloc:
        raise ConfigError(
            f"{option} {uri!r}: a ROS 2 topic URI has no host: ros2:///livox/lidar (three '/')"
        )
    query = dict(parse_qsl(parts.query, keep_blank_values=True))
    unknown = sorted(set(query) - {"type", "truth", "frame"})
    if unknown:
        raise ConfigError(
            f"{option} {uri!r}: unknown key(s) {', '.join(unknown)} (known: type, truth, frame)"
        )
    topic = None
    if parts.path not in ("", "/"):
        try:
            topic = ros_topic_name(parts.path)
        except ConfigError as exc:
            raise ConfigError(f"{option} {uri!r}: {exc}") from None
    msg_type = query.get("type")
    if msg_type is not None:
        pkg, msg = check_type_name(msg_type)
        msg_type = f"{pkg}/msg/{msg}"
    truth = query.get("truth")
    if truth is not None:
        try:
            truth = ros_topic_name(truth)
        except ConfigError as exc:
            raise ConfigError(f"{option} {uri!r}: truth: {exc}") from None
    frame = query.get("frame") or None
    return Ros2Uri(topic, msg_type, truth, frame)
