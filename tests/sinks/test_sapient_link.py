"""The SAPIENT link and node against the minimal fusion node, on loopback: registration,
reports in order, a fusion node killed and restarted, one that is not there, one that
sends garbage, a look-at task's round trip, and the edge node's reports checked
against pymap3d.  Every wait is bounded."""

from __future__ import annotations

import json
import math
import socket
import struct
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import pymap3d
import pytest

pytest.importorskip("google.protobuf")

from dronetrack.errors import ConfigError
from dronetrack.formats.sapient import messages as m
from dronetrack.formats.sapient.framing import FrameDecoder, encode_frame
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)
from dronetrack.geometry.geodesy import SiteFrame
from dronetrack.geometry.transforms import make_pose
from dronetrack.sinks.sapient.link import SapientLink, parse_endpoint
from dronetrack.sinks.sapient.listen import FusionNode
from dronetrack.sinks.sapient.node import SapientNode, aer_sigma
from dronetrack.types import TRACK_CLASSES, Frame, Sample, StepResult, Tracks
from dronetrack.zones import AlertEvent
from sapient_helpers import NODE, node_registration

SITE = SiteFrame(51.5, -0.12, 30.0, heading_deg=120.0, base=(0.0, 0.0, 1.0))
FUSION = "5c3d2e1f-0a9b-4c8d-9e7f-6a5b4c3d2e1f"


