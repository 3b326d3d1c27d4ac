"""``formats.livox.lvx``: headers, frames and packages built by hand from the specifications
(``tests/lvx_files.py``), decoded and checked field by field; the extrinsics."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.errors import DecodeError
from dronetrack.formats.livox import lvx
from lvx_files import (
    T0,
    avia_records,
    lvx1_device,
    lvx1_package,
    lvx2_device,
    lvx2_package,
    private_header,
    public_header,
    sdk1_packet,
)

EXT = (1.5, -2.25, 30.0, 0.5, -1.25, 2.0)  # roll, pitch, yaw [°], x, y, z [m]; exact in f32


def _lvx1_head(devices: int = 1) -> bytes:
    infos = b"".join(
        lvx1_device(f"3GGDJ6K0010058{k}".encode(), k, 7, 1, EXT, hub=b"HUB0001")
        for k in range(devices)
    )
    return public_header((1, 1, 0, 0)) + private_header(devices) + infos


def test_lvx1_header_decodes_field_by_field() -> None:
    head = _lvx1_head(2)
    assert len(head) == 24 + 5 + 2 * 59
    h = lvx.parse_header(head + b"more bytes after it")
    assert (h.major, h.version, h.frame_duration_ms, h.data_offset) == (1, (1, 1, 0, 0), 50, 147)
    assert len(h.devices) == 2
    d = h.devices[1]
    assert (d.code, d.hub_code, d.ident, d.device_type, d.model) == (
        "3GGDJ6K00100581",
        "HUB0001",
        1,
        7,
        "Avia",
    )
    assert d.extrinsic_enabled
    assert d.extrinsic == EXT


def test_lvx2_header_decodes_field_by_field() -> None:
    info = lvx2_device(b"47MDK9DF710030", 738306240, 9, 0, EXT, lidar_type=247)
    assert len(info) == 63
    head = public_header((2, 0, 0, 0)) + private_header(1, 50) + info
    h = lvx.parse_header(head)
    assert (h.major, h.version, h.data_offset) == (2, (2, 0, 0, 0), 92)
    (d,) = h.devices
    assert (d.code, d.hub_code, d.ident, d.lidar_type, d.device_type, d.model) == (
        "47MDK9DF710030",
        "",
        738306240,  # 192.168.1.44 as Livox Viewer 2 writes it
        247,
        9,
        "Mid-360",
    )
    assert not d.extrinsic_enabled
    assert d.extrinsic == EXT
    np.testing.assert_array_equal(d.pose, np.eye(4))  # disabled: no transform


@pytest.mark.parametrize(
    ("head", "message"),
    [
        (public_header((1, 1, 0, 0), magic=0xAC0EA766) + private_header(1), "magic code"),
        (
            b"livox_tecx" + bytes(6) + bytes([1, 1, 0, 0]) + struct.pack("<I", lvx.MAGIC),
            "signature",
        ),
        (public_header((1, 0, 0, 0)) + private_header(1), "version 1.0.0.0"),
        (public_header((3, 0, 0, 0)) + private_header(1), "version 3.0.0.0"),
        (public_header((1, 1, 0, 0)) + private_header(0), "device count is 0"),
        (public_header((1, 1, 0, 0))[:20], "public header"),
        (public_header((1, 1, 0, 0)) + private_header(1)[:3], "private header"),
        (public_header((2, 0, 0, 0)) + private_header(2) + bytes(63), "device info"),
    ],
)
def test_bad_headers_raise_a_decode_error_naming_the_problem(head: bytes, message: str) -> None:
    with pytest.raises(DecodeError, match=message):
        lvx.parse_header(head)


def test_two_devices_with_one_index_are_refused() -> None:
    info = lvx1_device(b"A", 3, 7, 0, EXT) + lvx1_device(b"B", 3, 7, 0, EXT)
    with pytest.raises(DecodeError, match="same index"):
        lvx.parse_header(public_header((1, 1, 0, 0)) + private_header(2) + info)


def test_frame_header_is_three_u64() -> None:
    raw = struct.pack("<QQQ", 1234, 5678, 9)
    assert lvx.parse_frame_header(raw) == (1234, 5678, 9)
    assert lvx.encode_frame(1234, 9, bytes(5678 - 1234 - 24))[:24] == raw
    with pytest.raises(DecodeError, match="shorter than 24"):
        lvx.parse_frame_header(raw[:23])


def _avia_points(n: int = 96) -> list[tuple[int, int, int, int, int]]:
    """Firing j returns at (10 m + j mm, −j mm, 2 j mm), every third firing none."""
    return [(10_000 + j, -j, 2 * j, j % 256, 0x10) if j % 3 else (0, 0, 0, 0, 0) for j in range(96)]


def test_lvx1_packages_split_and_decode_by_hand() -> None:
    """Two Avia packets (data type 2, 96 firings 4,167 ns apart) of device index 1, then
    an IMU packet (data type 6): each package is the device index and an SDK 1 packet."""
    p0 = lvx1_package(1, sdk1_packet(2, T0, avia_records(_avia_points())))
    p1 = lvx1_package(1, sdk1_packet(2, T0 + 96 * 4167, avia_records(_avia_points())))
    imu = lvx1_package(1, sdk1_packet(6, T0, struct.pack("<6f", 0, 0, 0, 0, 0, 1)))
    assert len(p0) == 1 + 18 + 96 * 14
    body = p0 + imu + p1
    pk = lvx.split_packages(body, 1)
    np.testing.assert_array_equal(pk.start, [0, len(p0), len(p0) + len(imu)])
    np.testing.assert_array_equal(pk.size, [len(p0), len(imu), len(p1)])
    np.testing.assert_array_equal(pk.ident, [1, 1, 1])
    np.testing.assert_array_equal(pk.data_type, [2, 6, 2])
    pts, line, bad = lvx.decode_lvx1(body, pk, 4167, lines=6)
    assert bad == 0
    assert len(pts) == 192  # the IMU sample gives no point
    j = np.arange(96)
    expect = np.stack([10.0 + j * 1e-3, -j * 1e-3, 2 * j * 1e-3], axis=1)
    np.testing.assert_allclose(pts.points[:96][j % 3 != 0], expect[j % 3 != 0], atol=1e-12)
    np.testing.assert_array_equal(pts.hit[:96], j % 3 != 0)
    np.testing.assert_array_equal(pts.t_ns[:96], T0 + j * 4167)
    np.testing.assert_array_equal(pts.t_ns[96:], T0 + (96 + j) * 4167)
    np.testing.assert_array_equal(pts.reflectivity[:96][j % 3 != 0], (j % 256)[j % 3 != 0])
    np.testing.assert_array_equal(line[:96], j % 6)


def test_lvx1_malformed_packets_are_counted_not_decoded() -> None:
    good = lvx1_package(0, sdk1_packet(2, T0, avia_records(_avia_points())))
    old = lvx1_package(0, sdk1_packet(2, T0, avia_records(_avia_points()), version=4))
    bad_time = lvx1_package(0, sdk1_packet(2, T0, avia_records(_avia_points()), ts_type=2))
    body = good + old + bad_time
    pts, _, bad = lvx.decode_lvx1(body, lvx.split_packages(body, 1), 4167)
    assert (len(pts), bad) == (96, 2)


@pytest.mark.parametrize(
    ("major", "body", "message"),
    [
        (1, lvx1_package(0, sdk1_packet(9, T0, b"")), "unknown data type 9"),
        (1, lvx1_package(0, sdk1_packet(2, T0, bytes(100))), "runs past the frame's end"),
        (1, lvx1_package(0, sdk1_packet(2, T0, b""))[:15], "cut off in its 19-byte header"),
        (2, lvx2_package(1, T0, 1, bytes(14))[:26], "cut off in its 27-byte header"),
        (2, lvx2_package(1, T0, 1, bytes(14), length=28), "runs past the frame's end"),
    ],
)
def test_packages_that_cannot_be_walked_raise(major: int, body: bytes, message: str) -> None:
    with pytest.raises(DecodeError, match=message):
        lvx.split_packages(body, major)


def test_lvx2_packages_split_and_decode_by_hand() -> None:
    """A Mid-360 package of data type 1 (x, y, z i32 mm) and one of data type 2 (i16 cm),
    point i at the package's timestamp + i · 5 µs."""
    rec1 = b"".join(struct.pack("<iiiBB", 5000 + i, -i, 300, 40 + i, 0) for i in range(96))
    rec2 = b"".join(struct.pack("<hhhBB", -200, 100 + i, 7, 9, 1) for i in range(10))
    a = lvx2_package(738306240, T0, 1, rec1, udp=7)
    b = lvx2_package(738306240, T0 + 480_000, 2, rec2, ts_type=1)
    assert len(a) == 27 + 96 * 14
    body = a + b
    pk = lvx.split_packages(body, 2)
    np.testing.assert_array_equal(pk.start, [0, len(a)])
    np.testing.assert_array_equal(pk.ident, [738306240, 738306240])
    np.testing.assert_array_equal(pk.data_type, [1, 2])
    heads = lvx.lvx2_heads(body, pk)
    assert heads["udp_counter"].tolist() == [7, 0]
    assert heads["length"].tolist() == [96 * 14, 10 * 8]
    pts, line, bad = lvx.decode_lvx2(body, pk, 5_000, lines=4)
    assert bad == 0
    i = np.arange(96)
    np.testing.assert_allclose(pts.points[:96, 0], 5.0 + i * 1e-3, atol=1e-12)
    np.testing.assert_allclose(pts.points[:96, 1], -i * 1e-3, atol=1e-12)
    np.testing.assert_array_equal(pts.t_ns[:96], T0 + i * 5_000)
    np.testing.assert_array_equal(pts.reflectivity[:96], 40 + i)
    np.testing.assert_array_equal(line[:96], i % 4)
    k = np.arange(10)
    np.testing.assert_allclose(
        pts.points[96:], np.c_[np.full(10, -2.0), 1.0 + k * 0.01, np.full(10, 0.07)]
    )
    np.testing.assert_array_equal(pts.t_ns[96:], T0 + 480_000 + k * 5_000)
    np.testing.assert_array_equal(pts.tag[96:], 1)


