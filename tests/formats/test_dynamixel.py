"""DYNAMIXEL Protocol 2.0 packets against the examples of the protocol document
(ROBOTIS e-manual, docs/en/dxl/protocol2.md), and the stream parser's properties."""

from __future__ import annotations

import contextlib
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import DecodeError
from dronetrack.formats.dynamixel import (
    BadPacket,
    Err,
    Inst,
    Packet,
    PacketParser,
    accel_to_units,
    crc16,
    decode_packet,
    encode_instruction,
    encode_status,
    rad_to_ticks,
    rate_to_units,
    read_params,
    stuff,
    sync_read_params,
    sync_write_params,
    ticks_to_rad,
    units_to_rate,
    unstuff,
)


def _hex(text: str) -> bytes:
    return bytes.fromhex(text)


# (packet bytes from the protocol document, what it decodes to)
DOCUMENT_PACKETS = [
    ("FF FF FD 00 01 03 00 01 19 4E", Packet(1, Inst.PING)),  # ping ID 1
    ("FF FF FD 00 FE 03 00 01 31 42", Packet(0xFE, Inst.PING)),  # broadcast ping
    # ping status of an XM430-W210: model 1030, firmware 38
    ("FF FF FD 00 01 07 00 55 00 06 04 26 65 5D", Packet(1, Inst.STATUS, _hex("00 06 04 26"))),
    ("FF FF FD 00 02 07 00 55 00 06 04 26 6F 6D", Packet(2, Inst.STATUS, _hex("00 06 04 26"))),
    # read present position (132, 4 bytes) of ID 1, and its status (166)
    ("FF FF FD 00 01 07 00 02 84 00 04 00 1D 15", Packet(1, Inst.READ, read_params(132, 4))),
    (
        "FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0",
        Packet(1, Inst.STATUS, _hex("00 A6 00 00 00")),
    ),
    # write 512 to goal position (116) of ID 1, and its status
    (
        "FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89",
        Packet(1, Inst.WRITE, _hex("74 00 00 02 00 00")),
    ),
    ("FF FF FD 00 01 04 00 55 00 A1 0C", Packet(1, Inst.STATUS, b"\x00")),
    ("FF FF FD 00 01 03 00 08 2F 4E", Packet(1, Inst.REBOOT)),  # reboot ID 1
    # sync read of present position of IDs 1 and 2, and the status of ID 2 (2079)
    (
        "FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA",
        Packet(0xFE, Inst.SYNC_READ, sync_read_params(132, 4, [1, 2])),
    ),
    (
        "FF FF FD 00 02 08 00 55 00 1F 08 00 00 BA BE",
        Packet(2, Inst.STATUS, _hex("00 1F 08 00 00")),
    ),
    # sync write of goal position 150 to ID 1 and 170 to ID 2
    (
        "FF FF FD 00 FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00 82 87",
        Packet(
            0xFE,
            Inst.SYNC_WRITE,
            sync_write_params(
                116, 4, {1: (150).to_bytes(4, "little"), 2: (170).to_bytes(4, "little")}
            ),
        ),
    ),
]


@pytest.mark.parametrize(("text", "packet"), DOCUMENT_PACKETS)
def test_document_examples_encode_and_decode(text: str, packet: Packet) -> None:
    raw = _hex(text)
    assert decode_packet(raw) == packet
    if packet.is_status:
        assert encode_status(packet.ident, packet.error, packet.data) == raw
    else:
        assert encode_instruction(packet.ident, packet.instruction, packet.params) == raw


def test_status_error_byte_is_a_number_with_an_alert_bit() -> None:
    """Bits 0–6 hold one error number (7 = access error is 0b111, not three flags);
    bit 7 is the alert."""
    status = decode_packet(encode_status(1, Err.ALERT | Err.ACCESS))
    assert (status.error_number, status.alert) == (Err.ACCESS, True)
    status = decode_packet(encode_status(1, Err.CRC))
    assert (status.error_number, status.alert, status.data) == (Err.CRC, False, b"")


def test_crc_of_the_ping_example_and_its_check_value() -> None:
    assert crc16(_hex("FF FF FD 00 01 03 00 01")) == 0x4E19
    # CRC-16/UMTS (poly 0x8005, init 0, unreflected) check value of "123456789"
    assert crc16(b"123456789") == 0xFEE8


def test_stuffing_inserts_fd_after_each_header_pattern() -> None:
    assert stuff(_hex("03 FF FF FD 01")) == _hex("03 FF FF FD FD 01")
    assert stuff(_hex("FF FF FD FD")) == _hex("FF FF FD FD FD")
    packet = encode_instruction(1, Inst.WRITE, _hex("74 00 FF FF FD 00"))
    assert packet[5:7] == (3 + 6 + 1).to_bytes(2, "little")  # LEN counts the stuffed byte
    assert decode_packet(packet).params == _hex("74 00 FF FF FD 00")


# Bodies rich in FF and FD, so that header patterns (and runs of them) are common.
_bodies = st.lists(st.sampled_from([0x00, 0x42, 0xFD, 0xFF]), max_size=40).map(bytes) | st.binary(
    max_size=40
)


@given(_bodies)
def test_stuffing_round_trips_and_hides_every_header(body: bytes) -> None:
    stuffed = stuff(body)
    assert unstuff(stuffed) == body
    i = stuffed.find(b"\xff\xff\xfd")
    while i >= 0:
        assert stuffed[i + 3 : i + 4] == b"\xfd"
        i = stuffed.find(b"\xff\xff\xfd", i + 1)


