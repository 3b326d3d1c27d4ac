"""PointCloud2 messages read from their bytes agree with rosbags; bad bytes raise DecodeError."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from rosbags.typesys import Stores, get_typestore

from dronetrack.errors import DecodeError
from dronetrack.formats.ros.pointcloud2 import Field
from dronetrack.formats.ros.pointcloud2_raw import decode_pointcloud2_cdr, decode_pointcloud2_ros1

TS2 = get_typestore(Stores.ROS2_HUMBLE)
TS1 = get_typestore(Stores.ROS1_NOETIC)
TYPE = "sensor_msgs/msg/PointCloud2"


def _message(
    ts: Any,
    ros1: bool,
    fields: list[Field],
    width: int,
    step: int,
    data: bytes,
    frame: str,
    big: bool,
) -> Any:
    T = ts.types
    stamp = T["builtin_interfaces/msg/Time"](sec=1_700_000_123, nanosec=456_789)
    header = (
        T["std_msgs/msg/Header"](seq=9, stamp=stamp, frame_id=frame)
        if ros1
        else T["std_msgs/msg/Header"](stamp=stamp, frame_id=frame)
    )
    return T[TYPE](
        header=header,
        height=1,
        width=width,
        fields=[
            T["sensor_msgs/msg/PointField"](
                name=f.name, offset=f.offset, datatype=f.datatype, count=f.count
            )
            for f in fields
        ],
        is_bigendian=big,
        point_step=step,
        row_step=step * width,
        data=np.frombuffer(data, np.uint8),
        is_dense=False,
    )


layouts = st.lists(
    st.tuples(
        st.sampled_from(["x", "y", "z", "intensity", "ring", "t", "a b", "é"]),
        st.integers(1, 8),
        st.integers(0, 3),
    ),
    min_size=0,
    max_size=6,
    unique_by=lambda f: f[0],
)


@settings(max_examples=60)
@given(
    layouts,
    st.integers(0, 20),
    st.integers(0, 8),
    st.text(max_size=12),
    st.booleans(),
    st.sampled_from(["cdr-le", "cdr-be", "ros1"]),
)
def test_header_fields_and_data_agree_with_rosbags(
    layout: list[tuple[str, int, int]], width: int, pad: int, frame: str, big: bool, kind: str
) -> None:
    fields = [
        Field(name, 4 * i, datatype, count) for i, (name, datatype, count) in enumerate(layout)
    ]
    step = 4 * len(fields) + pad
    data = np.random.default_rng(width).integers(0, 256, step * width, dtype=np.uint8).tobytes()
    ros1 = kind == "ros1"
    ts = TS1 if ros1 else TS2
    msg = _message(ts, ros1, fields, width, step, data, frame, big)
    if ros1:
        raw = ts.serialize_ros1(msg, TYPE)
        got = decode_pointcloud2_ros1(raw)
    else:
        raw = ts.serialize_cdr(msg, TYPE, little_endian=kind == "cdr-le")
        got = decode_pointcloud2_cdr(raw)
    assert got.stamp_ns == 1_700_000_123 * 10**9 + 456_789
    assert got.frame_id == frame
    assert got.fields == fields
    assert (got.width, got.height, got.point_step, got.row_step, got.bigendian) == (
        width,
        1,
        step,
        step * width,
        big,
    )
    assert bytes(got.data) == data


def _valid_cdr() -> bytes:
    fields = [Field("x", 0, 7), Field("y", 4, 7), Field("z", 8, 7)]
    data = np.arange(12, dtype="<f4").tobytes()
    raw: bytes = TS2.serialize_cdr(_message(TS2, False, fields, 4, 12, data, "lidar", False), TYPE)
    return raw


def test_the_points_decode() -> None:
    cloud = decode_pointcloud2_cdr(_valid_cdr())
    arr = cloud.array()
    np.testing.assert_array_equal(arr["x"], [0, 3, 6, 9])
    np.testing.assert_array_equal(arr["z"], [2, 5, 8, 11])


@settings(max_examples=150)
@given(st.data())
def test_corrupt_messages_raise_decode_errors_only(data: st.DataObject) -> None:
    raw = bytearray(_valid_cdr())
    how = data.draw(st.sampled_from(["truncate", "flip", "random", "extend"]))
    if how == "truncate":
        raw = raw[: data.draw(st.integers(0, len(raw) - 1))]
    elif how == "flip":
        for i in data.draw(st.lists(st.integers(0, len(raw) - 1), min_size=1, max_size=8)):
            raw[i] ^= data.draw(st.integers(1, 255))
    elif how == "random":
        raw = bytearray(data.draw(st.binary(max_size=300)))
    else:
        raw += bytes(data.draw(st.integers(4, 40)))
    error = None
    try:
        cloud = decode_pointcloud2_cdr(bytes(raw))
        cloud.array()
    except DecodeError as err:
        error = str(err)
    if error is None:
        # What still decodes is self-consistent: the data hold exactly the points.
        assert len(cloud.data) == cloud.row_step * cloud.height
    else:
        assert "\n" not in error


def test_truncations_always_fail() -> None:
    raw = _valid_cdr()
    for n in range(len(raw) - 3):  # CDR allows up to 3 padding bytes at the end
        with pytest.raises(DecodeError):
            decode_pointcloud2_cdr(raw[:n]).array()
