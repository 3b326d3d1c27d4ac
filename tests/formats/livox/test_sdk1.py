"""Livox SDK 1 codecs against packets built here by hand from the protocol layouts
(Livox-SDK ``livox_def.h``, ``sdk_protocol.h``; livox_ros_driver ``lds.h``, ``lds.cpp``),
with ``struct.pack`` and a bitwise CRC written from the CRC definitions, never
with the module's own encoder."""

from __future__ import annotations

import calendar
import contextlib
import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import DecodeError, InputError
from dronetrack.formats.livox import sdk1 as s1
from dronetrack.formats.livox.common import DecodedPackets
from livox_helpers import damaged_packets

DT = 4_167  # ns between firings of an Avia (lds.h)
T0 = 1_700_000_000_123_456_789


def _crc16_bitwise(data: bytes, reg: int) -> int:
    # MCRF4XX: reflected polynomial 0x1021 (0x8408), no final xor
    for b in data:
        reg ^= b
        for _ in range(8):
            reg = (reg >> 1) ^ 0x8408 if reg & 1 else reg >> 1
    return reg


def _crc32_bitwise(data: bytes, seed: int) -> int:
    # FastCRC crc32_calc: register = seed ^ 0xFFFFFFFF, reflected 0x04C11DB7, final xor
    reg = seed ^ 0xFFFFFFFF
    for b in data:
        reg ^= b
        for _ in range(8):
            reg = (reg >> 1) ^ 0xEDB88320 if reg & 1 else reg >> 1
    return reg ^ 0xFFFFFFFF


def _header(data_type: int, stamp: bytes | int = T0, ts_type: int = 0, version: int = 5) -> bytes:
    raw = stamp if isinstance(stamp, bytes) else struct.pack("<Q", stamp)
    return struct.pack("<BBBBIBB", version, 0, 1, 0, 0x0200, ts_type, data_type) + raw


# data type → (struct format of one firing, first firing's values, its expected points)
S = math.sqrt(0.5)
KNOWN = {
    0: ("<iiiB", (1000, -2000, 3000, 77), [(1.0, -2.0, 3.0)]),
    # depth 10 m, zenith 90°, azimuth 0° lies on +x
    1: ("<IHHB", (10_000, 9000, 0, 77), [(10.0, 0.0, 0.0)]),
    2: ("<iiiBB", (1000, -2000, 3000, 77, 5), [(1.0, -2.0, 3.0)]),
    # zenith 45°, azimuth 90°: (0, r sin45°, r cos45°)
    3: ("<IHHBB", (2000, 4500, 9000, 77, 5), [(0.0, 2 * S, 2 * S)]),
    4: ("<iiiBBiiiBB", (1000, 0, 0, 77, 5, 0, 2500, -1, 78, 6), [(1, 0, 0), (0, 2.5, -0.001)]),
    # zenith 0° is +z; both returns share the direction
    5: ("<HHIBBIBB", (0, 0, 3000, 77, 5, 4000, 78, 6), [(0, 0, 3.0), (0, 0, 4.0)]),
    7: (
        "<iiiBBiiiBBiiiBB",
        (1, 2, 3, 77, 5, 4, 5, 6, 78, 6, 0, 0, 9000, 79, 7),
        [(0.001, 0.002, 0.003), (0.004, 0.005, 0.006), (0.0, 0.0, 9.0)],
    ),
    # zenith 90°, azimuth 180° is −x
    8: (
        "<HHIBBIBBIBB",
        (9000, 18000, 1000, 77, 5, 2000, 78, 6, 3000, 79, 7),
        [(-1.0, 0, 0), (-2.0, 0, 0), (-3.0, 0, 0)],
    ),
}


def _packet(data_type: int, **kw: object) -> bytes:
    """A packet whose first firing is KNOWN's and whose other firings have no return."""
    fmt, values, _ = KNOWN[data_type]
    n = s1.POINTS_PER_PACKET[data_type]
    first = struct.pack(fmt, *values)
    return _header(data_type, **kw) + first + bytes(len(first) * (n - 1))  # type: ignore[arg-type]