def test_unstuff_rejects_a_bare_header_pattern() -> None:
    with pytest.raises(DecodeError, match="stuffed FD"):
        unstuff(_hex("03 FF FF FD 01"))


_packets = st.builds(
    Packet,
    ident=st.integers(0, 0xFC),
    instruction=st.sampled_from([Inst.PING, Inst.READ, Inst.WRITE, Inst.SYNC_READ, Inst.STATUS]),
    params=_bodies,
).filter(lambda p: not p.is_status or len(p.params) >= 1)


def _encode(p: Packet) -> bytes:
    if p.is_status:
        return encode_status(p.ident, p.params[0], p.params[1:])
    return encode_instruction(p.ident, p.instruction, p.params)


@settings(max_examples=150)
@given(
    st.lists(_packets, min_size=1, max_size=5),
    st.binary(max_size=12).map(lambda b: b.replace(b"\xfd", b"\x00")),
    st.data(),
)
def test_parser_finds_packets_in_any_chunking(
    packets: list[Packet], garbage: bytes, data: st.DataObject
) -> None:
    stream = garbage + b"".join(_encode(p) for p in packets)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=8)))
    parser, found = PacketParser(), []
    for a, b in zip([0, *cuts], [*cuts, len(stream)], strict=True):
        found += parser.feed(stream[a:b])
    assert found == packets
    assert parser.pending == 0
    assert parser.skipped == len(garbage)


def test_parser_reports_a_bad_crc_and_recovers() -> None:
    good = encode_instruction(1, Inst.PING)
    bad = bytearray(encode_instruction(2, Inst.READ, read_params(132, 4)))
    bad[-1] ^= 0x01
    found = PacketParser().feed(bytes(bad) + good)
    assert len(found) == 2
    assert isinstance(found[0], BadPacket)
    assert (found[0].crc, found[0].ident, found[0].instruction) == (True, 2, Inst.READ)
    assert "CRC mismatch" in found[0].reason
    assert found[1] == Packet(1, Inst.PING)


def test_parser_does_not_let_a_corrupt_length_swallow_the_next_packet() -> None:
    good = encode_instruction(1, Inst.PING)
    broken = bytearray(encode_instruction(2, Inst.PING))
    broken[5] = 0x40  # LEN 64: the frame runs into the next packet, whose CRC then fails
    parser = PacketParser()
    found = parser.feed(bytes(broken) + good + bytes(64))
    assert isinstance(found[0], BadPacket)
    assert found[1] == Packet(1, Inst.PING)


def test_parser_waits_for_the_rest_of_a_packet() -> None:
    raw, parser = encode_instruction(1, Inst.PING), PacketParser()
    assert parser.feed(raw[:6]) == []
    assert parser.pending == 6
    assert parser.feed(raw[6:]) == [Packet(1, Inst.PING)]


@pytest.mark.parametrize(
    ("raw", "message"),
    [
        (b"", "fewer than the 10"),
        (_hex("FF FF FD 01 01 03 00 01 19 4E"), "does not start with"),
        (_hex("FF FF FD 00 FD 03 00 01 19 4E"), "reserved"),
        (_hex("FF FF FD 00 01 02 00 01 19 4E"), "LEN 2 < 3"),
        (_hex("FF FF FD 00 01 04 00 01 19 4E"), "says 11 bytes, has 10"),
        (_hex("FF FF FD 00 01 03 00 01 19 4F"), "CRC mismatch"),
    ],
)
def test_malformed_packets_raise_decode_error_naming_the_problem(raw: bytes, message: str) -> None:
    with pytest.raises(DecodeError, match=message):
        decode_packet(raw)


def test_a_status_without_its_error_byte_is_malformed() -> None:
    body = _hex("FF FF FD 00 01 03 00 55")
    raw = body + crc16(body).to_bytes(2, "little")
    with pytest.raises(DecodeError, match="no error byte"):
        decode_packet(raw)


@settings(max_examples=300)
@given(st.binary(max_size=40))
def test_arbitrary_bytes_decode_or_raise_decode_error(raw: bytes) -> None:
    with contextlib.suppress(DecodeError):
        decode_packet(b"\xff\xff\xfd\x00" + raw)
    for item in PacketParser().feed(b"\xff\xff\xfd\x00" + raw):
        assert isinstance(item, Packet | BadPacket)


def test_units_against_the_xm430_manual() -> None:
    # 4096 ticks per turn, 2048 = 0 rad; 0.088° per tick
    assert ticks_to_rad(2048) == 0.0
    assert ticks_to_rad(3072) == pytest.approx(math.pi / 2)
    assert rad_to_ticks(-math.pi / 2) == 1024
    assert math.degrees(ticks_to_rad(2049)) == pytest.approx(0.088, abs=5e-4)
    # 180°/s = 30 rpm = 131 × 0.229 rpm (the WidowX's Velocity_Limit 131)
    assert rate_to_units(math.pi) == 131
    assert units_to_rate(131) == pytest.approx(math.pi, rel=2e-4)
    # 360°/s² = 3600 rev/min² ≈ 16.8 × 214.577 rev/min²
    assert accel_to_units(2 * math.pi) == 17
