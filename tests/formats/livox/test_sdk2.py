"""Livox SDK 2 (Mid-360) codecs against frames and packets built here by hand from
the Mid-360 protocol document (livox_wiki_en ``livox_eth_protocol_mid360.md``) with
``struct.pack`` and a bitwise CRC-16/CCITT-FALSE written from its definition, never
with the module's own encoder."""

from __future__ import annotations

import contextlib
import math
import struct

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import DecodeError, InputError
from dronetrack.formats.livox import sdk2 as s2
from dronetrack.formats.livox import sdk2_control as c2
from dronetrack.formats.livox.common import DecodedPackets, ImuSamples, LivoxPoints
from livox_helpers import T0, damaged_packets
from livox_helpers import ccitt_false as _ccitt_false
from livox_helpers import sdk2_frame as _frame_by_hand
from livox_helpers import sdk2_packet as _packet

FORMATS = {1: "<iiiBB", 2: "<hhhBB", 3: "<IHHBB", 0: "<6f"}
KNOWN = {
    1: ((1000, -2000, 3000, 77, 5), (1.0, -2.0, 3.0)),
    2: ((100, -200, 300, 77, 5), (1.0, -2.0, 3.0)),  # 16-bit coordinates in cm
    3: ((10_000, 9000, 0, 77, 5), (10.0, 0.0, 0.0)),  # depth 10 m, zenith 90°, azimuth 0°
}


def _points_packet(data_type: int, n: int = 96, **kw: int) -> bytes:
    values, _ = KNOWN[data_type]
    first = struct.pack(FORMATS[data_type], *values)
    return _packet(data_type, first + bytes(len(first) * (n - 1)), n, **kw)


def test_crc16_is_ccitt_false() -> None:
    assert c2.crc16(b"123456789") == _ccitt_false(b"123456789") == 0x29B1  # catalogue check


def test_frames_round_trip_against_hand_built_bytes() -> None:
    req = _frame_by_hand(0x0000, 0, 1, b"")
    assert req[20:24] == bytes(4)  # no data: CRC-32 field 0
    assert c2.decode_frame(req) == c2.CommandFrame(cmd_id=0, cmd_type=0, seq=1)
    assert c2.encode_frame(c2.CommandFrame(0, 0, 1)) == req
    ack_data = struct.pack("<BB16s4BH", 0, 9, b"47MDL9A0020074", 192, 168, 1, 12, 56100)
    ack = _frame_by_hand(0x0000, 1, 1, ack_data, sender=1)
    frame = c2.decode_frame(ack)
    assert (frame.cmd_type, frame.sender) == (1, 1)
    assert c2.DiscoveryAck.decode(frame.payload) == c2.DiscoveryAck(
        0, 9, "47MDL9A0020074", "192.168.1.12", 56100
    )
    assert c2.encode_frame(c2.CommandFrame(0, 1, 1, ack_data, sender=1)) == ack


def test_host_configuration_request_holds_the_documented_keys() -> None:
    data = c2.host_config_request("192.168.1.5", 56201, 56301, 56401)
    ip = bytes([192, 168, 1, 5])
    by_hand = (
        struct.pack("<HH", 4, 0)
        + struct.pack("<HH", 0x0005, 8) + ip + struct.pack("<HH", 56201, 56200)
        + struct.pack("<HH", 0x0006, 8) + ip + struct.pack("<HH", 56301, 56300)
        + struct.pack("<HH", 0x0007, 8) + ip + struct.pack("<HH", 56401, 56400)
        + struct.pack("<HHB", 0x001A, 1, 0x01)
    )  # fmt: skip
    assert data == by_hand
    items = c2.decode_key_values(c2.decode_frame(_frame_by_hand(0x0100, 0, 5, by_hand)).payload)
    assert [k for k, _ in items] == [5, 6, 7, 0x1A]
    assert c2.HostIpConfig.decode(items[1][1]) == c2.HostIpConfig("192.168.1.5", 56301, 56300)
    assert c2.ParamAck.decode(b"\x01\x06\x00") == c2.ParamAck(1, 6)
    assert c2.ParamAck(0).encode() == b"\x00\x00\x00"


