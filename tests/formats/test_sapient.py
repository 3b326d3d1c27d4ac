"""SAPIENT (BSI Flex 335 v2.0): the framing, known answers from the protobuf wire format,
every message kind decoded by an independent decoder compiled here from the vendored
official .proto files and held to the rules of their field options (what Apex checks),
the look-at tasks, and the committed modules being what protoc makes of the .proto
files."""

from __future__ import annotations

import filecmp
import math
import struct
import subprocess
import sys
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("google.protobuf")
pytest.importorskip("grpc_tools")


from dronetrack.errors import SapientProtocolError
from dronetrack.formats.sapient import ICD_VERSION
from dronetrack.formats.sapient import messages as m
from dronetrack.formats.sapient.framing import FrameDecoder, encode_frame
from dronetrack.formats.sapient.rules import broken_rules
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0 import (
    task_pb2,
)
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)
from dronetrack.sinks.sapient.node import node_uuid
from sapient_helpers import official_decoder

ROOT = Path(__file__).resolve().parents[2]
PROTO_ROOT = ROOT / "src" / "dronetrack" / "formats" / "sapient"
T = 1_795_000_000.25  # a Unix time [s]
NODE = "6f1c1a3e-2a57-4a4a-9d55-3a1b8c2d4e5f"  # version-4 UUIDs, as the ICD wants them
FUSION = "0d7e4f5a-9b1c-4c3d-8e2f-1a2b3c4d5e6f"


def _ulid(seed: int) -> str:
    return m.new_ulid(np.random.default_rng(seed), T)


@pytest.fixture(scope="module")
def official() -> Any:
    """``SapientMessage`` of the independent decoder (``sapient_helpers``)."""
    return official_decoder()


def _decode(official: Any, message: SapientMessage) -> Any:
    """``message``'s bytes off the wire, through the independent decoder, which finds
    it keeps the definitions' rules."""
    frame = encode_frame(message)
    (size,) = struct.unpack("<I", frame[:4])
    assert size == len(frame) - 4
    got = official.FromString(frame[4:])
    assert type(got) is not SapientMessage
    assert broken_rules(got) == []
    return got


# ------------------------------------------------------------------------ framing


def test_a_registration_ack_is_the_bytes_the_wire_format_says() -> None:
    msg = SapientMessage()
    msg.registration_ack.acceptance = True
    # field 5 (registration_ack), wire type 2: tag (5 << 3) | 2 = 0x2a, length 2; inside,
    # field 1 (acceptance), wire type 0: tag 0x08, value 1; the length 4 before it, "<I"
    assert encode_frame(msg) == b"\x04\x00\x00\x00" + b"\x2a\x02\x08\x01"
    assert FrameDecoder().feed(b"\x04\x00\x00\x00\x2a\x02\x08\x01") == [msg]


