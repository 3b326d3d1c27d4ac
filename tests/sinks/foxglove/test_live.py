"""``sinks.foxglove.live``: the server's address, and foxglove-sdk's own log records
handed on to our logger rather than printed bare (loopback only, bounded waits)."""

from __future__ import annotations

import contextlib
import logging
import socket
import time

import pytest

pytest.importorskip("foxglove")

from dronetrack.sinks.foxglove.live import FoxgloveServer


def _refused_handshake(port: int) -> None:
    """A client that speaks plain HTTP, not WebSocket: the server drops it."""
    with socket.create_connection(("127.0.0.1", port), timeout=2.0) as conn:
        conn.sendall(b"GET / HTTP/1.1\r\nHost: localhost\r\n\r\n")
        conn.settimeout(2.0)
        with contextlib.suppress(TimeoutError):
            conn.recv(1024)


def test_the_server_says_where_to_connect() -> None:
    server = FoxgloveServer(0)
    try:
        assert server.url == f"ws://127.0.0.1:{server.port}"
        with socket.create_connection(("127.0.0.1", server.port), timeout=2.0):
            pass  # it listens there
    finally:
        server.close()


class _Records(logging.Handler):
    """Keeps every record it is handed."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def test_the_sdks_log_goes_through_our_logger(capsys: pytest.CaptureFixture[str]) -> None:
    # A handler of our own on the root logger sees what propagates there: the relayed
    # record from our logger, never the SDK's own.  (pytest's caplog also hooks
    # loggers that do not propagate, the SDK's among them, so it cannot tell.)
    root = logging.getLogger()
    seen = _Records()
    root.addHandler(seen)
    server = FoxgloveServer(0)
    try:
        _refused_handshake(server.port)
        deadline = time.monotonic() + 5.0
        while (
            not any("Dropping client" in r.getMessage() for r in seen.records)
            and time.monotonic() < deadline
        ):
            time.sleep(0.02)
    finally:
        server.close()
        root.removeHandler(seen)
    ours = [r for r in seen.records if "Dropping client" in r.getMessage()]
    assert ours
    assert all(r.name == "dronetrack.sinks.foxglove.mcap_file" for r in ours)
    assert ours[0].getMessage().startswith("Foxglove SDK: Dropping client 127.0.0.1:")
    assert "Dropping client" not in capsys.readouterr().err