@pytest.mark.parametrize(
    ("data", "message"),
    [
        (b"\x01\x00", "shorter than 4"),
        (struct.pack("<HH", 1, 0) + b"\x05\x00", "truncated at item 0"),
        (struct.pack("<HHHH", 1, 0, 5, 8) + bytes(7), "truncated"),
        (struct.pack("<HHHHB", 1, 0, 0x1A, 1, 1) + b"\x00", "after 1 items"),
    ],
)
def test_malformed_key_value_lists_raise(data: bytes, message: str) -> None:
    with pytest.raises(DecodeError, match=message):
        c2.decode_key_values(data)


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda b: b"\x55" + b[1:], "SOF"),
        (lambda b: b[:-1], "length"),
        (lambda b: b[:4] + bytes([b[4] ^ 1]) + b[5:], "CRC-16"),
        (lambda b: b[:-1] + bytes([b[-1] ^ 1]), "CRC-32"),
        (lambda b: b[:23], "shorter"),
    ],
)
def test_malformed_frames_raise_a_decode_error_naming_the_problem(mutate, message) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(DecodeError, match=message):
        c2.decode_frame(mutate(_frame_by_hand(0x0100, 0, 5, b"\x00\x00\x00\x00")))


@pytest.mark.parametrize("data_type", [1, 2, 3])
def test_point_types_decode_hand_built_points(data_type: int) -> None:
    pts = s2.decode_packet(_points_packet(data_type), check_crc=True).points
    assert len(pts) == 96
    np.testing.assert_allclose(pts.points[0], KNOWN[data_type][1], atol=1e-12)
    assert (pts.reflectivity[0], pts.tag[0], pts.n_empty) == (77, 5, 95)
    # time_interval 950 × 0.1 µs spans the 95 gaps between 96 points: 1000 ns apart
    assert pts.t_ns.tolist() == [T0 + 1000 * i for i in range(96)]
    assert set(pts.return_index.tolist()) == {0}


def test_documented_packet_size_and_imu() -> None:
    assert len(_points_packet(1)) == 1380  # 96 type-1 points (protocol document)
    imu = s2.decode_packet(
        _packet(0, struct.pack("<6f", 0.5, 0, -0.25, 0, 0, 1.0), 1, interval=0)
    ).imu
    assert (imu.t_ns.tolist(), imu.gyro.tolist(), imu.acc.tolist()) == (
        [T0],
        [[0.5, 0, -0.25]],
        [[0, 0, 1.0]],
    )


def test_crc_is_checked_only_when_asked() -> None:
    buf = bytearray(_points_packet(1))
    buf[40] ^= 0xFF
    assert len(s2.decode_packet(bytes(buf)).points) == 96
    with pytest.raises(DecodeError, match="CRC-32"):
        s2.decode_packet(bytes(buf), check_crc=True)
    assert s2.decode_packets([bytes(buf)], check_crc=True)[1] == 1


def _with_length(buf: bytes, length: int) -> bytes:
    return buf[:1] + struct.pack("<H", length) + buf[3:]


@pytest.mark.parametrize(
    ("buf", "message"),
    [
        (_points_packet(1)[:-1], "length field"),
        (_with_length(_points_packet(1)[:-1], 1379), "do not hold 96"),
        (_with_length(_points_packet(1) + b"\x00", 1381), "do not hold 96"),
        (b"\x01" + _points_packet(1)[1:], "version 1"),
        (_packet(4, bytes(14), 1), "unknown data type 4"),
        (_points_packet(1, time_type=3), "time type 3"),
        (_packet(1, bytes(0), 0), "do not hold 0"),
        (bytes(35), "shorter"),
    ],
)
def test_malformed_packets_raise_singly_and_count_in_a_batch(buf: bytes, message: str) -> None:
    with pytest.raises(DecodeError, match=message):
        s2.decode_packet(buf)
    decoded, bad = s2.decode_packets([_points_packet(2), buf, _points_packet(3)])
    assert bad == 1
    assert len(decoded.points) == 192


def test_batch_decoder_equals_decoding_packet_by_packet() -> None:
    rng = np.random.default_rng(5)
    packets = []
    for _ in range(30):
        data_type = int(rng.choice([0, 1, 2, 3]))
        n = 1 if data_type == 0 else int(rng.choice([96, 40]))
        if data_type == 0:
            records = rng.normal(size=6).astype("<f4").tobytes()
        else:
            rec = rng.integers(0, 256, n * s2.RECORD_BYTES[data_type], dtype=np.uint8)
            view = rec.view(s2.LAYOUTS[data_type].dtype)
            if data_type == 3:
                view["theta"] %= 18001
                view["phi"] %= 36000
            records = rec.tobytes()
        packets.append(_packet(data_type, records, n, interval=int(rng.integers(0, 2000))))
    packets.insert(4, packets[0][:-2])  # one malformed
    batch, bad = s2.decode_packets(packets, check_crc=True)
    assert bad == 1
    singles = [s2.decode_packet(p, check_crc=True) for i, p in enumerate(packets) if i != 4]
    ref = DecodedPackets(
        LivoxPoints.concat([s.points for s in singles]), ImuSamples.concat([s.imu for s in singles])
    )
    for field in ("points", "reflectivity", "tag", "return_index", "t_ns", "hit"):
        np.testing.assert_array_equal(getattr(batch.points, field), getattr(ref.points, field))
    for field in ("t_ns", "gyro", "acc"):
        np.testing.assert_array_equal(getattr(batch.imu, field), getattr(ref.imu, field))
    assert len(batch.imu) > 0


