"""Livox CustomMsg decoders and encoders against rosbags' own (de)serializers."""

from __future__ import annotations

import struct
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import DecodeError, InputError
from dronetrack.formats.ros.livox_msg import (
    CUSTOM_MSG_MSG,
    CUSTOM_POINT_MSG,
    LIVOX_POINT,
    LIVOX_TYPES,
    LivoxCloud,
    decode_livox_cdr,
    decode_livox_ros1,
    encode_livox_cdr,
    encode_livox_ros1,
    livox_points,
    livox_typestore,
    register_livox_types,
)

rosbags_typesys = pytest.importorskip("rosbags.typesys")

ROS1_TYPE, ROS2_TYPE = "livox_ros_driver/msg/CustomMsg", "livox_ros_driver2/msg/CustomMsg"
TS1, TS2 = livox_typestore(ros1=True), livox_typestore(ros1=False)
NAMES = LIVOX_POINT.names or ()


def _random_points(n: int, rng: np.random.Generator) -> np.ndarray:
    pts = np.zeros(n, dtype=LIVOX_POINT)
    pts["offset_time"] = np.sort(rng.integers(0, 100_000_000, n))
    for axis in ("x", "y", "z"):
        pts[axis] = rng.uniform(-200, 200, n)
    pts["reflectivity"] = rng.integers(0, 256, n)
    pts["tag"] = rng.integers(0, 256, n)
    pts["line"] = rng.integers(0, 6, n)
    return pts


def _rosbags_msg(cloud: LivoxCloud, ros1: bool, seq: int = 0) -> Any:
    """The same cloud as a rosbags message object (one Python object per point)."""
    ts, pkg = (TS1, "livox_ros_driver") if ros1 else (TS2, "livox_ros_driver2")
    Header, Time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    Point = ts.types[f"{pkg}/msg/CustomPoint"]
    sec, nsec = divmod(cloud.stamp_ns, 1_000_000_000)
    stamp = Time(sec=sec, nanosec=nsec)
    header = (
        Header(seq=seq, stamp=stamp, frame_id=cloud.frame_id)
        if ros1
        else Header(stamp=stamp, frame_id=cloud.frame_id)
    )
    points = [Point(**{name: p[name].item() for name in NAMES}) for p in np.asarray(cloud.points)]
    return ts.types[f"{pkg}/msg/CustomMsg"](
        header=header,
        timebase=cloud.timebase_ns,
        point_num=len(points),
        lidar_id=cloud.lidar_id,
        rsvd=np.zeros(3, dtype=np.uint8),
        points=points,
    )


def _assert_same(cloud: LivoxCloud, msg: Any) -> None:
    """A decoded cloud equals a rosbags message field by field, exactly."""
    assert cloud.stamp_ns == msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
    assert cloud.frame_id == msg.header.frame_id
    assert cloud.timebase_ns == msg.timebase
    assert cloud.lidar_id == msg.lidar_id
    assert len(cloud.points) == msg.point_num == len(msg.points)
    assert cloud.points.dtype == LIVOX_POINT
    for name in NAMES:
        want = np.array([getattr(p, name) for p in msg.points], dtype=LIVOX_POINT[name])
        np.testing.assert_array_equal(cloud.points[name], want)


def _cloud(n: int, frame_id: str = "livox_frame", seed: int = 0) -> LivoxCloud:
    rng = np.random.default_rng(seed)
    stamp = 1_700_000_000_123_456_789
    return LivoxCloud(stamp, frame_id, stamp - 50_000_000, _random_points(n, rng), lidar_id=3)


# ---------------------------------------------------------------- types


def test_types_register_on_both_stores_and_twice() -> None:
    for ts in (TS1, TS2):
        assert set(ts.types) >= LIVOX_TYPES
        assert {t.replace("CustomMsg", "CustomPoint") for t in LIVOX_TYPES} <= set(ts.types)
        register_livox_types(ts)  # the same definitions again: accepted
    assert "uint8 line" in CUSTOM_POINT_MSG
    assert "CustomPoint[] points" in CUSTOM_MSG_MSG
    assert LIVOX_POINT.itemsize == 19


# ---------------------------------------------------------------- known answers


