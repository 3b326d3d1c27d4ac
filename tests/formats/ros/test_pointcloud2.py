"""PointCloud2 decoding against rosbags' serializer and an independent struct-based reference."""

from __future__ import annotations

import struct
import warnings
from typing import Any

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from dronetrack.errors import DecodeError, InputError
from dronetrack.formats.ros.pointcloud2 import (
    ENCODED_POINT_STEP,
    POINTFIELD_TYPES,
    CloudPoints,
    Field,
    cloud_dtype,
    cloud_points,
    decode_cloud,
    encode_cloud,
    fields_from_msg,
)

rosbags_typesys = pytest.importorskip("rosbags.typesys")
Stores, get_typestore = rosbags_typesys.Stores, rosbags_typesys.get_typestore

PC2 = "sensor_msgs/msg/PointCloud2"
STAMP = 1_700_000_123.25  # header stamp [s]
# struct format characters of the PointField datatypes (an independent reference)
STRUCT_CODES = {1: "b", 2: "B", 3: "h", 4: "H", 5: "i", 6: "I", 7: "f", 8: "d"}
SIZES = {k: struct.calcsize(c) for k, c in STRUCT_CODES.items()}

# velodyne_pointcloud PointXYZIRT: x, y, z (+4 B pad), intensity, ring, time; 32 B
VELODYNE = [
    Field("x", 0, 7),
    Field("y", 4, 7),
    Field("z", 8, 7),
    Field("intensity", 16, 7),
    Field("ring", 20, 4),
    Field("time", 24, 7),
]
VELODYNE_STEP = 32


def _velodyne_records(n: int, bigendian: bool, rng: np.random.Generator) -> np.ndarray:
    o = ">" if bigendian else "<"
    dt = np.dtype(
        {
            "names": ["x", "y", "z", "intensity", "ring", "time"],
            "formats": [o + "f4"] * 4 + [o + "u2", o + "f4"],
            "offsets": [0, 4, 8, 16, 20, 24],
            "itemsize": VELODYNE_STEP,
        }
    )
    rec = np.zeros(n, dtype=dt)
    for name in ("x", "y", "z"):
        rec[name] = rng.uniform(-50, 50, n)
    rec["intensity"] = rng.uniform(0, 255, n)
    rec["ring"] = rng.integers(0, 16, n)
    rec["time"] = rng.uniform(-0.1, 0.0, n)
    return rec


def _pc2_msg(
    ts: Any,
    fields: list[Field],
    data: bytes,
    width: int,
    height: int,
    point_step: int,
    row_step: int,
    bigendian: bool,
    ros1: bool,
) -> Any:
    Header, Time = ts.types["std_msgs/msg/Header"], ts.types["builtin_interfaces/msg/Time"]
    PointField = ts.types["sensor_msgs/msg/PointField"]
    sec = int(STAMP)
    stamp = Time(sec=sec, nanosec=round((STAMP - sec) * 1e9))
    header = (
        Header(seq=3, stamp=stamp, frame_id="velodyne")
        if ros1
        else Header(stamp=stamp, frame_id="velodyne")
    )
    return ts.types[PC2](
        header=header,
        height=height,
        width=width,
        fields=[
            PointField(name=f.name, offset=f.offset, datatype=f.datatype, count=f.count)
            for f in fields
        ],
        is_bigendian=bigendian,
        point_step=point_step,
        row_step=row_step,
        data=np.frombuffer(data, dtype=np.uint8),
        is_dense=True,
    )


def _roundtrip_rosbags(ts: Any, msg: Any, ros1: bool, little: bool = True) -> Any:
    if ros1:
        return ts.deserialize_ros1(bytes(ts.serialize_ros1(msg, PC2)), PC2)
    return ts.deserialize_cdr(bytes(ts.serialize_cdr(msg, PC2, little_endian=little)), PC2)