def _wait(condition: Callable[[], bool], timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return condition()


@contextmanager
def fusion(
    port: int = 0, icd_clean: bool = True, **kw: Any
) -> Iterator[tuple[FusionNode, list[str]]]:
    """The minimal fusion node serving in a thread; its lines in the list.  It holds
    what it receives to the ICD's rules, and if ``icd_clean``, the test to none broken."""
    lines: list[str] = []
    kw.setdefault("check_rules", True)
    node = FusionNode(port, say=lines.append, rng=np.random.default_rng(1), **kw)
    stop = threading.Event()
    thread = threading.Thread(target=node.serve, args=(stop.is_set, 0.02), daemon=True)
    thread.start()
    try:
        yield node, lines
    finally:
        stop.set()
        thread.join(5.0)
        node.close()
    if icd_clean:
        assert not [line for line in lines if "breaks the ICD" in line]


@contextmanager
def link_to(port: int, **kw: Any) -> Iterator[tuple[SapientLink, list[str]]]:
    said: list[str] = []
    link = SapientLink("127.0.0.1", port, node_registration, say=said.append, **kw)
    try:
        yield link, said
    finally:
        link.close()


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_endpoints_are_host_and_port() -> None:
    assert parse_endpoint("127.0.0.1:5020") == ("127.0.0.1", 5020)
    assert parse_endpoint("[::1]:5020") == ("::1", 5020)
    for bad in ("127.0.0.1", "host:", ":5020", "host:port", "host:70000"):
        with pytest.raises(ConfigError, match="give the fusion node as HOST:PORT"):
            parse_endpoint(bad)


def _task_id(seed: int) -> str:
    """A ULID known by ``seed``; lines show its last 6 characters."""
    return m.new_ulid(np.random.default_rng(seed), 1_800_000_000.0)


def _ack(seed: int) -> Any:
    """A TaskAck that keeps the ICD's rules, of the task ``_task_id(seed)``."""
    return m.task_ack(NODE, time.time(), _task_id(seed), True)


def test_registration_then_reports_in_order() -> None:
    with fusion() as (node, lines), link_to(node.port) as (link, said):
        assert _wait(lambda: link.stats.registered, 5.0), said
        for k in range(50):
            assert link.send(_ack(k))
        assert _wait(lambda: node.received == 51, 5.0)
    acks = [line.split("task ")[1].split()[0] for line in lines if "task_ack" in line]
    assert acks == [_task_id(k)[-6:] for k in range(50)]
    assert "registration: test (BSI Flex 335 v2.0)" in lines[1]
    assert (link.stats.sent, link.stats.dropped, link.stats.reconnects) == (50, 0, 0)
    assert any("registered with the fusion node" in s for s in said)


def test_a_restarted_fusion_node_is_rejoined_within_5_s_and_the_gap_counted() -> None:
    """The link's back-off doubles from 0.25 s and is capped at 2 s, so once the fusion
    node is back the link tries again within 2 s and registers a few milliseconds
    later on loopback; 5 s leaves room for a loaded machine."""
    port = _free_port()
    with link_to(port) as (link, said):
        with fusion(port) as (node, _):
            assert _wait(lambda: link.stats.registered, 5.0), said
            link.send(_ack(1000))
            assert _wait(lambda: node.received == 2, 5.0)
        # the fusion node is gone: what is sent meanwhile is dropped and counted
        assert _wait(lambda: not link.stats.registered, 5.0)
        dropped = link.stats.dropped
        for _ in range(20):
            assert not link.send(_ack(1001))
        assert link.stats.dropped == dropped + 20
        time.sleep(0.5)  # down half a second, the link retrying
        with fusion(port) as (node, lines):
            start = time.monotonic()
            assert _wait(lambda: link.stats.registered, 5.0), said
            rejoined = time.monotonic() - start
            assert link.send(_ack(1002))
            assert _wait(lambda: node.received == 2, 5.0)
    assert rejoined < 5.0
    assert any(_task_id(1002)[-6:] in line for line in lines)  # after, not the gap's
    assert (link.stats.connects, link.stats.reconnects) == (2, 1)
    assert any("link to" in s and "lost" in s for s in said)


def test_send_never_blocks_and_counts_what_it_could_not_send() -> None:
    message = _ack(0)
    with link_to(_free_port()) as (link, said):  # nobody listens there
        start = time.perf_counter()
        sent = [link.send(message) for _ in range(10_000)]
        elapsed = time.perf_counter() - start
        assert not any(sent)
        assert link.stats.dropped == 10_000
        # generous: 10 000 sends that only encode and count take well under a second
        assert elapsed < 5.0
        assert _wait(lambda: link.stats.connects == 0 and bool(said), 3.0)
        time.sleep(0.6)  # a few more attempts (0.25 s, then 0.5 s apart)
    # an outage is said once, however many times the link retries
    assert len([s for s in said if "cannot reach" in s]) == 1
    assert not link._thread.is_alive()  # close ended the thread


def test_a_fusion_node_that_comes_late_is_joined() -> None:
    port = _free_port()
    with link_to(port) as (link, said):
        assert _wait(lambda: any("cannot reach" in s for s in said), 3.0)
        with fusion(port):
            assert _wait(lambda: link.stats.registered, 5.0), said


@contextmanager
def fake_fusion() -> Iterator[socket.socket]:
    """A listening socket for a fusion node the test plays by hand."""
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(5.0)
    with server:
        yield server


def _registered(server: socket.socket, link: SapientLink) -> socket.socket:
    """Accept the link, read its Registration and accept it."""
    conn, _ = server.accept()
    conn.settimeout(5.0)
    decoder: FrameDecoder = FrameDecoder()
    got: list[Any] = []
    for _ in range(100):
        got += decoder.feed(conn.recv(65536))
        if got:
            break
    assert got[0].WhichOneof("content") == "registration"
    conn.sendall(encode_frame(m.registration_ack(FUSION, time.time(), True)))
    assert _wait(lambda: link.stats.registered, 5.0)
    return conn


@pytest.mark.parametrize(
    ("payload", "expected"),
    [
        (struct.pack("<I", 5) + b"\xff" * 5, "is no SapientMessage"),
        (struct.pack("<I", 10_000_000), "over the limit"),
        (struct.pack("<I", 100) + b"\x2a", "closed 5 bytes into a frame"),
    ],
)
def test_a_fusion_node_that_sends_garbage_is_left_and_joined_again(
    payload: bytes, expected: str
) -> None:
    """A fake fusion node: it acknowledges the registration, then sends ``payload`` and
    closes; the link says what was wrong in one line and connects again."""
    with fake_fusion() as server, link_to(server.getsockname()[1]) as (link, said):
        for _ in range(2):
            with _registered(server, link) as conn:
                conn.sendall(payload)
            assert _wait(lambda: not link.stats.registered, 5.0)
        assert link.stats.connects >= 2
        assert link.stats.bad_frames == 2
    lost = [s for s in said if "lost" in s]
    assert len(lost) == 2
    assert all(expected in s and "\n" not in s for s in lost)
    assert expected in link.stats.last_error


def test_a_refused_registration_is_said_once_and_tried_again() -> None:
    with fake_fusion() as server, link_to(server.getsockname()[1]) as (link, said):
        for _ in range(3):
            conn, _ = server.accept()
            with conn:
                conn.settimeout(5.0)
                conn.sendall(encode_frame(m.registration_ack(FUSION, time.time(), False, "full")))
                for _ in range(100):  # the Registration, then the link's end: it left
                    if not conn.recv(65536):
                        break
        assert not link.stats.registered
        assert link.stats.connects >= 3
        assert link.stats.last_error == "registration refused: full"
    assert len([s for s in said if "refused us: full" in s]) == 1


def test_the_fusion_nodes_errors_are_said_once_and_its_tasks_kept() -> None:
    error = SapientMessage(node_id=FUSION)
    error.error.packet = b"\x00"
    error.error.error_message.append("Invalid ULID: t1")
    task = m.look_at_task(FUSION, NODE, time.time(), _task_id(7), point=(51.5, -0.12, None))
    with fake_fusion() as server, link_to(server.getsockname()[1]) as (link, said):
        conn = _registered(server, link)
        with conn:
            conn.sendall(encode_frame(error) * 2 + encode_frame(task))
            assert _wait(lambda: link.stats.errors == 2 and bool(link._inbox), 5.0)
            [got] = link.tasks()
            assert got.task_id == _task_id(7)
            assert link.tasks() == []
    assert len([s for s in said if "reports an error: Invalid ULID: t1" in s]) == 1


def test_the_fusion_node_flags_what_breaks_the_icd(tmp_path: Any) -> None:
    out = (tmp_path / "c2.jsonl").open("w")
    with fusion(out=out, icd_clean=False) as (node, lines), link_to(node.port) as (link, _):
        assert _wait(lambda: link.stats.registered, 5.0)
        for _ in range(3):
            link.send(m.task_ack("node-1", time.time(), "t1", True))
        assert _wait(lambda: node.received == 4, 5.0)
    out.close()
    flagged = [line for line in lines if "breaks the ICD" in line]
    assert len(flagged) == 2  # each field once: node_id and task_id
    assert "node_id: 'node-1' is no lower-case version-4 UUID" in flagged[0]
    records = [json.loads(line) for line in (tmp_path / "c2.jsonl").read_text().splitlines()]
    assert "icd_problems" not in records[0]  # the registration keeps the rules
    assert len(records[1]["icd_problems"]) == 2


def test_the_fusion_node_drops_a_peer_that_sends_garbage_and_serves_the_others() -> None:
    with fusion(max_frame_bytes=1000) as (node, lines), link_to(node.port) as (link, _):
        assert _wait(lambda: link.stats.registered, 5.0)
        with socket.create_connection(("127.0.0.1", node.port), 5.0) as bad:
            bad.sendall(struct.pack("<I", 5000))
            assert _wait(lambda: any("over the limit of 1000" in s for s in lines), 5.0)
        with socket.create_connection(("127.0.0.1", node.port), 5.0) as half:
            half.sendall(encode_frame(_ack(1))[:7])
        assert _wait(lambda: any("closed 7 bytes into a frame" in s for s in lines), 5.0)
        link.send(_ack(2000))
        assert _wait(lambda: any(f"task {_task_id(2000)[-6:]}" in s for s in lines), 5.0)


def test_sapient_listen_tasks_a_node_and_prints_its_ack(
    tmp_path: Any, capsys: pytest.CaptureFixture[str]
) -> None:
    """``dronetrack sapient-listen --look-at``, for 1 s: a link registers, gets the
    look-at task, answers it; the command prints the TaskAck and writes JSON lines."""
    from dronetrack.cli.main import run

    port, out = _free_port(), tmp_path / "c2.jsonl"
    answered: list[str] = []

    def edge_node() -> None:
        link = SapientLink("127.0.0.1", port, node_registration, backoff_s=(0.05, 0.2))
        deadline = time.monotonic() + 5.0
        while not answered and time.monotonic() < deadline:
            for task in link.tasks():
                wanted = m.look_at(task)
                assert isinstance(wanted, m.LookAt)
                assert wanted.point is not None
                link.send(m.task_ack(NODE, time.time(), task.task_id, True))
                answered.append(task.task_id)
            time.sleep(0.02)
        time.sleep(0.2)
        link.close()

    thread = threading.Thread(target=edge_node, daemon=True)
    thread.start()
    argv = ["sapient-listen", "--port", str(port), "--out", str(out)]
    argv += ["--look-at", "51.5005,-0.1195,60", "--task-after", "0", "--duration", "1.0"]
    assert run(argv) == 0
    thread.join(5.0)
    err = capsys.readouterr().err
    [task_id] = answered
    assert f"task_ack: task {task_id[-6:]} accepted" in err
    assert "breaks the ICD" not in err
    records = [json.loads(line) for line in out.read_text().splitlines()]
    kinds = [next(k for k in r if k in ("registration", "task_ack")) for r in records]
    assert kinds == ["registration", "task_ack"]
    assert records[1]["task_ack"]["task_id"] == task_id


# ------------------------------------------------------------------ the edge node


class _Pipeline:
    """What a look-at task reaches: records the points, can say no."""

    def __init__(self, can: bool = True) -> None:
        self.can = can
        self.points: list[np.ndarray] = []

    def look_at(self, t: float, point: np.ndarray) -> bool:
        self.points.append(np.asarray(point))
        return self.can


def _position(track_id: int) -> list[float]:
    """Each track's world position [m], by its ID."""
    return [60.0 + 10 * track_id, -20.0 + 5 * track_id, 15.0 + track_id]


def _tracks(ids: list[int], classes: list[str], updated: list[bool]) -> Tracks:
    k = len(ids)
    positions = np.array([_position(i) for i in ids])
    cov = np.tile(np.diag([4.0, 1.0, 0.25, 1.0, 1.0, 1.0]), (k, 1, 1))
    return Tracks(
        ids=np.array(ids),
        positions=positions.reshape(k, 3),
        velocities=np.tile([5.0, -2.0, 0.5], (k, 1)),
        covariances=cov,
        born=np.zeros(k),
        updated=np.array(updated, dtype=bool),
        hovered=np.zeros(k, dtype=bool),
        locked=np.zeros(k, dtype=bool),
        classes=np.array([TRACK_CLASSES.index(c) for c in classes]),
        p_drone=np.array([0.9 if c == "drone" else 0.2 for c in classes]),
    )


def _sample() -> Sample:
    pose = make_pose(np.eye(3), [0.0, 0.0, 1.1])
    empty = np.zeros((0, 3))
    frame = Frame(
        0.0,
        0.1,
        empty,
        np.zeros(0),
        np.zeros(0, np.uint8),
        np.zeros(0, np.float32),
        np.array([0.0, 0.1]),
        np.stack([pose, pose]),
    )
    return Sample(frame)


def _result(t: float, tracks: Tracks) -> StepResult:
    return StepResult(
        t=t,
        phase="track",
        estimate=None,
        n_points=0,
        n_returns=0,
        command=None,
        step_ms=0.0,
        tracks=tracks,
    )


def _node(link: SapientLink, steerable: bool = True) -> SapientNode:
    return SapientNode(
        link,
        SITE,
        node_id=NODE,
        rng=np.random.default_rng(0),
        steerable=steerable,
    )


def test_the_edge_node_reports_each_updated_track_where_pymap3d_puts_it(
    tmp_path: Any,
) -> None:
    out = (tmp_path / "c2.jsonl").open("w")
    with fusion(out=out) as (fusion_node, lines), link_to(fusion_node.port) as (link, _):
        node = _node(link)
        assert _wait(lambda: link.stats.registered, 5.0)
        tracks = _tracks([3, 7, 9], ["drone", "bird", "static"], [True, True, True])
        node.frame(_sample(), _result(1.0, tracks), [])
        coasting = _tracks([3, 7], ["drone", "bird"], [True, False])
        node.frame(_sample(), _result(1.1, coasting), [])
        node.frame(_sample(), _result(1.2, _tracks([7], ["bird"], [True])), [])
        # status + 2 (the static track is not reported) + 1 (track 7 coasts) + 1 + lost
        assert _wait(lambda: fusion_node.received == 7, 5.0), lines
    out.close()
    records = [json.loads(line) for line in (tmp_path / "c2.jsonl").read_text().splitlines()]
    reports = [r["detection_report"] for r in records if "detection_report" in r]
    assert len(reports) == 5
    ids = {}
    for report in reports:
        info = {i["type"]: i for i in report["track_info"]}
        track = int(info["track_id"]["value"])
        ids.setdefault(track, set()).add(report["object_id"])
        if report.get("state") == "lost":
            assert track == 3  # it ended after the second frame
            continue
        x, y, z = _position(track)
        # the world frame: x at 120° from north, base 1 m up; ENU = Rz(90° − 120°) p
        th = math.radians(-30.0)
        e, n = math.cos(th) * x - math.sin(th) * y, math.sin(th) * x + math.cos(th) * y
        lat, lon, alt = pymap3d.enu2geodetic(e, n, z - 1.0, 51.5, -0.12, 30.0)
        loc = report["location"]
        assert loc["y"] == pytest.approx(lat, abs=1e-9)
        assert loc["x"] == pytest.approx(lon, abs=1e-9)
        assert loc["z"] == pytest.approx(alt, abs=1e-6)
        az, _el, rng = pymap3d.enu2aer(e, n, z - 1.0)
        assert float(info["range_m"]["value"]) == pytest.approx(rng, abs=1e-3)
        assert float(info["azimuth_deg"]["value"]) == pytest.approx(az, abs=1e-3)
        cls = report["classification"][0]
        assert cls["type"] == ("drone" if track == 3 else "bird")
        assert cls["confidence"] == pytest.approx(0.9 if track == 3 else 0.8)
    assert all(len(v) == 1 for v in ids.values())  # one object ID for a track's life
    assert len({next(iter(v)) for v in ids.values()}) == 2


def test_aer_sigma_is_the_covariance_through_the_jacobian() -> None:
    # Straight north at 100 m: east error is azimuth error, up is elevation, north range
    s_az, s_el, s_r = aer_sigma(np.array([0.0, 100.0, 0.0]), np.diag([4.0, 9.0, 1.0]))
    assert s_az == pytest.approx(math.degrees(2.0 / 100.0))
    assert s_el == pytest.approx(math.degrees(1.0 / 100.0))
    assert s_r == pytest.approx(3.0)


def test_a_look_at_task_turns_the_search_or_is_refused_with_the_reason() -> None:
    point = (51.5005, -0.1195, 60.0)
    with fusion(look_at=point, task_after_s=0.0) as (fusion_node, lines):
        with link_to(fusion_node.port) as (link, _):
            node, pipeline = _node(link), _Pipeline()
            node.attach(pipeline)
            assert _wait(lambda: link.stats.registered, 5.0)
            assert _wait(lambda: bool(link._inbox), 5.0)
            node.frame(_sample(), _result(1.0, _tracks([], [], [])), [])
            assert _wait(lambda: any("task_ack" in s for s in lines), 5.0), lines
        [target] = pipeline.points
        np.testing.assert_allclose(target, SITE.from_geodetic(*point), atol=1e-6)
        assert any("accepted" in s for s in lines if "task_ack" in s)
        # a replay: no turret to point
        with link_to(fusion_node.port) as (link, _):
            node = _node(link, steerable=False)
            assert _wait(lambda: bool(link._inbox), 5.0)
            node.frame(_sample(), _result(1.0, _tracks([], [], [])), [])
            assert _wait(lambda: any("rejected: this run has no turret" in s for s in lines), 5.0)


def test_alerts_go_out_with_their_track(tmp_path: Any) -> None:
    out = (tmp_path / "c2.jsonl").open("w")
    with fusion(out=out) as (fusion_node, lines), link_to(fusion_node.port) as (link, _):
        node = _node(link)
        assert _wait(lambda: link.stats.registered, 5.0)
        tracks = _tracks([3], ["drone"], [True])
        inside = AlertEvent(
            1.0, 3, "depot", "inside", tracks.positions[0], tracks.velocities[0], 0.0, 0.0
        )
        node.frame(_sample(), _result(1.0, tracks), [inside])
        clear = AlertEvent(
            2.0,
            3,
            "depot",
            "clear",
            tracks.positions[0],
            tracks.velocities[0],
            math.inf,
            30.0,
            "left",
        )
        node.frame(_sample(), _result(2.0, tracks), [clear])
        assert _wait(lambda: sum("alert:" in s for s in lines) == 2, 5.0), lines
        node.close()  # a GOODBYE, sent before the link closes
        assert _wait(lambda: any("closed the connection" in s for s in lines), 5.0), lines
    out.close()
    records = [json.loads(line) for line in (tmp_path / "c2.jsonl").read_text().splitlines()]
    alerts = [r["alert"] for r in records if "alert" in r]
    reports = [r["detection_report"] for r in records if "detection_report" in r]
    assert [(a["alert_type"], a["status"]) for a in alerts] == [
        ("ALERT_TYPE_CRITICAL", "ALERT_STATUS_ACTIVE"),
        ("ALERT_TYPE_WARNING", "ALERT_STATUS_CLEAR"),
    ]
    assert alerts[0]["associated_detection"][0]["object_id"] == reports[0]["object_id"]
    assert records[-1]["status_report"]["system"] == "SYSTEM_GOODBYE"
    assert link.stats.sent == len(records) - 1  # all but the registration
