"""A minimal SAPIENT fusion node (``dronetrack sapient-listen``): it accepts edge nodes,
acknowledges their registrations, says one line per message, writes every message it
receives as a JSON line, and can send each registered node a look-at task.

It is a test partner and a way to see the stream without a C2 system, not a fusion
engine: it fuses nothing.  It accepts every Registration (a RegistrationAck) and every
Alert (an AlertAck).  One thread serves every connection (``selectors``); a node
that sends garbage, a frame over the limit, or closes in the middle of a frame is
said in one line and dropped, and the others go on.
"""

from __future__ import annotations

import contextlib
import json
import selectors
import socket
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import IO

import numpy as np
from google.protobuf.json_format import MessageToDict

from dronetrack.errors import SapientProtocolError
from dronetrack.formats.sapient.framing import MAX_FRAME_BYTES, FrameDecoder, encode_frame
from dronetrack.formats.sapient.messages import (
    alert_ack,
    look_at_task,
    new_ulid,
    registration_ack,
)
from dronetrack.formats.sapient.rules import broken_rules
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0 import task_ack_pb2
from dronetrack.formats.sapient.sapient_msg.bsi_flex_335_v2_0.sapient_message_pb2 import (
    SapientMessage,
)

__all__ = ["FusionNode", "describe", "look_at_task", "task_status_name"]

Say = Callable[[str], None]


def describe(message: SapientMessage) -> str:
    """One line of what ``message`` says."""
    kind = message.WhichOneof("content")
    node = message.node_id[:8]
    if kind == "registration":
        reg = message.registration
        return f"{node} registration: {reg.name or '?'} ({reg.icd_version})"
    if kind == "status_report":
        s = message.status_report
        where = s.node_location
        return (
            f"{node} status_report: {s.mode or '-'} at {where.y:.6f}, {where.x:.6f}, "
            f"{where.z:.1f} m"
        )
    if kind == "detection_report":
        d = message.detection_report
        cls = d.classification[0] if d.classification else None
        what = f"{cls.type} {cls.confidence:.2f}" if cls is not None else "unclassified"
        track = next((i.value for i in d.track_info if i.type == "track_id"), "?")
        loc = d.location
        state = f" {d.state}" if d.HasField("state") else ""
        return (
            f"{node} detection_report: track {track} ({d.object_id[-6:]}) {what} at "
            f"{loc.y:.6f}, {loc.x:.6f}, {loc.z:.1f} m{state}"
        )
    if kind == "alert":
        a = message.alert
        return f"{node} alert: {a.description}"
    if kind == "task_ack":
        ack = message.task_ack
        status = task_status_name(ack.task_status)
        why = f": {'; '.join(ack.reason)}" if ack.reason else ""
        return f"{node} task_ack: task {ack.task_id[-6:]} {status}{why}"
    if kind == "error":
        return f"{node} error: {'; '.join(message.error.error_message) or 'no description'}"
    return f"{node} {kind}"


def task_status_name(status: int) -> str:
    """A TaskAck's status in a word: ``accepted``, ``rejected``, ``completed`` ..."""
    name: str = task_ack_pb2.TaskAck.TaskStatus.Name(status)
    return name.removeprefix("TASK_STATUS_").lower()


@dataclass
class _Peer:
    sock: socket.socket
    name: str
    decoder: FrameDecoder
    node_id: str | None = None
    registered_at: float | None = None
    tasked: bool = False
    received: int = 0
    flagged: set[str] = field(default_factory=set)  # the fields whose breach was said