def _stream_messages() -> list[SapientMessage]:
    return [
        m.registration_ack(FUSION, T, True),
        m.task_ack(NODE, T, _ulid(1), False, ["no turret"]),
        m.status_report(
            NODE,
            T,
            report_id=_ulid(2),
            location=(47.4, 19.2, 120.0),
            pointing=m.RangeBearing(45.0, 5.0, 190.0),
            field_of_view_deg=(70.4, 77.2),
        ),
        m.registration_ack(FUSION, T, False, "full"),
    ]


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(1, 60), min_size=1, max_size=30))
def test_any_chunking_of_a_stream_gives_the_same_messages(cuts: list[int]) -> None:
    messages = _stream_messages()
    frames = [encode_frame(x) for x in messages]
    stream = b"".join(frames)
    ends = set(np.cumsum([len(f) for f in frames]).tolist())  # where frames end
    decoder, got, i = FrameDecoder(), [], 0
    for cut in cuts * (len(stream) // sum(cuts) + 1):  # the cuts, repeated to the end
        got += decoder.feed(stream[i : i + cut])
        i = min(i + cut, len(stream))
        assert (decoder.pending == 0) == (i in ends)  # a frame begun, or not
        if i == len(stream):
            break
    assert got == messages
    assert decoder.pending == 0
    decoder.close()  # at a frame's end: nothing to refuse


def test_bad_streams_are_refused_in_one_line() -> None:
    with pytest.raises(SapientProtocolError, match="over the limit of 64"):
        FrameDecoder(max_bytes=64).feed(struct.pack("<I", 65))  # refused before its bytes
    assert FrameDecoder(max_bytes=64).feed(struct.pack("<I", 64)) == []  # 64 is allowed
    with pytest.raises(SapientProtocolError, match="is no SapientMessage"):
        FrameDecoder().feed(struct.pack("<I", 3) + b"\xff\xff\xff")
    with pytest.raises(SapientProtocolError, match="has no content"):
        FrameDecoder().feed(struct.pack("<I", 0))
    with pytest.raises(SapientProtocolError, match="has no content"):
        FrameDecoder().feed(encode_frame(SapientMessage(node_id=NODE)))
    decoder = FrameDecoder()
    assert decoder.feed(encode_frame(m.registration_ack(FUSION, T, True))[:5]) == []
    assert decoder.pending == 5
    with pytest.raises(SapientProtocolError, match="closed 5 bytes into a frame"):
        decoder.close()


# ------------------------------------------------------------------ every message


def test_the_registration_says_what_the_node_is(official: Any) -> None:
    reg = m.registration(
        NODE,
        T,
        name="dronetrack",
        short_name="dt",
        classes=("drone", "bird", "unknown"),
        status_period_s=5.0,
        field_of_view_deg=(70.4, 77.2),
        max_range_m=195.0,
        latency_s=0.1,
        model="avia on widowx",
        version="0.1.0",
    )
    got = _decode(official, reg)
    assert got.WhichOneof("content") == "registration"
    assert got.node_id == NODE
    r = got.registration
    assert r.icd_version == ICD_VERSION == "BSI Flex 335 v2.0"
    assert r.node_definition[0].node_type == 3  # NODE_TYPE_LIDAR
    assert r.status_definition.status_interval.value == pytest.approx(5.0)
    mode = r.mode_definition[0]
    assert mode.mode_name == "default"
    assert (mode.scan_type, mode.tracking_type) == (3, 3)  # STEERABLE, TRACK
    detection = mode.detection_definition[0]
    assert detection.location_type.location_units == 1  # LAT_LNG_DEG_M
    assert detection.location_type.location_datum == 1  # WGS84_E
    assert detection.velocity_type.enu_velocity_units.east_north_rate_units == 1  # m/s
    classes = [c.type for c in detection.detection_class_definition[0].class_definition]
    assert classes == ["drone", "bird", "unknown"]
    assert [c.type for c in mode.task.command] == [6]  # COMMAND_TYPE_LOOK_AT
    assert list(mode.task.region_definition.region_type) == [1]  # AREA_OF_INTEREST
    assert got.timestamp.seconds == 1_795_000_000
    assert got.timestamp.nanos == 250_000_000
    assert r.config_data[0].model == "avia on widowx"


def test_registration_acks_decode(official: Any) -> None:
    yes = _decode(official, m.registration_ack(FUSION, T, True)).registration_ack
    assert yes.acceptance
    no = _decode(official, m.registration_ack(FUSION, T, False, "full")).registration_ack
    assert no.HasField("acceptance")  # present, and false
    assert (no.acceptance, list(no.ack_response_reason)) == (False, ["full"])


def test_a_detection_report_carries_the_track(official: Any) -> None:
    rng = np.random.default_rng(7)
    object_id = m.new_ulid(rng, T)
    report = m.detection_report(
        NODE,
        T,
        report_id=m.new_ulid(rng, T),
        object_id=object_id,
        location=(47.4, 19.2, 140.5),
        sigma_enu_m=(2.0, 1.0, 0.5),
        range_bearing=m.RangeBearing(30.0, 10.0, 120.0, 0.5, 0.25, 0.3),
        velocity_enu=(3.0, -4.0, 0.5),
        velocity_sigma_enu=(0.2, 0.3, 0.1),
        classification=[("drone", 0.93), ("bird", 0.05)],
        track_id=12,
        frame_t=42.1,
        confidence=0.8,
        task_id=_ulid(3),
        track_info=[("speed_m_s", "5.02", 0.3), ("hovering", "no", None)],
    )
    d = _decode(official, report).detection_report
    assert d.object_id == object_id
    assert d.task_id == _ulid(3)
    assert d.detection_confidence == pytest.approx(0.8)
    loc = d.location
    assert (loc.y, loc.x, loc.z) == (47.4, 19.2, 140.5)
    # errors in the location's own units: 1 m north is 1/a rad of latitude
    assert loc.y_error == pytest.approx(math.degrees(1.0 / 6378137.0))
    assert loc.x_error == pytest.approx(
        math.degrees(2.0 / (6378137.0 * math.cos(math.radians(47.4))))
    )
    assert loc.z_error == 0.5
    assert (loc.coordinate_system, loc.datum) == (1, 1)  # LAT_LNG_DEG_M, WGS84_E
    assert d.WhichOneof("location_oneof") == "location"
    info = [(i.type, i.value, i.error if i.HasField("error") else None) for i in d.track_info]
    assert [i[0] for i in info] == [
        "range_m",
        "azimuth_deg",
        "elevation_deg",
        "track_id",
        "frame_t_s",
        "speed_m_s",
        "hovering",
    ]
    by_type = {i[0]: i[1:] for i in info}
    assert by_type["range_m"] == ("120.000", pytest.approx(0.3))
    assert by_type["azimuth_deg"] == ("30.000", pytest.approx(0.5))
    assert by_type["elevation_deg"] == ("10.000", pytest.approx(0.25))
    assert by_type["track_id"] == ("12", None)
    assert by_type["frame_t_s"] == ("42.100000", None)
    assert by_type["hovering"] == ("no", None)
    v = d.enu_velocity
    assert (v.east_rate, v.north_rate, v.up_rate) == (3.0, -4.0, 0.5)
    assert v.north_rate_error == pytest.approx(0.3)
    assert [(c.type, round(c.confidence, 6)) for c in d.classification] == [
        ("drone", 0.93),
        ("bird", 0.05),
    ]


def test_status_alert_and_acks_decode(official: Any) -> None:
    status = m.status_report(
        NODE,
        T,
        report_id=_ulid(1),
        location=(47.4, 19.2, 120.0),
        pointing=m.RangeBearing(45.0, 5.0, 190.0),
        field_of_view_deg=(70.4, 77.2),
        active_task=_ulid(2),
        notes=[("ptz_status", "tracking")],
    )
    s = _decode(official, status).status_report
    assert (s.system, s.info, s.mode, s.active_task_id) == (1, 1, "default", _ulid(2))
    assert (s.node_location.y, s.node_location.x, s.node_location.z) == (47.4, 19.2, 120.0)
    cone = s.field_of_view.range_bearing
    assert (cone.azimuth, cone.horizontal_extent) == (45.0, pytest.approx(70.4))
    assert (cone.coordinate_system, cone.datum) == (1, 1)  # DEGREES_M, TRUE
    assert [(x.status_type, x.status_value) for x in s.status] == [(8, "tracking")]  # PTZ
    with pytest.raises(ValueError, match="STATUS_TYPE_TURRET"):
        m.status_report(
            NODE,
            T,
            report_id="r",
            location=(0, 0, 0),
            pointing=None,
            field_of_view_deg=(1, 1),
            notes=[("turret", "x")],
        )
    unchanged = m.status_report(
        NODE,
        T,
        report_id=_ulid(3),
        location=(47.4, 19.2, 120.0),
        pointing=None,
        field_of_view_deg=(70.4, 77.2),
        ok=False,
        new=False,
    )
    u = _decode(official, unchanged).status_report
    assert (u.system, u.info) == (2, 2)  # SYSTEM_WARNING, INFO_UNCHANGED
    assert not u.HasField("field_of_view")
    object_id = _ulid(4)
    alert = m.alert(
        NODE,
        T,
        alert_id=_ulid(5),
        active=True,
        critical=True,
        description="drone track 3 inside zone 'depot'",
        location=(47.4, 19.2, 130.0),
        object_id=object_id,
        region_id=_ulid(6),
    )
    a = _decode(official, alert).alert
    assert (a.alert_type, a.status, a.priority) == (3, 1, 3)  # CRITICAL, ACTIVE, HIGH
    assert a.region_id == _ulid(6)
    assert (a.associated_detection[0].node_id, a.associated_detection[0].object_id) == (
        NODE,
        object_id,
    )
    clear = m.alert(
        NODE,
        T,
        alert_id=_ulid(7),
        active=False,
        critical=False,
        description="clear",
        location=(47.4, 19.2, 130.0),
        object_id=None,
    )
    c = _decode(official, clear).alert
    assert (c.alert_type, c.status, c.priority) == (2, 5, 2)  # WARNING, CLEAR, MEDIUM
    ack = _decode(official, m.task_ack(NODE, T, _ulid(8), False, ["no turret"])).task_ack
    assert (ack.task_id, ack.task_status, list(ack.reason)) == (_ulid(8), 2, ["no turret"])
    yes = _decode(official, m.task_ack(NODE, T, _ulid(8), True)).task_ack
    assert (yes.task_status, list(yes.reason)) == (1, [])  # TASK_STATUS_ACCEPTED
    alert_ack = _decode(official, m.alert_ack(FUSION, T, _ulid(5), True, destination=NODE))
    assert alert_ack.destination_id == NODE
    assert (alert_ack.alert_ack.alert_id, alert_ack.alert_ack.alert_ack_status) == (_ulid(5), 1)


# ------------------------------------------------------------- the ICD's rules


def test_the_rules_catch_what_apex_would_refuse(official: Any) -> None:
    """Known answers for the rules checker itself, on the independent decoder's
    messages: each breach is found and named."""
    good = official.FromString(encode_frame(m.task_ack(NODE, T, _ulid(1), True))[4:])
    assert broken_rules(good) == []
    v5 = str(uuid.uuid5(uuid.NAMESPACE_URL, "dronetrack"))
    cases: list[tuple[Callable[[Any], None], str]] = [
        (lambda x: setattr(x, "node_id", v5), "node_id: '" + v5 + "' is no lower-case version-4"),
        (lambda x: setattr(x, "node_id", NODE.upper()), "node_id: '" + NODE.upper()),
        (lambda x: x.ClearField("timestamp"), "timestamp: mandatory, missing"),
        (lambda x: x.task_ack.ClearField("task_id"), "task_ack.task_id: mandatory, missing"),
        (lambda x: setattr(x.task_ack, "task_id", "t1"), "task_ack.task_id: 't1' is no upper"),
        (lambda x: setattr(x.task_ack, "task_status", 9), "task_ack.task_status: 9 is no"),
        (lambda x: x.ClearField("task_ack"), "content: none of its fields is set"),
    ]
    for spoil, expected in cases:
        bad = official.FromString(good.SerializeToString())
        spoil(bad)
        assert [b for b in broken_rules(bad) if b.startswith(expected)], (expected, bad)


def test_the_edge_nodes_ids_keep_the_rules() -> None:
    a = node_uuid("depot", 47.4, 19.2)
    assert a == node_uuid("depot", 47.4, 19.2)  # a site keeps its ID from run to run
    assert a != node_uuid("depot", 47.4, 19.3)
    assert uuid.UUID(a).version == 4
    assert broken_rules(m.task_ack(a, T, _ulid(1), True)) == []


# ------------------------------------------------------------------- look-at tasks


def _task(control: int = task_pb2.Task.CONTROL_START) -> task_pb2.Task:
    return task_pb2.Task(task_id="T1", control=control)


def _location_task(points: list[tuple[float, float]], system: int = 1, datum: int = 1) -> Any:
    task = _task()
    where = task.command.look_at.location_list
    for lat, lon in points:
        where.locations.add(x=lon, y=lat, coordinate_system=system, datum=datum)
    return task


def _cone_task(system: int = 1, datum: int = 1, **values: float) -> Any:
    task = _task()
    rb = task.command.look_at.range_bearing
    for name, value in values.items():
        setattr(rb, name, value)
    rb.coordinate_system, rb.datum = system, datum
    return task


def test_look_at_tasks_are_read_in_degrees_and_metres() -> None:
    got = m.look_at(_location_task([(47.40, 19.20), (47.42, 19.24)]))
    assert isinstance(got, m.LookAt)
    assert got.point == m.LookAtPoint(pytest.approx(47.41), pytest.approx(19.22), None)
    radians = _location_task([(math.radians(47.4), math.radians(19.2))], system=2)
    got = m.look_at(radians)
    assert isinstance(got, m.LookAt)
    assert got.point is not None
    assert (got.point.latitude, got.point.longitude) == (pytest.approx(47.4), pytest.approx(19.2))
    cone = _cone_task(azimuth=250.0, range=80.0)
    assert m.look_at(cone) == m.LookAt("T1", bearing=m.RangeBearing(250.0, 0.0, 80.0))
    km = _cone_task(system=4, azimuth=math.pi / 2, elevation=0.1, range=0.3)  # RADIANS_KM
    got = m.look_at(km)
    assert isinstance(got, m.LookAt)
    assert got.bearing is not None
    assert got.bearing.azimuth == pytest.approx(90.0)
    assert got.bearing.elevation == pytest.approx(math.degrees(0.1))
    assert got.bearing.range == pytest.approx(300.0)
    no_range = m.look_at(_cone_task(azimuth=10.0))
    assert isinstance(no_range, m.LookAt)
    assert no_range.bearing is not None
    assert no_range.bearing.range == 100.0  # DEFAULT_LOOK_AT_RANGE_M
    assert m.look_at(_task(task_pb2.Task.CONTROL_STOP)) == m.LookAt("T1", stop=True)
    assert m.look_at(_task(task_pb2.Task.CONTROL_PAUSE)) == m.LookAt("T1", stop=True)
    geoid_no_altitude = _location_task([(47.4, 19.2)], datum=2)
    assert isinstance(m.look_at(geoid_no_altitude), m.LookAt)  # lat/lon are the same


def test_other_tasks_are_refused_with_the_reason() -> None:
    mode = _task()
    mode.command.mode_change = "night"
    utm = _location_task([(5_000_000.0, 400_000.0)], system=5)
    geoid = _location_task([(47.4, 19.2)], datum=2)
    geoid.command.look_at.location_list.locations[0].z = 150.0
    empty = _task()
    empty.command.look_at.location_list.SetInParent()
    cases = [
        (_task(task_pb2.Task.CONTROL_UNSPECIFIED), "the task has no control"),
        (_task(), "the task has no command"),
        (mode, "the command mode_change is not done"),
        (utm, "not latitude and longitude"),
        (geoid, "not above the WGS-84 ellipsoid"),
        (empty, "the look_at location list is empty"),
        (_cone_task(datum=2, azimuth=10.0), "not from true north"),  # magnetic
        (_cone_task(system=0, azimuth=10.0), "has no units"),
        (_cone_task(elevation=3.0), "has no azimuth"),
    ]
    for task, reason in cases:
        got = m.look_at(task)
        assert isinstance(got, str), reason
        assert reason in got
        assert "\n" not in got


def test_a_look_at_task_goes_through_the_independent_decoder(official: Any) -> None:
    point = m.look_at_task(FUSION, NODE, T, _ulid(1), point=(51.5, -0.12, 60.0))
    got = _decode(official, point)
    assert (got.node_id, got.destination_id) == (FUSION, NODE)
    location = got.task.command.look_at.location_list.locations[0]
    assert (location.y, location.x, location.z) == (51.5, -0.12, 60.0)
    back = SapientMessage.FromString(got.SerializeToString())
    assert m.look_at(back.task) == m.LookAt(_ulid(1), point=m.LookAtPoint(51.5, -0.12, 60.0))
    bearing = m.RangeBearing(120.0, 4.0, 250.0)
    along = _decode(official, m.look_at_task(FUSION, NODE, T, _ulid(2), bearing=bearing))
    back = SapientMessage.FromString(along.SerializeToString())
    assert m.look_at(back.task) == m.LookAt(_ulid(2), bearing=bearing)
    with pytest.raises(ValueError, match="a point or a bearing"):
        m.look_at_task(FUSION, NODE, T, _ulid(3))


# ------------------------------------------------------------------------- IDs, code


def test_ulids_carry_their_time_and_come_from_the_generator() -> None:
    from ulid import ULID

    a = m.new_ulid(np.random.default_rng(3), T)
    assert a == m.new_ulid(np.random.default_rng(3), T)  # seeded
    assert a != m.new_ulid(np.random.default_rng(4), T)
    assert len(a) == 26
    assert ULID.from_str(a).milliseconds == int(T * 1000)
    assert m.timestamp(T).seconds == 1_795_000_000
    assert m.timestamp(T).nanos == 250_000_000


def test_a_missing_extra_is_one_line_with_the_install_hint(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import importlib

    from dronetrack.errors import MissingExtraError
    from dronetrack.formats.sapient import require_sapient

    require_sapient()  # installed here
    real = importlib.import_module

    def without_ulid(name: str, package: str | None = None) -> Any:
        if name == "ulid":
            raise ImportError("No module named 'ulid'")
        return real(name, package)

    monkeypatch.setattr(importlib, "import_module", without_ulid)
    with pytest.raises(MissingExtraError, match=r"pip install 'dronetrack\[sapient\]'"):
        require_sapient()


def test_the_committed_modules_are_what_protoc_makes_of_the_protos(tmp_path: Path) -> None:
    """tools/sapient_protoc.py, run afresh, writes exactly the committed modules."""
    done = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "sapient_protoc.py"), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        check=False,
        timeout=60,
    )
    assert done.returncode == 0, done.stderr
    made = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*_pb2.py*"))
    committed = sorted(p.relative_to(PROTO_ROOT) for p in PROTO_ROOT.rglob("*_pb2.py*"))
    assert made == committed
    assert len(made) == 2 * 17  # v2.0's 16 definitions and proto_options, .py and .pyi
    _, mismatch, errors = filecmp.cmpfiles(
        tmp_path, PROTO_ROOT, [str(p) for p in made], shallow=False
    )
    assert mismatch == []
    assert errors == []
    for path in made:  # no top-level sapient_msg import is left
        text = (tmp_path / path).read_text()
        assert "from sapient_msg" not in text
        assert "import sapient_msg" not in text