@pytest.mark.parametrize("n", [0, 1, 2, 25])
@pytest.mark.parametrize("frame_id", ["", "a", "livox_frame", "lidar_ø"])
@pytest.mark.parametrize("little", [True, False])
def test_cdr_decode_matches_rosbags(n: int, frame_id: str, little: bool) -> None:
    msg = _rosbags_msg(_cloud(n, frame_id, seed=n), ros1=False)
    raw = bytes(TS2.serialize_cdr(msg, ROS2_TYPE, little_endian=little))
    cloud = decode_livox_cdr(raw)
    _assert_same(cloud, TS2.deserialize_cdr(raw, ROS2_TYPE))
    # and from the other buffer kinds a reader may hand over
    for kind in (memoryview(raw), np.frombuffer(raw, np.uint8), bytearray(raw)):
        np.testing.assert_array_equal(decode_livox_cdr(kind).points, cloud.points)


@pytest.mark.parametrize("n", [0, 1, 25])
@pytest.mark.parametrize("frame_id", ["", "livox_frame", "lidar_ø"])
def test_ros1_decode_matches_rosbags(n: int, frame_id: str) -> None:
    msg = _rosbags_msg(_cloud(n, frame_id, seed=n), ros1=True, seq=41)
    raw = bytes(TS1.serialize_ros1(msg, ROS1_TYPE))
    _assert_same(decode_livox_ros1(raw), TS1.deserialize_ros1(raw, ROS1_TYPE))


def test_cdr_points_are_a_strided_view() -> None:
    raw = encode_livox_cdr(_cloud(5))
    cloud = decode_livox_cdr(raw)
    assert cloud.points.strides == (20,)
    assert np.shares_memory(cloud.points, np.frombuffer(raw, np.uint8))
    # encapsulation, 40 B of header..rsvd for an 11-character frame_id, length, records
    assert len(raw) == 4 + 40 + 4 + 20 * 5 - 1


@pytest.mark.parametrize("n", [0, 1, 25])
@pytest.mark.parametrize("frame_id", ["", "abc", "livox_frame"])
def test_encoders_are_byte_identical_to_rosbags(n: int, frame_id: str) -> None:
    cloud = _cloud(n, frame_id, seed=n)
    cdr = encode_livox_cdr(cloud)
    ros1 = encode_livox_ros1(cloud, seq=9)
    assert cdr == bytes(
        TS2.serialize_cdr(_rosbags_msg(cloud, False), ROS2_TYPE, little_endian=True)
    )
    assert ros1 == bytes(TS1.serialize_ros1(_rosbags_msg(cloud, True, seq=9), ROS1_TYPE))
    _assert_same(cloud, TS2.deserialize_cdr(cdr, ROS2_TYPE))
    _assert_same(cloud, TS1.deserialize_ros1(ros1, ROS1_TYPE))
    assert TS1.deserialize_ros1(ros1, ROS1_TYPE).header.seq == 9