@pytest.mark.parametrize(
    "package",
    [
        lvx2_package(1, T0, 1, bytes(14), version=1),
        lvx2_package(1, T0, 3, bytes(14)),  # spherical: not in the LVX2 document
        lvx2_package(1, T0, 1, bytes(15)),  # not whole points
        lvx2_package(1, T0, 1, b""),
        lvx2_package(1, T0, 1, bytes(14), ts_type=7),
        lvx2_package(1, 1 << 63, 1, bytes(14)),
    ],
)
def test_lvx2_malformed_packages_are_counted_not_decoded(package: bytes) -> None:
    good = lvx2_package(1, T0, 1, struct.pack("<iiiBB", 1000, 0, 0, 1, 0))
    body = good + package
    pts, _, bad = lvx.decode_lvx2(body, lvx.split_packages(body, 2), 5_000)
    assert (len(pts), bad) == (1, 1)


def test_extrinsic_rotations_about_each_axis() -> None:
    """R = Rz(yaw) Ry(pitch) Rx(roll): roll 90° turns y into z, pitch 90° turns x into −z,
    yaw 90° turns x into y; the translation is added after."""

    def moved(ext: tuple[float, ...], p: tuple[float, float, float]) -> np.ndarray:
        T = lvx.extrinsic_pose(ext)
        return T[:3, :3] @ np.array(p) + T[:3, 3]

    np.testing.assert_allclose(moved((90, 0, 0, 0, 0, 0), (0, 1, 0)), [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(moved((0, 90, 0, 0, 0, 0), (1, 0, 0)), [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(moved((0, 0, 90, 0, 0, 0), (1, 0, 0)), [0, 1, 0], atol=1e-12)
    # yaw 90° then the mount 1, 2, 3 m away: a return 10 m ahead lies at (1, 12, 3)
    np.testing.assert_allclose(moved((0, 0, 90, 1, 2, 3), (10, 0, 0)), [1, 12, 3], atol=1e-12)
    # the order: roll, then pitch, then yaw (x-y-z about fixed axes)
    np.testing.assert_allclose(moved((90, 0, 90, 0, 0, 0), (0, 1, 0)), [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(moved((0, 90, 90, 0, 0, 0), (0, 0, 1)), [0, 1, 0], atol=1e-12)


def test_extrinsic_matrix_is_the_livox_driver_formula() -> None:
    """Every entry of R against the closed form Livox's driver writes out."""
    r, p, y = (math.radians(v) for v in EXT[:3])
    cr, sr, cp, sp, cy, sy = (
        math.cos(r),
        math.sin(r),
        math.cos(p),
        math.sin(p),
        math.cos(y),
        math.sin(y),
    )
    expect = [
        [cp * cy, sr * sp * cy - cr * sy, cr * sp * cy + sr * sy],
        [cp * sy, sr * sp * sy + cr * cy, cr * sp * sy - sr * cy],
        [-sp, sr * cp, cr * cp],
    ]
    T = lvx.extrinsic_pose(EXT)
    np.testing.assert_allclose(T[:3, :3], expect, atol=1e-15)
    np.testing.assert_allclose(T[:3, 3], EXT[3:])


angles = st.floats(-179.0, 179.0)


@given(
    angles,
    st.floats(-89.0, 89.0),
    angles,
    st.floats(-50, 50),
    st.floats(-50, 50),
    st.floats(-50, 50),
)
def test_extrinsic_of_inverts_extrinsic_pose(
    roll: float, pitch: float, yaw: float, x: float, y: float, z: float
) -> None:
    back = lvx.extrinsic_of(lvx.extrinsic_pose((roll, pitch, yaw, x, y, z)))
    np.testing.assert_allclose(back, (roll, pitch, yaw, x, y, z), atol=1e-9)


@given(angles, st.sampled_from([-90.0, 90.0]), angles)
def test_extrinsic_of_looking_straight_up_or_down_gives_the_same_pose(
    roll: float, pitch: float, yaw: float
) -> None:
    """At pitch ±90° roll and yaw turn about one axis: any pair giving the rotation."""
    T = lvx.extrinsic_pose((roll, pitch, yaw, 1.0, 2.0, 3.0))
    np.testing.assert_allclose(lvx.extrinsic_pose(lvx.extrinsic_of(T)), T, atol=1e-9)


def test_encoded_header_is_the_hand_built_one() -> None:
    """Our encoder writes the bytes the specification gives (the decoder is checked above
    against hand-built bytes; this checks the writer against them too)."""
    d = lvx.LvxDevice("3GGDJ6K00100580", "HUB0001", 0, 7, True, EXT)
    assert lvx.encode_header(1, [d]) == _lvx1_head()
    d2 = lvx.LvxDevice("47MDK9DF710030", "", 738306240, 9, False, EXT, lidar_type=247)
    assert lvx.encode_header(2, [d2]) == (
        public_header((2, 0, 0, 0))
        + private_header(1)
        + lvx2_device(b"47MDK9DF710030", 738306240, 9, 0, EXT)
    )


def test_encoded_lvx2_packages_are_the_hand_built_ones() -> None:
    pts = np.array([[1.0, -2.0, 0.5], [0.0, 0.0, 0.0], [3.25, 0.001, -0.002]])
    refl = np.array([10, 0, 200], np.uint8)
    (got,) = lvx.encode_lvx2_packages(
        pts, refl, lidar_id=5, t0_ns=T0, point_interval_ns=5000, timestamp_type=1, udp_counter=3
    )
    rec = struct.pack("<iiiBB", 1000, -2000, 500, 10, 0) + struct.pack("<iiiBB", 0, 0, 0, 0, 0)
    rec += struct.pack("<iiiBB", 3250, 1, -2, 200, 0)
    assert got == lvx2_package(5, T0, 1, rec, ts_type=1, udp=3)