def _decode_msg(msg: Any) -> np.ndarray:
    return decode_cloud(
        fields_from_msg(msg),
        msg.data,
        msg.width,
        msg.height,
        msg.point_step,
        msg.row_step,
        msg.is_bigendian,
    )


# ---------------------------------------------------------------- known answers


@pytest.mark.parametrize(
    ("ros1", "bigendian", "little_cdr", "row_pad"),
    [
        (False, False, True, 0),
        (False, True, True, 0),
        (False, False, False, 12),
        (True, False, True, 0),
        (True, True, True, 5),
    ],
)
def test_velodyne_cloud_through_rosbags(
    rng: np.random.Generator, ros1: bool, bigendian: bool, little_cdr: bool, row_pad: int
) -> None:
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    width, height = 7, 3
    rec = _velodyne_records(width * height, bigendian, rng)
    row_step = width * VELODYNE_STEP + row_pad
    rows = rec.view(np.uint8).reshape(height, width * VELODYNE_STEP)
    padded = np.zeros((height, row_step), dtype=np.uint8)
    padded[:, : width * VELODYNE_STEP] = rows
    msg = _pc2_msg(
        ts, VELODYNE, padded.tobytes(), width, height, VELODYNE_STEP, row_step, bigendian, ros1
    )
    back = _roundtrip_rosbags(ts, msg, ros1, little_cdr)

    arr = _decode_msg(back)
    assert arr.shape == (width * height,)
    for name in ("x", "y", "z", "intensity", "ring", "time"):
        np.testing.assert_array_equal(arr[name], rec[name])

    cp = cloud_points(arr, STAMP)
    assert cp.points.dtype == np.float64
    assert cp.points.dtype.isnative
    np.testing.assert_allclose(
        cp.points, np.stack([rec["x"], rec["y"], rec["z"]], axis=1), rtol=0, atol=1e-6
    )
    assert cp.t is not None
    np.testing.assert_allclose(cp.t, rec["time"], rtol=0, atol=1e-6)  # already relative [s]
    np.testing.assert_array_equal(cp.intensity, rec["intensity"].astype(np.float32))
    np.testing.assert_array_equal(cp.line, rec["ring"])


@pytest.mark.parametrize("ros1", [False, True])
@pytest.mark.parametrize("bigendian", [False, True])
def test_encoded_cloud_deserializes_with_rosbags(
    rng: np.random.Generator, ros1: bool, bigendian: bool
) -> None:
    n = 50
    pts = rng.uniform(-30, 30, (n, 3))
    t_rel = np.sort(rng.uniform(0, 0.1, n))
    intensity = rng.integers(0, 256, n).astype(np.float64)
    line = rng.integers(0, 6, n)
    fields, data, step = encode_cloud(pts, t_rel, intensity, line, STAMP, bigendian=bigendian)
    assert step == ENCODED_POINT_STEP
    assert len(data) == n * step
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    msg = _pc2_msg(ts, fields, data, n, 1, step, n * step, bigendian, ros1)
    back = _roundtrip_rosbags(ts, msg, ros1)
    assert [(f.name, f.offset, f.datatype, f.count) for f in back.fields] == [
        ("x", 0, 7, 1),
        ("y", 4, 7, 1),
        ("z", 8, 7, 1),
        ("intensity", 12, 7, 1),
        ("tag", 16, 2, 1),
        ("line", 17, 2, 1),
        ("timestamp", 24, 8, 1),
    ]
    cp = cloud_points(_decode_msg(back), STAMP)
    np.testing.assert_allclose(cp.points, pts, rtol=1e-6, atol=1e-5)  # float32 storage
    assert cp.t is not None
    np.testing.assert_allclose(cp.t, t_rel, rtol=0, atol=1e-6)  # float64 ns: ≈ 256 ns
    np.testing.assert_array_equal(cp.intensity, intensity.astype(np.float32))
    np.testing.assert_array_equal(cp.line, line)
    # the absolute timestamp [ns] as written, read independently with numpy
    o = ">" if bigendian else "<"
    ts_ns = np.frombuffer(bytes(back.data), dtype=o + "f8").reshape(n, 4)[:, 3]
    np.testing.assert_allclose(ts_ns * 1e-9, STAMP + t_rel, rtol=0, atol=1e-6)


