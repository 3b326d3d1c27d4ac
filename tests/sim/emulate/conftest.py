"""Fixtures of the emulated devices' tests."""

from __future__ import annotations

import socket
from collections.abc import Iterator

import pytest

from livox_helpers import loopback_udp


@pytest.fixture
def host() -> Iterator[tuple[socket.socket, socket.socket]]:
    """The test's command and data sockets on loopback."""
    cmd, data = loopback_udp(), loopback_udp()
    yield cmd, data
    cmd.close()
    data.close()
