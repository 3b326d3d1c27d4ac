"""A Foxglove WebSocket client for the live-server tests (loopback only, bounded)."""

from __future__ import annotations

import base64
import json
import os
import socket
import time
from collections.abc import Iterator


def ws_messages(port: int, until_s: float) -> Iterator[dict[str, object]]:
    """The JSON messages a Foxglove WebSocket server sends a new client (a WebSocket
    handshake by hand, RFC 6455: unmasked server frames; binary frames skipped)."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(
        (
            "GET / HTTP/1.1\r\nHost: localhost\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
            f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
            "Sec-WebSocket-Protocol: foxglove.sdk.v1\r\n\r\n"
        ).encode()
    )
    buf = b""
    while b"\r\n\r\n" not in buf:
        buf += sock.recv(4096)
    head, buf = buf.split(b"\r\n\r\n", 1)
    assert head.startswith(b"HTTP/1.1 101"), head

    def need(n: int) -> bytes:
        nonlocal buf
        while len(buf) < n:
            buf += sock.recv(65536)
        out, buf = buf[:n], buf[n:]
        return out

    deadline = time.monotonic() + until_s
    try:
        while time.monotonic() < deadline:
            b0, b1 = need(2)
            size = b1 & 0x7F
            if size == 126:
                size = int.from_bytes(need(2), "big")
            elif size == 127:
                size = int.from_bytes(need(8), "big")
            payload = need(size)
            if b0 & 0x0F == 1:  # a text frame
                yield json.loads(payload)
    finally:
        sock.close()
