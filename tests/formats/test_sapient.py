"""SAPIENT (BSI Flex 335 v2.0): the framing, known answers from the protobuf wire format,
every message kind decoded by an independent decoder compiled here from the vendored
official .proto files, the look-at tasks, and the committed modules being what protoc
makes of the .proto files."""

from __future__ import annotations

import filecmp
import math
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("google.protobuf")
pytest.importorskip("grpc_tools")

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

from dronetrack.errors import SapientProtocolError
from dronetrack.formats.sapient import ICD_VERSION
from dronetrack.formats.sapient import messages as m
from dronetrack.formats.sapient.framing import (
    FrameDecoder,
    encode_frame,
)
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0 import (
    location_pb2,
    range_bearing_pb2,
    task_pb2,
)
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)

ROOT = Path(__file__).resolve().parents[2]
PROTO_ROOT = ROOT / "src" / "dronetrack" / "formats" / "sapient"
T = 1_795_000_000.25  # a Unix time [s]


@pytest.fixture(scope="module")
def official(tmp_path_factory: pytest.TempPathFactory) -> Any:
    """``SapientMessage`` of an independent decoder: the vendored .proto files compiled
    here by protoc into a descriptor set, loaded into a pool of their own."""
    from grpc_tools import protoc

    out = tmp_path_factory.mktemp("descriptors") / "sapient.pb"
    include = Path(protoc.__file__).parent / "_proto"
    protos = sorted(str(p.relative_to(PROTO_ROOT)) for p in PROTO_ROOT.rglob("*.proto"))
    args = ["protoc", f"-I{PROTO_ROOT}", f"-I{include}", "--include_imports"]
    assert protoc.main([*args, f"--descriptor_set_out={out}", *protos]) == 0
    files = descriptor_pb2.FileDescriptorSet.FromString(out.read_bytes())
    pool = descriptor_pool.DescriptorPool()
    for file in files.file:
        pool.Add(file)
    name = "sapient_msg.bsi_flex_335_v2_0.SapientMessage"
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(name))


def _decode(official: Any, message: SapientMessage) -> Any:
    """``message``'s bytes off the wire, through the independent decoder."""
    frame = encode_frame(message)
    (size,) = struct.unpack("<I", frame[:4])
    assert size == len(frame) - 4
    return official.FromString(frame[4:])