def test_heartbeat_frame_matches_the_known_bytes() -> None:
    known = bytes.fromhex("AA 00 0F 00 00 01 00 F7 CA 00 03 C9 8B 3E A8")
    assert s1.encode_frame(s1.CommandFrame(s1.CMD, 1, 0, 3)) == known
    assert s1.decode_frame(known) == s1.CommandFrame(cmd_type=0, seq=1, cmd_set=0, cmd_id=3)
    assert s1.crc16(known[:7]) == _crc16_bitwise(known[:7], 0x4C49) == 0xCAF7
    assert s1.crc32(known[:11]) == _crc32_bitwise(known[:11], 0x564F580A)


def test_crcs_match_their_catalogue_check_values() -> None:
    # CRC-16/MCRF4XX (init 0xFFFF) check 0x6F91; with seed 0 the SDK's crc32_calc is
    # plain CRC-32 (register 0xFFFFFFFF), check 0xCBF43926
    assert s1.crc16(b"123456789", init=0xFFFF) == 0x6F91
    assert _crc32_bitwise(b"123456789", 0) == 0xCBF43926


@given(st.binary(min_size=7, max_size=7), st.binary(max_size=64))
@settings(max_examples=100)
def test_crcs_agree_with_the_bitwise_definitions(pre: bytes, body: bytes) -> None:
    c = s1.crc16(pre)
    assert c == _crc16_bitwise(pre, 0x4C49)
    assert s1.crc16(pre + struct.pack("<H", c)) == 0  # CRC of all 9 preamble bytes
    assert s1.crc32(body) == _crc32_bitwise(body, 0x564F580A)


def _frame_by_hand(cmd_type: int, seq: int, cmd_id: int, payload: bytes) -> bytes:
    pre = struct.pack("<BBHBH", 0xAA, 0, 15 + len(payload), cmd_type, seq)
    body = pre + struct.pack("<HBB", _crc16_bitwise(pre, 0x4C49), 0, cmd_id) + payload
    return body + struct.pack("<I", _crc32_bitwise(body, 0x564F580A))


def test_general_command_payloads_decode_from_hand_built_frames() -> None:
    bc = _frame_by_hand(2, 0, 0, struct.pack("<16sBH", b"3GGDJ6K00100581", 7, 0))
    assert s1.Broadcast.decode(s1.decode_frame(bc).payload) == s1.Broadcast("3GGDJ6K00100581", 7)
    hs = _frame_by_hand(
        1, 9, 1, bytes([192, 168, 1, 50]) + struct.pack("<HHH", 56001, 55501, 56001)
    )
    frame = s1.decode_frame(hs)
    assert (frame.cmd_type, frame.seq, frame.cmd_id) == (1, 9, 1)
    assert s1.Handshake.decode(frame.payload) == s1.Handshake("192.168.1.50", 56001, 55501, 56001)
    ack = _frame_by_hand(1, 2, 3, struct.pack("<BBBI", 0, 1, 0, 0x0200))
    assert s1.HeartbeatAck.decode(s1.decode_frame(ack).payload) == s1.HeartbeatAck(0, 1, 0, 0x0200)
    assert s1.decode_sampling(s1.decode_frame(_frame_by_hand(0, 3, 4, b"\x01")).payload) is True
    assert s1.decode_ret_code(s1.decode_frame(_frame_by_hand(1, 4, 6, b"\x00")).payload) == 0
    for msg in (
        s1.Broadcast("ABC", 1),
        s1.Handshake("10.0.0.2", 1, 2, 3),
        s1.HeartbeatAck(0, 1, 1, 7),
    ):
        assert type(msg).decode(msg.encode()) == msg
    assert s1.encode_sampling(False) == b"\x00"
    assert s1.encode_frame(s1.CommandFrame(1, 9, 0, 1, hs[11:-4])) == hs


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda b: b"\xab" + b[1:], "SOF"),
        (lambda b: b[:-1], "length"),
        (lambda b: b + b"\x00", "length"),
        (lambda b: b[:5] + bytes([b[5] ^ 1]) + b[6:], "CRC-16"),
        (lambda b: b[:-1] + bytes([b[-1] ^ 1]), "CRC-32"),
        (lambda b: b[:10], "shorter"),
    ],
)
def test_malformed_frames_raise_a_decode_error_naming_the_problem(mutate, message) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(DecodeError, match=message):
        s1.decode_frame(mutate(s1.encode_frame(s1.CommandFrame(0, 1, 0, 4, b"\x01"))))