class FusionNode:
    """Listens on ``host:port`` (port 0: any free one, ``port`` says which).

    ``out``: the JSON lines file; ``look_at``: a (lat°, lon°, alt m or None) to task
    each registered node with, ``task_after_s`` after its registration; ``received``:
    told each message as it is read.  ``check_rules``: hold each message to the
    definitions' rules (``formats.sapient.rules``, what Apex checks), say each new
    breach of a node in one line, and list them in its JSON line (``icd_problems``).
    """

    def __init__(
        self,
        port: int,
        host: str = "127.0.0.1",
        *,
        out: IO[str] | None = None,
        say: Say | None = None,
        look_at: tuple[float, float, float | None] | None = None,
        task_after_s: float = 2.0,
        max_frame_bytes: int = MAX_FRAME_BYTES,
        rng: np.random.Generator | None = None,
        received: Callable[[SapientMessage], None] | None = None,
        check_rules: bool = False,
    ) -> None:
        self.say = say or (lambda text: None)
        self.on_message = received  # told each message as it is read
        self.check_rules = check_rules
        self.out = out
        self.look_at = look_at
        self.task_after_s = task_after_s
        self.max_frame_bytes = max_frame_bytes
        self.rng = rng if rng is not None else np.random.default_rng()
        self.node_id = str(uuid.UUID(bytes=self.rng.bytes(16), version=4))
        self.received = 0
        self._server = socket.create_server((host, port), reuse_port=False)
        self._server.setblocking(False)
        self.port = int(self._server.getsockname()[1])
        self.host = host
        self._sel = selectors.DefaultSelector()
        self._sel.register(self._server, selectors.EVENT_READ)
        self._peers: dict[socket.socket, _Peer] = {}

    def serve(self, until: Callable[[], bool], poll_s: float = 0.1) -> None:
        """Serve until ``until()`` is true (checked every ``poll_s``)."""
        while not until():
            for key, _ in self._sel.select(timeout=poll_s):
                if key.fileobj is self._server:
                    self._accept()
                else:
                    assert isinstance(key.fileobj, socket.socket)
                    self._read(self._peers[key.fileobj])
            self._task_due()

    def close(self) -> None:
        """Close every connection and stop listening."""
        for peer in list(self._peers.values()):
            self._drop(peer)
        self._sel.close()
        self._server.close()

    def _accept(self) -> None:
        try:
            sock, addr = self._server.accept()
        except BlockingIOError:
            return
        sock.setblocking(False)
        name = f"{addr[0]}:{addr[1]}"
        self._peers[sock] = _Peer(sock, name, FrameDecoder(self.max_frame_bytes))
        self._sel.register(sock, selectors.EVENT_READ)
        self.say(f"connection from {name}")

    def _read(self, peer: _Peer) -> None:
        try:
            data = peer.sock.recv(65536)
            if not data:
                peer.decoder.close()
                self.say(f"{peer.name} closed the connection")
                self._drop(peer)
                return
            messages = peer.decoder.feed(data)
        except SapientProtocolError as err:
            self.say(f"{peer.name}: {err}; dropping the connection")
            self._drop(peer)
            return
        except OSError as err:
            self.say(f"{peer.name}: {err.strerror or err}; dropping the connection")
            self._drop(peer)
            return
        for message in messages:
            self._receive(peer, message)

    def _receive(self, peer: _Peer, message: SapientMessage) -> None:
        self.received += 1
        peer.received += 1
        if self.on_message is not None:
            self.on_message(message)
        problems = broken_rules(message) if self.check_rules else []
        if self.out is not None:
            record = MessageToDict(message, preserving_proto_field_name=True)
            record = {"received": round(time.time(), 6), "peer": peer.name, **record}
            if problems:
                record["icd_problems"] = problems
            self.out.write(json.dumps(record) + "\n")
            self.out.flush()
        self.say(describe(message))
        kind = message.WhichOneof("content")
        for problem in problems:
            key = f"{kind} {problem.split(':', 1)[0]}"  # each field of each kind, once
            if key not in peer.flagged:
                peer.flagged.add(key)
                self.say(f"{peer.name}: the {kind} breaks the ICD's rules: {problem}")
        if kind == "registration":
            peer.node_id = message.node_id
            peer.registered_at = time.monotonic()
            self._send(peer, registration_ack(self.node_id, time.time(), True))
        elif kind == "alert":
            alert_id = message.alert.alert_id
            self._send(peer, alert_ack(self.node_id, time.time(), alert_id, True, [], peer.node_id))

    def _task_due(self) -> None:
        if self.look_at is None:
            return
        now = time.monotonic()
        for peer in list(self._peers.values()):
            due = peer.registered_at is not None and now - peer.registered_at >= self.task_after_s
            if due and not peer.tasked and peer.node_id is not None:
                peer.tasked = True
                task_id = new_ulid(self.rng, time.time())
                task = look_at_task(self.node_id, peer.node_id, time.time(), task_id, self.look_at)
                self._send(peer, task)
                lat, lon, _ = self.look_at
                self.say(f"task {task_id[-6:]} to {peer.node_id[:8]}: look at {lat:.6f}, {lon:.6f}")

    def _send(self, peer: _Peer, message: SapientMessage) -> None:
        try:
            peer.sock.setblocking(True)
            peer.sock.settimeout(1.0)
            peer.sock.sendall(encode_frame(message))
        except OSError as err:
            self.say(f"{peer.name}: cannot send ({err}); dropping the connection")
            self._drop(peer)
        else:
            peer.sock.setblocking(False)

    def _drop(self, peer: _Peer) -> None:
        with contextlib.suppress(KeyError, ValueError):
            self._sel.unregister(peer.sock)
        self._peers.pop(peer.sock, None)
        peer.sock.close()