def test_livox_points_known_answer() -> None:
    pts = np.zeros(3, dtype=LIVOX_POINT)
    pts["offset_time"] = [0, 1_000_000, 99_000_000]  # ns after timebase
    pts["x"], pts["y"], pts["z"] = [1.5, 2.0, -3.0], [0.25, 0.0, 1.0], [-1.0, 4.0, 0.5]
    pts["reflectivity"], pts["line"] = [0, 128, 255], [0, 3, 5]
    stamp = 1_700_000_000_000_000_000
    # timebase 20 ms before the header stamp: t_rel = (timebase + offset - stamp) · 1e-9
    xyz, t_rel, refl, line = livox_points(LivoxCloud(stamp, "f", stamp - 20_000_000, pts))
    np.testing.assert_array_equal(xyz, [[1.5, 0.25, -1.0], [2.0, 0.0, 4.0], [-3.0, 1.0, 0.5]])
    np.testing.assert_allclose(t_rel, [-0.020, -0.019, 0.079], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(refl, [0.0, 128.0, 255.0])
    np.testing.assert_array_equal(line, [0, 3, 5])
    assert xyz.dtype == t_rel.dtype == np.float64
    assert refl.dtype == np.float32
    assert line.dtype == np.uint8


def test_big_endian_points_come_out_native() -> None:
    msg = _rosbags_msg(_cloud(4), ros1=False)
    cloud = decode_livox_cdr(bytes(TS2.serialize_cdr(msg, ROS2_TYPE, little_endian=False)))
    xyz, _, _, _ = livox_points(cloud)
    np.testing.assert_array_equal(xyz[:, 0], [p.x for p in msg.points])


def test_negative_stamp_in_cdr() -> None:
    cloud = LivoxCloud(-1_500_000_000, "f", 0, np.zeros(1, LIVOX_POINT))
    back = decode_livox_cdr(encode_livox_cdr(cloud))
    assert back.stamp_ns == -1_500_000_000


# ---------------------------------------------------------------- encoder input checks


@pytest.mark.parametrize(
    ("cloud", "message"),
    [
        (LivoxCloud(0, "f", 0, np.zeros(1, LIVOX_POINT), lidar_id=256), "lidar_id 256"),
        (LivoxCloud(0, "f", -1, np.zeros(1, LIVOX_POINT)), "timebase -1"),
        (LivoxCloud(0, "a\0b", 0, np.zeros(1, LIVOX_POINT)), "NUL"),
        (LivoxCloud(2**80, "f", 0, np.zeros(1, LIVOX_POINT)), "out of range"),
        (LivoxCloud(0, "f", 0, np.zeros(1, [("x", "f4")])), "missing"),
    ],
)
def test_encoders_reject_unrepresentable_clouds(cloud: LivoxCloud, message: str) -> None:
    with pytest.raises(InputError, match=message):
        encode_livox_cdr(cloud)
    with pytest.raises(InputError, match=message):
        encode_livox_ros1(cloud)


def test_ros1_rejects_negative_stamp_and_bad_seq() -> None:
    with pytest.raises(InputError, match="out of range"):
        encode_livox_ros1(LivoxCloud(-1, "f", 0, np.zeros(0, LIVOX_POINT)))
    with pytest.raises(InputError, match="seq"):
        encode_livox_ros1(LivoxCloud(0, "f", 0, np.zeros(0, LIVOX_POINT)), seq=-1)


# ---------------------------------------------------------------- properties


clouds = st.builds(
    lambda n, frame_id, stamp, dt, lidar_id, seed: LivoxCloud(
        stamp, frame_id, stamp + dt, _random_points(n, np.random.default_rng(seed)), lidar_id
    ),
    n=st.integers(0, 40),
    frame_id=st.text(st.characters(exclude_characters="\0"), max_size=12),
    stamp=st.integers(0, 2**31 - 1).map(lambda s: s * 1_000_000_000 + 999_999_999),
    dt=st.integers(-(10**9), 10**9),
    lidar_id=st.integers(0, 255),
    seed=st.integers(0, 1000),
)


def _same_cloud(a: LivoxCloud, b: LivoxCloud) -> None:
    assert (a.stamp_ns, a.frame_id, a.timebase_ns, a.lidar_id) == (
        b.stamp_ns,
        b.frame_id,
        b.timebase_ns,
        b.lidar_id,
    )
    assert a.points.tobytes() == np.ascontiguousarray(b.points).tobytes()


@settings(max_examples=60)
@given(cloud=clouds)
def test_encode_decode_roundtrip(cloud: LivoxCloud) -> None:
    _same_cloud(decode_livox_cdr(encode_livox_cdr(cloud)), cloud)
    _same_cloud(decode_livox_ros1(encode_livox_ros1(cloud)), cloud)


@settings(max_examples=20)
@given(cloud=clouds)
def test_encoders_agree_with_rosbags(cloud: LivoxCloud) -> None:
    _assert_same(cloud, TS2.deserialize_cdr(encode_livox_cdr(cloud), ROS2_TYPE))
    _assert_same(cloud, TS1.deserialize_ros1(encode_livox_ros1(cloud), ROS1_TYPE))


# ---------------------------------------------------------------- fuzz and corruption


def _decoders() -> list[tuple[str, Any, Any]]:
    return [
        ("cdr", encode_livox_cdr, decode_livox_cdr),
        ("ros1", encode_livox_ros1, decode_livox_ros1),
    ]


def _decodes_consistently(decode: Any, raw: bytes) -> None:
    """Either a DecodeError or a cloud whose point count accounts for every byte."""
    try:
        cloud = decode(raw)
    except DecodeError:
        return
    assert isinstance(cloud, LivoxCloud)
    assert cloud.points.dtype == LIVOX_POINT
    assert cloud.points.ndim == 1
    # the canonical encoding of what was decoded has the same size (CDR: up to 3 B of padding)
    if decode is decode_livox_cdr:
        assert 0 <= len(raw) - len(encode_livox_cdr(cloud)) <= 3
    else:
        assert len(raw) == len(encode_livox_ros1(cloud))


@settings(max_examples=150)
@given(
    raw=st.binary(max_size=120),
    head=st.sampled_from([b"", b"\x00\x01\x00\x00", b"\x00\x00\x00\x00"]),
)
def test_random_bytes(raw: bytes, head: bytes) -> None:
    _decodes_consistently(decode_livox_cdr, head + raw)
    _decodes_consistently(decode_livox_ros1, head + raw)


@settings(max_examples=60)
@given(
    n=st.integers(0, 6),
    frame_id=st.sampled_from(["", "ab", "livox_frame"]),
    position=st.integers(0, 10_000),
    value=st.integers(0, 255),
)
def test_flipped_bytes(n: int, frame_id: str, position: int, value: int) -> None:
    for _, encode, decode in _decoders():
        raw = bytearray(encode(_cloud(n, frame_id)))
        raw[position % len(raw)] = value
        _decodes_consistently(decode, bytes(raw))


@pytest.mark.parametrize(("kind", "encode", "decode"), _decoders())
@pytest.mark.parametrize("n", [0, 1, 3])
def test_every_truncation_raises(kind: str, encode: Any, decode: Any, n: int) -> None:
    raw = encode(_cloud(n))
    for k in range(len(raw)):
        with pytest.raises(DecodeError):
            decode(raw[:k])


@pytest.mark.parametrize(("kind", "encode", "decode"), _decoders())
def test_trailing_bytes(kind: str, encode: Any, decode: Any) -> None:
    raw = encode(_cloud(2))
    allowed = 3 if kind == "cdr" else 0  # CDR may be padded to a 4-byte boundary
    decode(raw + bytes(allowed))
    with pytest.raises(DecodeError, match="bytes after its 2 points"):
        decode(raw + bytes(allowed + 1))


def _field_positions(kind: str, frame_id: str) -> tuple[int, int]:
    """Byte positions of point_num and of the points length in an encoded message."""
    if kind == "cdr":
        fixed = 4 + 12 + len(frame_id) + 1  # header, stamp, frame_id length, frame_id + NUL
        timebase = 4 + -(-(fixed - 4) // 8) * 8
    else:
        timebase = 16 + len(frame_id)
    return timebase + 8, timebase + 16


@pytest.mark.parametrize(("kind", "encode", "decode"), _decoders())
@pytest.mark.parametrize("frame_id", ["", "ab", "livox_frame"])
def test_wrong_counts_raise(kind: str, encode: Any, decode: Any, frame_id: str) -> None:
    raw = bytearray(encode(_cloud(4, frame_id)))
    num_at, len_at = _field_positions(kind, frame_id)
    assert struct.unpack_from("<II", raw, num_at)[0] == 4
    assert struct.unpack_from("<I", raw, len_at)[0] == 4
    for count in (3, 5, 2**32 - 1):
        wrong_num = bytearray(raw)
        struct.pack_into("<I", wrong_num, num_at, count)
        with pytest.raises(DecodeError, match="point_num"):
            decode(bytes(wrong_num))
        wrong_len = bytearray(raw)
        struct.pack_into("<I", wrong_len, len_at, count)
        with pytest.raises(DecodeError):
            decode(bytes(wrong_len))


def test_malformed_headers_and_strings() -> None:
    raw = encode_livox_cdr(_cloud(1, "ab"))
    with pytest.raises(DecodeError, match="encapsulation"):
        decode_livox_cdr(b"\x00\x02" + raw[2:])  # parameter-list CDR is not supported
    with pytest.raises(DecodeError, match="NUL-terminated"):
        decode_livox_cdr(raw[:18] + b"X" + raw[19:])  # frame_id "ab" + NUL at 16..18
    with pytest.raises(DecodeError, match="UTF-8"):
        decode_livox_cdr(raw[:16] + b"\xff" + raw[17:])
    ros1 = encode_livox_ros1(_cloud(1, "ab"))
    with pytest.raises(DecodeError, match="UTF-8"):
        decode_livox_ros1(ros1[:16] + b"\xff" + ros1[17:])
    with pytest.raises(DecodeError, match="frame_id"):
        decode_livox_ros1(ros1[:12] + struct.pack("<I", 10**6) + ros1[16:])
    with pytest.raises(DecodeError, match="array of float64"):
        decode_livox_cdr(np.zeros(4))
    with pytest.raises(DecodeError, match="not a byte buffer"):
        decode_livox_ros1("text")  # type: ignore[arg-type]