def test_packet_sizes_are_those_of_the_driver_table() -> None:
    # livox_ros_driver lds.h data_type_info_pair_table packet lengths
    assert s1.PACKET_BYTES == {
        0: 1318,
        1: 918,
        2: 1362,
        3: 978,
        4: 1362,
        5: 786,
        6: 42,
        7: 1278,
        8: 678,
    }


@pytest.mark.parametrize("data_type", sorted(KNOWN))
def test_every_point_type_decodes_hand_built_points(data_type: int) -> None:
    expected = KNOWN[data_type][2]
    R = len(expected)
    pts = s1.decode_packet(_packet(data_type), DT).points
    n = s1.POINTS_PER_PACKET[data_type]
    assert len(pts) == n * R
    np.testing.assert_allclose(pts.points[:R], np.array(expected, float), atol=1e-12)
    assert pts.hit[:R].all()
    assert pts.n_empty == (n - 1) * R
    assert pts.reflectivity[:R].tolist() == [77, 78, 79][:R]
    tagged = data_type not in (0, 1)
    assert pts.tag[:R].tolist() == ([5, 6, 7][:R] if tagged else [0])
    assert pts.return_index.tolist() == list(range(R)) * n
    # firing j at T0 + j·Δt; the returns of one firing share its time
    assert pts.t_ns.tolist() == [T0 + j * DT for j in range(n) for _ in range(R)]
    assert len(pts.hits()) == R


def test_imu_packet_decodes_gyro_and_acceleration() -> None:
    buf = _header(6) + struct.pack("<6f", 0.5, -0.25, 0.125, 0.0, 0.0, 1.0)
    imu = s1.decode_packet(buf, DT).imu
    assert imu.t_ns.tolist() == [T0]
    assert imu.gyro.tolist() == [[0.5, -0.25, 0.125]]
    assert imu.acc.tolist() == [[0.0, 0.0, 1.0]]


def test_utc_timestamp_is_the_hour_plus_microseconds() -> None:
    stamp = bytes([24, 3, 15, 10]) + struct.pack("<I", 123_456_789)
    pts = s1.decode_packet(_packet(0, stamp=stamp, ts_type=3), DT).points
    hour = calendar.timegm((2024, 3, 15, 10, 0, 0))
    assert pts.t_ns[0] == hour * 10**9 + 123_456_789_000
    assert pts.t_ns[1] - pts.t_ns[0] == DT


@pytest.mark.parametrize(
    ("buf", "message"),
    [
        (_packet(0)[:-1], "expected 1318"),
        (_packet(0) + b"\x00", "expected 1318"),
        (_packet(0, version=4), "version 4"),
        (_header(9) + bytes(100), "unknown data type 9"),
        (_packet(0, ts_type=2), "timestamp type 2"),
        (_packet(0, stamp=bytes([24, 13, 1, 0, 0, 0, 0, 0]), ts_type=3), "no date"),
        (_packet(0, stamp=bytes([24, 2, 30, 0, 0, 0, 0, 0]), ts_type=3), "no date"),
        (_packet(0, stamp=bytes([24, 2, 1, 24, 0, 0, 0, 0]), ts_type=3), "hour 24"),
        (_packet(0, stamp=struct.pack("<Q", 1 << 63), ts_type=1), "out of range"),
        (b"\x05" * 17, "shorter"),
    ],
)
def test_malformed_packets_raise_singly_and_count_in_a_batch(buf: bytes, message: str) -> None:
    with pytest.raises(DecodeError, match=message):
        s1.decode_packet(buf, DT)
    decoded, bad = s1.decode_packets([_packet(2), buf, _packet(0)], DT)
    assert bad == 1
    assert len(decoded.points) == 96 + 100