@given(
    st.sampled_from([1, 2, 3]),
    st.integers(1, 300),
    st.integers(0, 2**32),
    st.integers(1, 6000),
)
@settings(max_examples=60, deadline=None)
def test_encode_then_decode_gives_the_arrays_back(
    data_type: int, N: int, seed: int, dt: int
) -> None:
    rng = np.random.default_rng(seed)
    reach = 300.0 if data_type == 2 else 1000.0  # the 16-bit type holds ±327.67 m
    points = rng.uniform(-reach, reach, (N, 3))
    refl, tag = rng.integers(0, 256, (2, N), dtype=np.uint8)
    packets = s2.encode_point_packets(
        points, refl, tag, data_type=data_type, t0_ns=T0, point_interval_ns=dt
    )
    assert len(packets) == -(-N // 96)
    pts = s2.decode_packets(packets, check_crc=True)[0].points
    assert len(pts) == N
    error = np.linalg.norm(pts.points - points, axis=1)
    # half a quantum per axis (mm or cm); spherical: 0.5 mm of depth + √2 · 0.005° of arc
    bound = {
        1: 0.0005 * math.sqrt(3),
        2: 0.005 * math.sqrt(3),
        3: 0.0005 + np.linalg.norm(points, axis=1) * math.radians(0.005) * 2,
    }[data_type]
    assert np.all(error <= bound + 1e-9)
    assert (pts.reflectivity.tolist(), pts.tag.tolist()) == (refl.tolist(), tag.tolist())
    # time_interval is in 0.1 µs: each time is within 100 ns of t0 + i·Δt
    assert np.all(np.abs(pts.t_ns - (T0 + np.arange(N) * dt)) <= 100)


def test_encoder_refuses_what_the_wire_cannot_hold() -> None:
    one = np.zeros(1, np.uint8)
    with pytest.raises(InputError, match="out of range"):
        s2.encode_point_packets(
            np.array([[400.0, 0, 0]]), one, data_type=2, t0_ns=0, point_interval_ns=1
        )
    with pytest.raises(InputError, match=r"6\.5535 ms"):
        s2.encode_point_packets(
            np.zeros((96, 3)), np.zeros(96, np.uint8), t0_ns=0, point_interval_ns=100_000
        )
    with pytest.raises(InputError, match="not a point type"):
        s2.encode_point_packets(np.zeros((1, 3)), one, data_type=0, t0_ns=0, point_interval_ns=1)
    with pytest.raises(InputError, match="IP address"):
        c2.HostIpConfig("host", 1, 2).encode()
    with pytest.raises(InputError, match="exceeds 1400"):
        c2.encode_frame(c2.CommandFrame(0x0100, 0, 1, bytes(1377)))
    imu = s2.encode_imu_packets(np.array([T0, T0 + 5]), np.ones((2, 3)), np.zeros((2, 3)))
    assert s2.decode_packets(imu)[0].imu.t_ns.tolist() == [T0, T0 + 5]


GOOD = [_points_packet(1), _points_packet(3, n=10), _packet(0, bytes(24), 1)]


@given(damaged_packets(GOOD, header_bytes=36), st.booleans())
@settings(max_examples=300, deadline=None)
def test_damaged_packets_give_decode_errors_or_a_malformed_count(buf: bytes, check: bool) -> None:
    try:
        s2.decode_packet(buf, check_crc=check)
        single_ok = True
    except DecodeError:
        single_ok = False
    decoded, bad = s2.decode_packets([GOOD[0], buf], check_crc=check)
    assert bad == (0 if single_ok else 1)
    assert len(decoded.points) >= 96


@given(st.binary(max_size=80))
@settings(max_examples=200, deadline=None)
def test_damaged_frames_and_payloads_give_only_decode_errors(buf: bytes) -> None:
    decoders = (
        c2.decode_frame,
        c2.decode_key_values,
        c2.DiscoveryAck.decode,
        c2.HostIpConfig.decode,
        c2.ParamAck.decode,
    )
    for decode in decoders:
        with contextlib.suppress(DecodeError):
            decode(buf)


def test_parameter_queries_and_their_acks_against_hand_built_bytes() -> None:
    # query 0x0101: key_num u16, reserved u16, keys u16 (Livox-SDK2 command_impl.cpp)
    query = struct.pack("<HHHH", 2, 0, 0x8006, 0x0000)
    assert c2.encode_key_list([0x8006, 0x0000]) == query
    assert c2.decode_key_list(query) == [0x8006, 0x0000]
    # its ACK: ret_code u8, key_num u16, then {key, length, value} with no reserved field
    ack = struct.pack("<BHHHBHHB", 0, 2, 0x8006, 1, 0x01, 0x0000, 1, 3)
    assert c2.QueryAck.decode(ack) == c2.QueryAck(0, ((0x8006, b"\x01"), (0x0000, b"\x03")))
    assert c2.QueryAck(0, ((0x8006, b"\x01"), (0x0000, b"\x03"))).encode() == ack
    with pytest.raises(DecodeError, match="not 4"):
        c2.decode_key_list(query[:-1])
    with pytest.raises(DecodeError, match="does not hold 2 keys"):
        c2.decode_key_list(query[:-2])
    with pytest.raises(DecodeError, match="truncated"):
        c2.QueryAck.decode(ack[:-1])


def _kv(key: int, value: bytes) -> bytes:
    return struct.pack("<HH", key, len(value)) + value


def test_device_information_from_a_hand_built_inquiry_ack() -> None:
    # Livox-SDK2 QueryLivoxLidarFirmwareVer: key_num 1, reserved, key 0x8002
    assert c2.encode_key_list([0x8002]) == struct.pack("<HHH", 1, 0, 0x8002)
    # the ACK (document, 0x0101 and the key_value_list table): ret_code, key_num, then
    # sn uint8_t[16], product_info char[64], version_app uint8_t[4] aa.bb.cc.dd with
    # version_info[0] = aa, version_loader, version_hardware, mac uint8_t[6]
    # aa:bb:cc:dd:ee:ff with data[0] = aa, cur_work_state uint8_t; and a key not read
    items = [
        _kv(0x8000, b"47MDL9W0020022\0\0"),
        _kv(0x8001, b"Mid-360 2021/12/01".ljust(64, b"\0")),
        _kv(0x8002, bytes([10, 11, 6, 35])),
        _kv(0x8003, bytes([1, 2, 3, 4])),
        _kv(0x8004, bytes([0, 0, 0, 2])),
        _kv(0x8005, bytes([0x3C, 0x6D, 0x66, 0x01, 0xAB, 0xCD])),
        _kv(0x8006, b"\x01"),
        _kv(0x8007, struct.pack("<i", 4250)),  # core_temp, 42.50 °C: not read
    ]
    ack = struct.pack("<BH", 0, len(items)) + b"".join(items)
    info = c2.DeviceInfo.from_items(c2.QueryAck.decode(ack).items)
    assert info == c2.DeviceInfo(
        serial="47MDL9W0020022",
        product="Mid-360 2021/12/01",
        firmware="10.11.6.35",
        loader="1.2.3.4",
        hardware="0.0.0.2",
        mac="3c:6d:66:01:ab:cd",
        work_state=1,
    )
    assert info.work_state_name == "SAMPLING"
    # a device that leaves keys out: those are None
    only = struct.pack("<BH", 0, 1) + _kv(0x8002, bytes([1, 0, 0, 0]))
    assert c2.DeviceInfo.from_items(c2.QueryAck.decode(only).items) == c2.DeviceInfo(
        firmware="1.0.0.0"
    )
    assert c2.DeviceInfo().work_state_name is None
    assert c2.DeviceInfo(work_state=0x03).work_state_name == "unknown"


@pytest.mark.parametrize(
    ("key", "value"),
    [
        (0x8002, bytes(3)),  # version_app is 4 bytes
        (0x8005, bytes(7)),  # mac is 6
        (0x8006, b""),  # cur_work_state is 1
        (0x8000, bytes(17)),  # sn is at most 16
    ],
)
def test_device_information_of_the_wrong_length_raises(key: int, value: bytes) -> None:
    with pytest.raises(DecodeError, match=f"0x{key:04X}"):
        c2.DeviceInfo.from_items([(key, value)])


def test_host_configuration_alone_leaves_out_the_work_mode() -> None:
    data = c2.host_config_request("192.168.1.5", 1, 2, 3, work_mode=None)
    assert struct.unpack_from("<H", data)[0] == 3
    assert [k for k, _ in c2.decode_key_values(data)] == [5, 6, 7]


def test_packet_problem_names_what_is_wrong_or_nothing() -> None:
    assert s2.packet_problem(_points_packet(1)) is None
    assert s2.packet_problem(_points_packet(1)[:-1]) == "length field 1380 != 1379 bytes"
    assert s2.packet_problem(b"") == "0 bytes, shorter than the 36-byte header"
