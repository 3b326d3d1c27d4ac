"""ROS 2 on DDS: names (ros2/design's topic name rules, ``pkg/msg/Name`` types, the
``rt/`` and ``::dds_::`` mapping), ``ros2://`` URIs, the IDL mirrors' bytes against
rosbags' serialisation, and the small messages' codecs against bytes built by hand
from the CDR rules."""

from __future__ import annotations

import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.errors import ConfigError, DecodeError
from dronetrack.formats.ros.msgs import (
    MarkerSpec,
    decode_joint_state,
    decode_tf,
    encode_joint_command,
    encode_joint_state,
    encode_marker_array,
    encode_path,
    encode_point_stamped,
    encode_points,
    encode_tf,
    ros2_typestore,
)
from dronetrack.formats.ros.names import (
    check_type_name,
    dds_topic,
    dds_type,
    parse_ros2_uri,
    ros_topic,
    ros_topic_name,
    ros_type,
)


@pytest.mark.parametrize(
    ("name", "full"),
    [
        ("/livox/lidar", "/livox/lidar"),
        ("livox/lidar", "/livox/lidar"),
        ("/tf", "/tf"),
        ("/_private/x_1", "/_private/x_1"),
        ("/a/B9", "/a/B9"),
    ],
)
def test_valid_topic_names_are_fully_qualified(name: str, full: str) -> None:
    assert ros_topic_name(name) == full
    assert dds_topic(name) == "rt" + full
    assert ros_topic("rt" + full) == full


@pytest.mark.parametrize(
    ("name", "rule"),
    [
        ("", "empty"),
        ("/", "namespace"),
        ("/livox/", "end with"),
        ("//livox", "repeat '/'"),
        ("/livox//lidar", "repeat '/'"),
        ("/li__dar", "repeat '_'"),
        ("/9lidar", "not a token"),
        ("/livox/1", "not a token"),
        ("/li-dar", "not a token"),
        ("/li dar", "not a token"),
        ("~/lidar", "not a token"),
        ("/{node}/x", "not a token"),
    ],
)
def test_topic_names_breaking_a_rule_are_refused(name: str, rule: str) -> None:
    with pytest.raises(ConfigError, match=rule):
        ros_topic_name(name)


_token = st.from_regex(r"[A-Za-z_][A-Za-z0-9_]{0,8}", fullmatch=True).filter(
    lambda t: "__" not in t
)


@given(st.lists(_token, min_size=1, max_size=4))
def test_topic_mapping_round_trips(tokens: list[str]) -> None:
    name = "/" + "/".join(tokens)
    if "__" in name:  # two tokens' underscores meet across no slash: impossible
        return
    assert ros_topic(dds_topic(name)) == name


def test_non_ros_dds_topics_have_no_ros_name() -> None:
    assert ros_topic("rq/add_two_intsRequest") is None
    assert ros_topic("DCPSParticipant") is None
    assert ros_topic("rt/bad//name") is None


@pytest.mark.parametrize(
    ("ros", "dds"),
    [
        ("sensor_msgs/msg/PointCloud2", "sensor_msgs::msg::dds_::PointCloud2_"),
        ("livox_ros_driver2/msg/CustomMsg", "livox_ros_driver2::msg::dds_::CustomMsg_"),
        ("tf2_msgs/msg/TFMessage", "tf2_msgs::msg::dds_::TFMessage_"),
        ("interbotix_xs_msgs/msg/JointGroupCommand",
         "interbotix_xs_msgs::msg::dds_::JointGroupCommand_"),
    ],
)  # fmt: skip
def test_type_names_map_to_dds_and_back(ros: str, dds: str) -> None:
    assert dds_type(ros) == dds
    assert ros_type(dds) == ros
    pkg, msg = check_type_name(ros)
    assert dds_type(f"{pkg}/{msg}") == dds  # pkg/Name is pkg/msg/Name