def test_encode_cloud_rejects_bad_shapes() -> None:
    with pytest.raises(InputError, match="points must have shape"):
        encode_cloud(np.zeros((2, 2)), [0, 0], [0, 0], [0, 0], STAMP)
    with pytest.raises(InputError, match="t_rel"):
        encode_cloud(np.zeros((2, 3)), [0], [0, 0], [0, 0], STAMP)
    with pytest.raises(InputError, match="line"):
        encode_cloud(np.zeros((1, 3)), [0], [0], [256], STAMP)


def test_empty_encoded_cloud() -> None:
    fields, data, step = encode_cloud(np.zeros((0, 3)), [], [], [], STAMP)
    cp = cloud_points(decode_cloud(fields, data, 0, 1, step, 0, False), STAMP)
    assert cp.points.shape == (0, 3)
    assert cp.t is not None
    assert cp.t.shape == (0,)


# ---------------------------------------------------------------- time and attribute fields


def _cloud(columns: dict[str, np.ndarray]) -> np.ndarray:
    arr = np.zeros(
        len(next(iter(columns.values()))), dtype=[(k, v.dtype) for k, v in columns.items()]
    )
    for k, v in columns.items():
        arr[k] = v
    return arr


XYZ = {axis: np.array([1.0, 2.0], dtype=np.float32) for axis in ("x", "y", "z")}


@pytest.mark.parametrize(
    ("name", "values", "expected"),
    [
        ("offset_time", np.array([0, 5_000_000], dtype=np.uint32), [0.0, 0.005]),
        ("t", np.array([1_000, 99_000_000], dtype=np.uint32), [1e-6, 0.099]),
        ("time", np.array([-0.1, 0.0], dtype=np.float32), [-0.1, 0.0]),
        ("time", np.array([-0.05, 0.02], dtype=">f8"), [-0.05, 0.02]),
        ("timestamp", np.array([STAMP + 0.01, STAMP + 0.02]), [0.01, 0.02]),
        ("timestamp", np.array([STAMP * 1e9 + 3e7, STAMP * 1e9 - 1e6]), [0.03, -0.001]),
    ],
)
def test_time_conventions(name: str, values: np.ndarray, expected: list[float]) -> None:
    cp = cloud_points(_cloud({**XYZ, name: values}), STAMP)
    assert cp.t is not None
    np.testing.assert_allclose(cp.t, expected, rtol=0, atol=1e-6)


def test_time_field_preference_and_absence() -> None:
    both = _cloud(
        {**XYZ, "time": np.array([9.0, 9.0]), "offset_time": np.array([0, 1000], np.uint32)}
    )
    cp = cloud_points(both, STAMP)
    assert cp.t is not None
    np.testing.assert_allclose(cp.t, [0.0, 1e-6])
    bare = cloud_points(_cloud(XYZ), STAMP)
    assert bare.t is None
    np.testing.assert_array_equal(bare.intensity, [0, 0])
    np.testing.assert_array_equal(bare.line, [0, 0])
    assert bare.intensity.dtype == np.float32
    assert bare.line.dtype == np.uint8


def test_nan_timestamps_do_not_warn() -> None:
    cp = cloud_points(_cloud({**XYZ, "timestamp": np.array([np.nan, np.nan])}), STAMP)
    assert cp.t is not None
    assert np.all(np.isnan(cp.t))


def test_reflectivity_and_ring_clipping() -> None:
    arr = _cloud(
        {
            **XYZ,
            "reflectivity": np.array([7, 200], np.uint8),
            "ring": np.array([3, 300], np.uint16),
        }
    )
    cp = cloud_points(arr, STAMP)
    np.testing.assert_array_equal(cp.intensity, [7.0, 200.0])
    np.testing.assert_array_equal(cp.line, [3, 255])
    floats = cloud_points(_cloud({**XYZ, "line": np.array([np.nan, -4.0], np.float32)}), STAMP)
    np.testing.assert_array_equal(floats.line, [0, 0])