def _assert_same(a: DecodedPackets, b: DecodedPackets) -> None:
    for field in ("points", "reflectivity", "tag", "return_index", "t_ns", "hit"):
        np.testing.assert_array_equal(getattr(a.points, field), getattr(b.points, field))
    for field in ("t_ns", "gyro", "acc"):
        np.testing.assert_array_equal(getattr(a.imu, field), getattr(b.imu, field))


def test_batch_decoder_equals_decoding_packet_by_packet() -> None:
    rng = np.random.default_rng(11)
    packets = []
    for k in range(40):
        data_type = int(rng.choice([0, 1, 2, 3, 4, 5, 6, 7, 8]))
        buf = bytearray(
            _packet(data_type, stamp=T0 + k * 1_000_000)
            if data_type != 6
            else _header(6) + bytes(24)
        )
        body = rng.integers(0, 256, len(buf) - 18, dtype=np.uint8)
        if data_type in s1.LAYOUTS:  # keep spherical angles in range: any bytes are valid otherwise
            rec = body.view(s1.LAYOUTS[data_type].dtype)
            rec["theta" if data_type in (1, 3, 5, 8) else rec.dtype.names[0]] %= 18001
            if "phi" in (rec.dtype.names or ()):
                rec["phi"] %= 36000
        elif data_type == 6:
            body = np.zeros(24, np.uint8)
            body.view("<f4")[:] = rng.normal(size=6)
        buf[18:] = body.tobytes()
        packets.append(bytes(buf))
    packets.insert(7, _packet(0)[:-3])  # one malformed
    batch, bad = s1.decode_packets(packets, DT)
    assert bad == 1
    singles = [s1.decode_packet(p, DT) for i, p in enumerate(packets) if i != 7]
    ref = DecodedPackets(
        type(batch.points).concat([s.points for s in singles]),
        type(batch.imu).concat([s.imu for s in singles]),
    )
    _assert_same(batch, ref)
    assert len(batch.imu) == sum(len(s.imu) for s in singles) > 0


MM = 0.0005 + 1e-9  # half a millimetre: the coordinates' quantisation
CDEG = math.radians(0.005)  # half of 0.01°: the angles' quantisation