@pytest.mark.parametrize(
    "name",
    ["sensor_msgs/srv/PointCloud2", "Sensor_msgs/msg/X", "sensor__msgs/msg/X", "a/msg/lower",
     "pkg/msg/", "pkg_/msg/X", "x"],
)  # fmt: skip
def test_bad_type_names_are_refused(name: str) -> None:
    with pytest.raises(ConfigError):
        check_type_name(name)
    assert ros_type(name.replace("/msg/", "::msg::dds_::") + "_") is None


def test_ros2_uris() -> None:
    uri = parse_ros2_uri("ros2:///livox/lidar?type=sensor_msgs/PointCloud2&truth=/gt&frame=world")
    assert (uri.topic, uri.msg_type, uri.truth, uri.frame) == (
        "/livox/lidar",
        "sensor_msgs/msg/PointCloud2",
        "/gt",
        "world",
    )
    assert parse_ros2_uri("ros2://").topic is None
    for bad, why in [
        ("ros2://host/livox", "no host"),
        ("ros2:///livox//lidar", "repeat"),
        ("ros2:///x?colour=red", "unknown key"),
        ("ros2:///x?type=bad", "pkg/msg/Name"),
    ]:
        with pytest.raises(ConfigError, match=why):
            parse_ros2_uri(bad)


# --- the IDL mirrors against rosbags ---------------------------------------------------


def _idl() -> object:
    pytest.importorskip("cyclonedds")
    from dronetrack.formats.ros import idl as ros2_idl

    return ros2_idl


def _padded(raw: bytes) -> bytes:
    return raw + b"\0" * (-len(raw) % 4)


def _messages() -> dict[str, bytes]:
    rng = np.random.default_rng(3)
    T = np.eye(4)
    T[:3, 3] = (1.0, -2.0, 0.5)
    from dronetrack.formats.ros.livox_msg import LIVOX_POINT, LivoxCloud, encode_livox_cdr

    pts = np.zeros(5, dtype=LIVOX_POINT)
    pts["x"], pts["offset_time"], pts["line"] = rng.normal(size=5), np.arange(5) * 1000, 3
    return {
        "sensor_msgs/msg/PointCloud2": encode_points(
            1_767_225_600_500_000_000, "lidar", rng.normal(size=(7, 3)), np.linspace(0, 0.1, 7)
        ),
        "livox_ros_driver2/msg/CustomMsg": encode_livox_cdr(
            LivoxCloud(1_767_225_600_000_000_001, "lidar", 1_767_225_600_000_000_001, pts)
        ),
        "tf2_msgs/msg/TFMessage": encode_tf(5_000_000_123, [("world", "a", T), ("a", "b", T)]),
        "sensor_msgs/msg/JointState": encode_joint_state(7, ["pan", "tilt"], [0.1, -0.2]),
        "geometry_msgs/msg/PointStamped": encode_point_stamped(9, "world", np.array([1, 2, 3])),
        "nav_msgs/msg/Path": encode_path(9, "world", rng.normal(size=(3, 3))),
        "interbotix_xs_msgs/msg/JointGroupCommand": encode_joint_command("turret", [0.5, -0.25]),
        "visualization_msgs/msg/MarkerArray": encode_marker_array(
            11,
            "world",
            [
                MarkerSpec("tracks", 4, "sphere", (1.0, 2.0, 3.0), 0.6, (0.9, 0.2, 0.8, 0.6)),
                MarkerSpec("track_labels", 4, "text", (1.0, 2.0, 4.0), 1.0, text="4 drone"),
                MarkerSpec("tracks", 9, "delete"),
            ],
        ),
    }