def test_cloud_points_requires_xyz() -> None:
    with pytest.raises(DecodeError, match=r"no x, y, z fields \(it has: x, y, intensity\)"):
        cloud_points(_cloud({"x": XYZ["x"], "y": XYZ["y"], "intensity": XYZ["z"]}), STAMP)
    multi = np.zeros(2, dtype=[("x", "f4", 2), ("y", "f4"), ("z", "f4")])
    with pytest.raises(DecodeError, match="'x' has count"):
        cloud_points(multi, STAMP)


# ---------------------------------------------------------------- dtype and layout checks


@pytest.mark.parametrize(
    ("fields", "step", "message"),
    [
        ([Field("x", 0, 9)], 4, "unknown datatype 9"),
        ([Field("x", 0, 7), Field("y", 2, 7)], 8, "'x' and 'y' overlap"),
        ([Field("x", 0, 7), Field("x", 4, 7)], 8, "'x' appears twice"),
        ([Field("x", 6, 7)], 8, "spans bytes 6..10 outside point_step 8"),
        ([Field("x", 0, 7, 3)], 8, "spans bytes 0..12"),
        ([Field("x", -1, 2)], 8, "spans bytes -1..0"),
        ([Field("x", 0, 7, -1)], 8, "count -1"),
        ([Field("", 0, 7)], 8, "empty name"),
        ([Field("x", 0, 7)], 0, "point_step must be > 0"),
    ],
)
def test_cloud_dtype_rejects(fields: list[Field], step: int, message: str) -> None:
    with pytest.raises(DecodeError, match=message):
        cloud_dtype(fields, step, bigendian=False)


def test_cloud_dtype_layout() -> None:
    dt = cloud_dtype(
        [Field("b", 8, 8), Field("a", 0, 3, 2), Field("gone", 0, 7, 0)], 20, bigendian=True
    )
    assert dt.itemsize == 20
    assert dt.names == ("b", "a")  # the count-0 field is ignored
    assert dt.fields is not None
    assert dt.fields["b"] == (np.dtype(">f8"), 8)
    assert dt.fields["a"] == (np.dtype((">i2", (2,))), 0)
    assert set(POINTFIELD_TYPES) == set(range(1, 9))


def test_decode_cloud_validation_messages() -> None:
    fields = [Field("x", 0, 7), Field("y", 4, 7), Field("z", 8, 7)]
    with pytest.raises(DecodeError, match=r"point count 3×2 needs 72 bytes .*has 60"):
        decode_cloud(fields, bytes(60), 3, 2, 12, 36, False)
    with pytest.raises(DecodeError, match="row_step 30 < width 3"):
        decode_cloud(fields, bytes(60), 3, 2, 12, 30, False)
    with pytest.raises(DecodeError, match="negative"):
        decode_cloud(fields, bytes(0), -1, 2, 12, 0, False)
    with pytest.raises(DecodeError, match="array of float64"):
        decode_cloud(fields, np.zeros(9), 3, 1, 12, 36, False)
    with pytest.raises(DecodeError, match="not a byte buffer"):
        decode_cloud(fields, "not bytes", 3, 1, 12, 36, False)  # type: ignore[arg-type]


def test_decode_cloud_zero_copy_for_each_buffer_kind(rng: np.random.Generator) -> None:
    rec = _velodyne_records(10, False, rng)
    raw = rec.tobytes()
    as_array = np.frombuffer(raw, dtype=np.uint8)
    for data in (raw, memoryview(raw), as_array, bytearray(raw)):
        arr = decode_cloud(VELODYNE, data, 10, 1, VELODYNE_STEP, 10 * VELODYNE_STEP, False)
        np.testing.assert_array_equal(arr["x"], rec["x"])
    view = decode_cloud(VELODYNE, as_array, 10, 1, VELODYNE_STEP, 320, False)
    assert np.shares_memory(view, as_array)
    padded = np.zeros((2, 170), dtype=np.uint8)
    padded[:, :160] = np.frombuffer(raw, np.uint8).reshape(2, 160)
    copy = decode_cloud(VELODYNE, padded, 5, 2, VELODYNE_STEP, 170, False)
    np.testing.assert_array_equal(copy["time"], rec["time"])