@given(
    st.sampled_from([0, 1, 2, 3, 4, 5, 7, 8]),
    st.integers(1, 130),
    st.integers(0, 2**32),
    st.sampled_from([4_167, 10_000]),
)
@settings(max_examples=60, deadline=None)
def test_encode_then_decode_gives_the_arrays_back(
    data_type: int, F: int, seed: int, dt: int
) -> None:
    rng = np.random.default_rng(seed)
    R = s1.LAYOUTS[data_type].returns
    direction = rng.normal(size=(F, 1, 3))
    direction /= np.linalg.norm(direction, axis=2, keepdims=True)
    ranges = rng.uniform(0.5, 400.0, (F, R, 1))
    points = (direction * ranges).reshape(F * R, 3)  # the returns of a firing are collinear
    refl = rng.integers(0, 256, F * R, dtype=np.uint8)
    tag = rng.integers(0, 256, F * R, dtype=np.uint8)
    packets = s1.encode_point_packets(
        points, refl, tag, data_type=data_type, t0_ns=T0, point_interval_ns=dt
    )
    n = s1.POINTS_PER_PACKET[data_type]
    assert len(packets) == -(-F // n)
    assert all(len(p) == s1.PACKET_BYTES[data_type] for p in packets)
    decoded, bad = s1.decode_packets(packets, dt)
    pts = decoded.points
    assert bad == 0
    assert len(pts) == len(packets) * n * R
    assert pts.n_empty == len(pts) - F * R
    error = np.linalg.norm(pts.points[: F * R] - points, axis=1)
    # spherical: depth within 0.5 mm, direction within √2 · 0.005° of arc
    bound = (
        MM * math.sqrt(3)
        if data_type in (0, 2, 4, 7)
        else MM + np.linalg.norm(points, axis=1) * CDEG * 2
    )
    assert np.all(error <= bound)
    assert pts.reflectivity[: F * R].tolist() == refl.tolist()
    if data_type not in (0, 1):
        assert pts.tag[: F * R].tolist() == tag.tolist()
    assert pts.t_ns[: F * R].tolist() == [T0 + j * dt for j in range(F) for _ in range(R)]


def test_utc_and_imu_encoding_round_trip() -> None:
    t0 = calendar.timegm((2031, 12, 31, 23, 59, 59)) * 10**9 + 999_500_000  # 0.5 ms before 2032
    packets = s1.encode_point_packets(
        np.ones((150, 3)),
        np.zeros(150, np.uint8),
        data_type=0,
        t0_ns=t0,
        point_interval_ns=10_000,
        timestamp_type=3,
    )
    assert packets[1][10:14] == bytes([32, 1, 1, 0])  # the second packet is in the next year
    pts = s1.decode_packets(packets, 10_000)[0].points
    assert pts.t_ns[:150].tolist() == [t0 + j * 10_000 for j in range(150)]
    gyro, acc = np.array([[0.5, 0.25, -1.0]]), np.array([[0.0, 1.0, 0.0]])
    imu = s1.decode_packet(s1.encode_imu_packets(np.array([T0]), gyro, acc)[0], DT).imu
    assert (imu.t_ns.tolist(), imu.gyro.tolist(), imu.acc.tolist()) == (
        [T0],
        gyro.tolist(),
        acc.tolist(),
    )


def test_encoder_refuses_what_the_wire_cannot_hold() -> None:
    with pytest.raises(InputError, match="out of range"):
        s1.encode_point_packets(
            np.array([[3e6, 0, 0]]),
            np.zeros(1, np.uint8),
            data_type=0,
            t0_ns=0,
            point_interval_ns=DT,
        )
    with pytest.raises(InputError, match="not a point type"):
        s1.encode_point_packets(
            np.zeros((1, 3)), np.zeros(1, np.uint8), data_type=6, t0_ns=0, point_interval_ns=DT
        )
    with pytest.raises(InputError, match=r"\(F·2, 3\)"):
        s1.encode_point_packets(
            np.zeros((3, 3)), np.zeros(3, np.uint8), data_type=4, t0_ns=0, point_interval_ns=DT
        )
    with pytest.raises(InputError, match="years 2000-2255"):
        s1.encode_point_packets(
            np.zeros((1, 3)),
            np.zeros(1, np.uint8),
            data_type=0,
            t0_ns=0,
            point_interval_ns=DT,
            timestamp_type=3,
        )
    with pytest.raises(InputError, match="host IP"):
        s1.Handshake("192.168.1", 1, 2, 3).encode()


GOOD = [_packet(t) for t in (0, 3, 5, 8)] + [_header(6) + bytes(24)]


@given(damaged_packets(GOOD, header_bytes=18))
@settings(max_examples=300, deadline=None)
def test_damaged_packets_give_decode_errors_or_a_malformed_count(buf: bytes) -> None:
    try:
        s1.decode_packet(buf, DT)
        single_ok = True
    except DecodeError:
        single_ok = False
    decoded, bad = s1.decode_packets([buf, GOOD[0]], DT)
    assert bad == (0 if single_ok else 1)
    assert len(decoded.points) >= 100


@given(
    st.binary(max_size=64)
    | st.builds(lambda b, n: b[:n], st.just(_frame_by_hand(1, 2, 3, bytes(7))), st.integers(0, 21))
)
@settings(max_examples=200, deadline=None)
def test_damaged_frames_and_payloads_give_only_decode_errors(buf: bytes) -> None:
    for decode in (
        s1.decode_frame,
        s1.Broadcast.decode,
        s1.Handshake.decode,
        s1.HeartbeatAck.decode,
        s1.decode_sampling,
        s1.decode_ret_code,
    ):
        with contextlib.suppress(DecodeError):
            decode(buf)