def test_a_registration_ack_is_the_bytes_the_wire_format_says() -> None:
    msg = SapientMessage()
    msg.registration_ack.acceptance = True
    # field 5 (registration_ack), wire type 2: tag (5 << 3) | 2 = 0x2a, length 2; inside,
    # field 1 (acceptance), wire type 0: tag 0x08, value 1; the length 4 before it, "<I"
    assert encode_frame(msg) == b"\x04\x00\x00\x00" + b"\x2a\x02\x08\x01"
    assert FrameDecoder().feed(b"\x04\x00\x00\x00\x2a\x02\x08\x01") == [msg]


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(1, 40), min_size=1, max_size=30))
def test_any_chunking_of_a_stream_gives_the_same_messages(cuts: list[int]) -> None:
    messages = [
        m.registration_ack("n", T, True),
        m.task_ack("n", T, "01HF7YAT00Z2YH0HDRX36MXA9X", False, ["no turret"]),
        m.registration_ack("n", T, False, "full"),
    ]
    stream = b"".join(encode_frame(x) for x in messages)
    decoder, got, i = FrameDecoder(), [], 0
    for cut in cuts * (len(stream) // sum(cuts) + 1):
        got += decoder.feed(stream[i : i + cut])
        i += cut
        if i >= len(stream):
            break
    assert got == messages
    assert decoder.pending == 0


def test_bad_streams_are_refused_in_one_line() -> None:
    with pytest.raises(SapientProtocolError, match="over the limit of 64"):
        FrameDecoder(max_bytes=64).feed(struct.pack("<I", 65))  # refused before its bytes
    with pytest.raises(SapientProtocolError, match="is no SapientMessage"):
        FrameDecoder().feed(struct.pack("<I", 3) + b"\xff\xff\xff")
    with pytest.raises(SapientProtocolError, match="has no content"):
        FrameDecoder().feed(struct.pack("<I", 0))
    decoder = FrameDecoder()
    assert decoder.feed(encode_frame(m.registration_ack("n", T, True))[:5]) == []
    with pytest.raises(SapientProtocolError, match="closed 5 bytes into a frame"):
        decoder.close()


def test_the_registration_says_what_the_node_is(official: Any) -> None:
    reg = m.registration(
        "6f1c1a3e-2a57-5a4a-9d55-3a1b8c2d4e5f",
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
    r = got.registration
    assert r.icd_version == ICD_VERSION == "BSI Flex 335 v2.0"
    assert r.node_definition[0].node_type == 3  # NODE_TYPE_LIDAR
    assert r.status_definition.status_interval.value == pytest.approx(5.0)
    mode = r.mode_definition[0]
    assert (mode.scan_type, mode.tracking_type) == (3, 3)  # STEERABLE, TRACK
    detection = mode.detection_definition[0]
    assert detection.location_type.location_units == 1  # LAT_LNG_DEG_M
    classes = [c.type for c in detection.detection_class_definition[0].class_definition]
    assert classes == ["drone", "bird", "unknown"]
    assert [c.type for c in mode.task.command] == [6]  # COMMAND_TYPE_LOOK_AT
    assert got.timestamp.seconds == 1_795_000_000
    assert got.timestamp.nanos == 250_000_000
    assert r.config_data[0].model == "avia on widowx"


def test_a_detection_report_carries_the_track(official: Any) -> None:
    rng = np.random.default_rng(7)
    object_id = m.new_ulid(rng, T)
    report = m.detection_report(
        "node",
        T,
        report_id=m.new_ulid(rng, T),
        object_id=object_id,
        location=(47.4, 19.2, 140.5),
        sigma_enu_m=(2.0, 1.0, 0.5),
        range_bearing=m.RangeBearing(30.0, 10.0, 120.0, 0.5, 0.25, 0.3),
        velocity_enu=(3.0, -4.0, 0.5),
        velocity_sigma_enu=(0.2, 0.3, 0.1),
        classification=("drone", 0.93),
        track_id=12,
        frame_t=42.1,
    )
    d = _decode(official, report).detection_report
    assert d.object_id == object_id
    loc = d.location
    assert (loc.y, loc.x, loc.z) == (47.4, 19.2, 140.5)
    # errors in the location's own units: 1 m north is 1/a rad of latitude
    assert loc.y_error == pytest.approx(math.degrees(1.0 / 6378137.0))
    assert loc.x_error == pytest.approx(
        math.degrees(2.0 / (6378137.0 * math.cos(math.radians(47.4))))
    )
    assert loc.z_error == 0.5
    assert (loc.coordinate_system, loc.datum) == (1, 1)  # LAT_LNG_DEG_M, WGS84_E
    info = {i.type: (i.value, i.error) for i in d.track_info}
    assert info["range_m"] == ("120.000", pytest.approx(0.3))
    assert info["azimuth_deg"] == ("30.000", pytest.approx(0.5))
    assert info["track_id"][0] == "12"
    assert info["frame_t_s"][0] == "42.100000"
    v = d.enu_velocity
    assert (v.east_rate, v.north_rate, v.up_rate) == (3.0, -4.0, 0.5)
    assert v.north_rate_error == pytest.approx(0.3)
    assert [(c.type, round(c.confidence, 6)) for c in d.classification] == [("drone", 0.93)]


def test_status_alert_and_task_ack_decode(official: Any) -> None:
    status = m.status_report(
        "node",
        T,
        report_id="r1",
        location=(47.4, 19.2, 120.0),
        pointing=m.RangeBearing(45.0, 5.0, 190.0),
        field_of_view_deg=(70.4, 77.2),
        active_task="task-1",
    )
    s = _decode(official, status).status_report
    assert (s.system, s.info, s.mode, s.active_task_id) == (1, 1, "default", "task-1")
    cone = s.field_of_view.range_bearing
    assert (cone.azimuth, cone.horizontal_extent) == (45.0, pytest.approx(70.4))
    alert = m.alert(
        "node",
        T,
        alert_id="a1",
        active=True,
        critical=True,
        description="drone track 3 inside zone 'depot'",
        location=(47.4, 19.2, 130.0),
        object_id="o3",
    )
    a = _decode(official, alert).alert
    assert (a.alert_type, a.status, a.priority) == (3, 1, 3)  # CRITICAL, ACTIVE, HIGH
    assert a.associated_detection[0].object_id == "o3"
    clear = _decode(
        official,
        m.alert(
            "node",
            T,
            alert_id="a2",
            active=False,
            critical=False,
            description="clear",
            location=(47.4, 19.2, 130.0),
            object_id=None,
        ),
    ).alert
    assert (clear.alert_type, clear.status) == (2, 5)  # WARNING, CLEAR
    ack = _decode(official, m.task_ack("node", T, "t1", False, ["no turret"])).task_ack
    assert (ack.task_id, ack.task_status, list(ack.reason)) == ("t1", 2, ["no turret"])


def _task(control: int = task_pb2.Task.CONTROL_START) -> task_pb2.Task:
    return task_pb2.Task(task_id="T1", control=control)


def test_look_at_tasks_are_read_or_refused_with_the_reason() -> None:
    task = _task()
    where = task.command.look_at.location_list
    for lat, lon in ((47.40, 19.20), (47.42, 19.24)):
        where.locations.add(
            x=lon, y=lat, coordinate_system=location_pb2.LOCATION_COORDINATE_SYSTEM_LAT_LNG_DEG_M
        )
    got = m.look_at(task)
    assert isinstance(got, m.LookAt)
    assert got.point == m.LookAtPoint(pytest.approx(47.41), pytest.approx(19.22), None)
    cone = _task()
    rb = cone.command.look_at.range_bearing
    rb.azimuth, rb.range = 250.0, 80.0
    rb.coordinate_system = range_bearing_pb2.RANGE_BEARING_COORDINATE_SYSTEM_DEGREES_M
    rb.datum = range_bearing_pb2.RANGE_BEARING_DATUM_TRUE
    assert m.look_at(cone) == m.LookAt("T1", bearing=m.RangeBearing(250.0, 0.0, 80.0))
    assert m.look_at(_task(task_pb2.Task.CONTROL_STOP)) == m.LookAt("T1", stop=True)
    assert "no command" in str(m.look_at(_task()))
    mode = _task()
    mode.command.mode_change = "night"
    assert "mode_change is not done" in str(m.look_at(mode))
    radians = _task()
    radians.command.look_at.location_list.locations.add(x=0.3, y=0.8, coordinate_system=2)
    assert "degrees only" in str(m.look_at(radians))
    empty = _task()
    empty.command.look_at.location_list.SetInParent()
    assert "empty" in str(m.look_at(empty))


def test_ulids_carry_their_time_and_come_from_the_generator() -> None:
    from ulid import ULID

    a = m.new_ulid(np.random.default_rng(3), T)
    assert a == m.new_ulid(np.random.default_rng(3), T)  # seeded
    assert a != m.new_ulid(np.random.default_rng(4), T)
    assert len(a) == 26
    assert ULID.from_str(a).milliseconds == int(T * 1000)


def test_the_committed_modules_are_what_protoc_makes_of_the_protos(tmp_path: Path) -> None:
    """tools/sapient_protoc.py, run afresh, writes exactly the committed modules."""
    done = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "sapient_protoc.py"), "--out", str(tmp_path)],
        capture_output=True,
        text=True,
        check=False,
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