def test_fields_from_msg_duck_typing() -> None:
    class F:
        def __init__(self, name: str, offset: int) -> None:
            self.name, self.offset, self.datatype, self.count = name, offset, 7, 1

    class M:
        fields = (F("x", 0), F("y", 4))

    assert fields_from_msg(M()) == [Field("x", 0, 7), Field("y", 4, 7)]
    with pytest.raises(DecodeError, match="no 'fields'"):
        fields_from_msg(object())

    class Bad:
        fields = (object(),)

    with pytest.raises(DecodeError, match="malformed"):
        fields_from_msg(Bad())


# ---------------------------------------------------------------- properties


@st.composite
def layouts(draw: st.DrawFn) -> tuple[list[Field], int, bool, int, int, int]:
    """Random fields (shuffled), padding, byte order and cloud shape with row padding."""
    k = draw(st.integers(1, 6))
    names = draw(
        st.lists(st.text("abcxyz_", min_size=1, max_size=4), min_size=k, max_size=k, unique=True)
    )
    fields: list[Field] = []
    pos = 0
    for name in names:
        pos += draw(st.integers(0, 5))  # padding before the field
        datatype = draw(st.integers(1, 8))
        count = draw(st.integers(1, 3))
        fields.append(Field(name, pos, datatype, count))
        pos += SIZES[datatype] * count
    point_step = pos + draw(st.integers(0, 9))
    fields = draw(st.permutations(fields))
    width, height = draw(st.integers(0, 6)), draw(st.integers(0, 3))
    row_step = width * point_step + draw(st.integers(0, 7))
    return fields, point_step, draw(st.booleans()), width, height, row_step


def _reference_value(
    data: bytes, pos: int, field: Field, bigendian: bool
) -> tuple[float | int, ...]:
    fmt = (">" if bigendian else "<") + STRUCT_CODES[field.datatype] * field.count
    return struct.unpack_from(fmt, data, pos + field.offset)


_SIGNALLING_NAN_LAYOUT = (
    [
        Field("_", 0, 1),
        Field("a", 1, 1),
        Field("b", 2, 1),
        Field("c", 3, 5, 3),
        Field("__", 15, 1),
        Field("___", 19, 7, 2),
    ],
    27,
    False,
    1,
    1,
    27,
)


@settings(max_examples=80)
@given(layout=layouts(), seed=st.integers(0, 2**32 - 1))
@example(layout=_SIGNALLING_NAN_LAYOUT, seed=238)  # bytes 23-26 are a float32 signalling NaN
def test_decode_matches_struct_reference(
    layout: tuple[list[Field], int, bool, int, int, int], seed: int
) -> None:
    fields, point_step, bigendian, width, height, row_step = layout
    data = np.random.default_rng(seed).integers(0, 256, row_step * height, np.uint8).tobytes()
    arr = decode_cloud(fields, data, width, height, point_step, row_step, bigendian)
    assert arr.shape == (width * height,)
    for i in range(width * height):
        row, col = divmod(i, width)
        pos = row * row_step + col * point_step
        for f in fields:
            want = np.array(_reference_value(data, pos, f, bigendian), dtype=np.float64)
            # Random bytes can hold a signalling NaN; widening it to float64 quiets it
            # and raises the 'invalid' flag, which is expected here, not an error.
            with np.errstate(invalid="ignore"):
                got = np.atleast_1d(arr[f.name][i]).astype(np.float64)
            np.testing.assert_array_equal(got, want)  # NaN equals NaN here