@pytest.mark.parametrize("msg_type", list(_messages()))
def test_idl_mirrors_serialise_as_rosbags_does(msg_type: str) -> None:
    """cyclonedds' own codec reads rosbags' bytes and writes them back unchanged."""
    ros2_idl = _idl()
    cls = ros2_idl.IDL_TYPES[msg_type]  # type: ignore[attr-defined]
    raw = _messages()[msg_type]
    sample = cls.deserialize(raw)
    assert _padded(sample.serialize()) == _padded(raw)
    assert ros2_typestore().deserialize_cdr(sample.serialize(), msg_type) is not None


def test_idl_sample_built_field_by_field_equals_rosbags() -> None:
    """A JointGroupCommand and a PointStamped made from values, not from bytes."""
    m = _idl()
    cmd = m.JointGroupCommand(name="turret", cmd=[0.5, -0.25])  # type: ignore[attr-defined]
    assert _padded(cmd.serialize()) == _padded(encode_joint_command("turret", [0.5, -0.25]))
    header = m.Header(stamp=m.Time(sec=0, nanosec=9), frame_id="world")  # type: ignore[attr-defined]
    ps = m.PointStamped(header=header, point=m.Point(x=1.0, y=2.0, z=3.0))  # type: ignore[attr-defined]
    assert _padded(ps.serialize()) == _padded(encode_point_stamped(9, "world", np.array([1, 2, 3])))


# --- the small messages from bytes built by hand ---------------------------------------


def _string(s: str, at: int) -> bytes:
    """A CDR string at offset ``at`` of the body (after the 4-byte header): aligned u32
    length counting the NUL, the bytes, the NUL."""
    pad = b"\0" * (-at % 4)
    data = s.encode() + b"\0"
    return pad + struct.pack("<I", len(data)) + data


def test_tf_from_hand_built_bytes() -> None:
    """TFMessage with one transform: sequence length, Header (Time sec i32, nanosec u32,
    frame_id), child_frame_id, translation and rotation as 8-aligned float64s."""
    body = struct.pack("<I", 1) + struct.pack("<iI", 12, 345)
    body += _string("world", len(body))
    body += _string("turret_base", len(body))
    body += b"\0" * (-len(body) % 8)
    body += struct.pack("<7d", 1.0, 2.0, 3.0, 0.0, 0.0, 0.6, 0.8)
    [s] = decode_tf(b"\x00\x01\x00\x00" + body)
    assert (s.stamp_ns, s.parent, s.child) == (12_000_000_345, "world", "turret_base")
    assert s.translation == (1.0, 2.0, 3.0)
    assert s.rotation_xyzw == (0.0, 0.0, 0.6, 0.8)
    with pytest.raises(DecodeError):
        decode_tf(b"\x00\x01\x00\x00" + body[:20])


def test_joint_state_from_hand_built_bytes() -> None:
    body = struct.pack("<iI", 1, 2) + _string("", 8)
    body += b"\0" * (-len(body) % 4) + struct.pack("<I", 2)
    body += _string("pan", len(body))
    body += _string("tilt", len(body))
    body += b"\0" * (-len(body) % 4) + struct.pack("<I", 2)
    body += b"\0" * (-len(body) % 8) + struct.pack("<2d", 0.25, -0.5)
    body += struct.pack("<I", 0) + struct.pack("<I", 0)  # no velocity, no effort
    reading = decode_joint_state(b"\x00\x01\x00\x00" + body)
    assert reading.stamp_ns == 1_000_000_002
    assert reading.position == {"pan": 0.25, "tilt": -0.5}
    assert all(np.isnan(v) for v in reading.velocity.values())


def test_joint_state_round_trip_and_bad_counts() -> None:
    r = decode_joint_state(encode_joint_state(5, ["pan", "tilt"], [0.1, 0.2], [1.0, 2.0]))
    assert r.position == {"pan": 0.1, "tilt": 0.2}
    assert r.velocity == {"pan": 1.0, "tilt": 2.0}
    with pytest.raises(DecodeError, match="names"):
        decode_joint_state(encode_joint_state(5, ["pan", "tilt"], [0.1]))
