"""The FLIR PTU ASCII command set: replies as the PTU-D46 User's Manual (v2.14.0,
§4.2-4.5) prints them, written here by hand, and the position conversions against
its worked example."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.errors import DecodeError
from dronetrack.formats.ptu import (
    ARCSEC,
    CommandSplitter,
    Reply,
    angle_to_position,
    byte_time,
    parse_number,
    parse_reply,
    position_to_angle,
    split_lines,
)


@pytest.mark.parametrize(
    ("line", "want"),
    [
        ("*", Reply(True)),  # a command carried out (§4.2: "*<CR>")
        ("* 185.1428", Reply(True, "185.1428")),  # PR, terse (§4.3.3)
        ("* -3090", Reply(True, "-3090")),  # PN, terse (§4.3.4)
        ("* Current pan position is 0", Reply(True, "Current pan position is 0")),  # FV
        (
            "! Maximum allowable Pan position is 3090",  # PP3200 with limits on (§4.3.4)
            Reply(False, message="Maximum allowable Pan position is 3090"),
        ),
        (
            "! Pan speed cannot exceed 2902 positions/sec",  # PS3300 (§4.4.6)
            Reply(False, message="Pan speed cannot exceed 2902 positions/sec"),
        ),
        ("!T!T!P!P*", Reply(True, limit_hits="!T!T!P!P")),  # a reset (flir_ptu driver)
        ("PP * 22", Reply(True, "22")),  # with echo on (§4.5.3: "PP * 22")
        ("ED *", Reply(True)),
    ],
)
def test_replies_as_the_manual_prints_them(line: str, want: Reply) -> None:
    assert parse_reply(line) == want
    assert parse_reply(line + "\r") == want


@pytest.mark.parametrize("line", ["PP", "!P", "!T!P", "   "])
def test_an_echo_or_a_lone_limit_marker_is_no_reply(line: str) -> None:
    assert parse_reply(line) is None


def test_terse_numbers_and_a_verbose_answer() -> None:
    assert parse_number(Reply(True, "185.1428"), "PR") == pytest.approx(185.1428)
    assert parse_number(Reply(True, "-907"), "TN") == -907
    with pytest.raises(DecodeError, match="PP: expected a number"):
        parse_number(Reply(True, "Current pan position is 0"), "PP")
    with pytest.raises(DecodeError):
        parse_number(Reply(True, "nan"), "PP")


def test_lines_end_at_cr_lf_or_both() -> None:
    lines, rest = split_lines(b"* 1\r\n*\r! Illegal argument\n\r\n* 4")
    assert lines == ["* 1", "*", "! Illegal argument"]
    assert rest == b"* 4"
    assert split_lines(b"* 12") == ([], b"* 12")


def test_the_manuals_worked_example_of_resolution() -> None:
    # §4.3.3: 185.1428 seconds arc per position = 0.0514285°; 21.3° left: 21.3 / 0.0514285 =
    # 414.2 positions
    r = 185.1428
    assert math.degrees(r * ARCSEC) == pytest.approx(0.0514285, abs=1e-7)
    assert angle_to_position(math.radians(21.3), r, "pan") == 414
    assert math.degrees(position_to_angle(414, r, "pan")) == pytest.approx(21.2914, abs=1e-4)


def test_the_units_tilt_grows_up_the_turrets_down() -> None:
    # the D46's TX 604 is 31° up: the turret's tilt -31.06°
    r = 185.1428
    assert math.degrees(position_to_angle(604, r, "tilt")) == pytest.approx(-31.06, abs=0.01)
    assert angle_to_position(math.radians(10.0), r, "tilt") == -194


@given(
    st.integers(-100_000, 100_000),
    st.sampled_from(["pan", "tilt"]),
    st.floats(1.0, 400.0),
)
def test_positions_round_trip(position: int, axis: str, arcsec: float) -> None:
    assert angle_to_position(position_to_angle(position, arcsec, axis), arcsec, axis) == position


def test_a_byte_is_ten_bit_times() -> None:
    assert byte_time(9600) == pytest.approx(1.0 / 960.0)


def test_the_units_side_splits_commands_at_space_cr_or_lf() -> None:
    splitter = CommandSplitter(max_length=8)
    assert splitter.feed(b"pp tp1500\r") == [("PP", 2), ("TP1500", 9)]
    assert splitter.feed(b"  PS") == []
    assert splitter.pending
    assert splitter.feed(b"2900\n") == [("PS2900", 4)]
    assert splitter.feed(b"X" * 20 + b" ") == [("XXXXXXXX…", 20)]
    assert not splitter.pending