def test_cloud_points_keeps_signalling_nans_as_nan() -> None:
    snan32 = np.array([0x7FA00001], dtype="<u4").view("<f4")[0]  # exponent all ones, quiet bit 0
    fields = [Field(name, 4 * k, 7) for k, name in enumerate(("x", "y", "z", "t", "intensity"))]
    fields.append(Field("ring", 20, 7))
    data = np.full(6, snan32, dtype="<f4").tobytes()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cp = cloud_points(decode_cloud(fields, data, 1, 1, 24, 24, False), STAMP)
    assert np.isnan(cp.points).all()
    assert cp.t is not None
    assert np.isnan(cp.t).all()
    assert np.isnan(cp.intensity).all()
    np.testing.assert_array_equal(cp.line, [0])


@settings(max_examples=40)
@given(
    n=st.integers(0, 30),
    bigendian=st.booleans(),
    seed=st.integers(0, 2**32 - 1),
)
def test_encode_decode_roundtrip(n: int, bigendian: bool, seed: int) -> None:
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-100, 100, (n, 3)).astype(np.float32).astype(np.float64)
    t_rel = rng.uniform(-0.05, 0.15, n)
    intensity = rng.integers(0, 256, n)
    line = rng.integers(0, 256, n)
    fields, data, step = encode_cloud(pts, t_rel, intensity, line, STAMP, bigendian=bigendian)
    cp = cloud_points(decode_cloud(fields, data, n, 1, step, n * step, bigendian), STAMP)
    assert isinstance(cp, CloudPoints)
    np.testing.assert_array_equal(cp.points, pts)
    assert cp.t is not None
    np.testing.assert_allclose(cp.t, t_rel, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(cp.intensity, intensity)
    np.testing.assert_array_equal(cp.line, line)


# ---------------------------------------------------------------- fuzz


@settings(max_examples=150)
@given(
    data=st.binary(max_size=200),
    fields=st.lists(
        st.builds(
            Field,
            st.sampled_from(["x", "y", "z", "t", "time", "timestamp", "ring", "intensity"]),
            st.integers(-2, 40),
            st.integers(0, 10),
            st.integers(-1, 3),
        ),
        max_size=6,
    ),
    width=st.integers(-1, 20),
    height=st.integers(-1, 4),
    point_step=st.integers(-1, 40),
    row_step=st.integers(-1, 200),
    bigendian=st.booleans(),
)
def test_random_input_decodes_or_raises_decode_error(
    data: bytes,
    fields: list[Field],
    width: int,
    height: int,
    point_step: int,
    row_step: int,
    bigendian: bool,
) -> None:
    try:
        arr = decode_cloud(fields, data, width, height, point_step, row_step, bigendian)
    except DecodeError:
        return
    assert arr.shape == (width * height,)
    try:
        cp = cloud_points(arr, STAMP)
    except DecodeError:
        return
    n = width * height
    assert cp.points.shape == (n, 3)
    assert cp.intensity.shape == cp.line.shape == (n,)
    assert cp.t is None or cp.t.shape == (n,)


@settings(max_examples=40)
@given(
    n=st.integers(1, 12),
    cut=st.integers(1, 10_000),
    extra=st.integers(1, 40),
    seed=st.integers(0, 1000),
)
def test_truncated_extended_or_miscounted_data_raise(
    n: int, cut: int, extra: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    fields, data, step = encode_cloud(
        rng.normal(size=(n, 3)), np.zeros(n), np.zeros(n), np.zeros(n), STAMP
    )
    short = data[: len(data) - 1 - cut % len(data)]
    with pytest.raises(DecodeError, match="point count"):
        decode_cloud(fields, short, n, 1, step, n * step, False)
    with pytest.raises(DecodeError, match="point count"):
        decode_cloud(fields, data + bytes(extra), n, 1, step, n * step, False)
    for width in (n - 1, n + 1):
        with pytest.raises(DecodeError, match="point count"):
            decode_cloud(fields, data, width, 1, step, width * step, False)
