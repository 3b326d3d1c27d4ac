"""A short sample of an open live point stream, as ``dronetrack info`` reports it."""

from __future__ import annotations

import time
from collections.abc import Sized
from typing import Protocol

__all__ = ["CountedStream", "sample_stream"]


class CountedStream(Protocol):
    """An open point stream with its packet counters (the Livox and VLP-16 clients)."""

    @property
    def packets_received(self) -> int: ...

    @property
    def packets_lost(self) -> int: ...

    @property
    def packets_malformed(self) -> int: ...

    def read(self, timeout_s: float = 0.1) -> Sized: ...


def sample_stream(client: CountedStream, sample_s: float) -> tuple[str, str]:
    """Read ``client`` for ``sample_s`` seconds; the ``info`` line of what came: packets
    and points, and the lost and malformed packets."""
    points = 0
    until = time.monotonic() + sample_s
    while time.monotonic() < until:
        points += len(client.read(0.05))
    return (
        f"sampling {sample_s:g} s",
        f"{client.packets_received} packets, {points} points, "
        f"{client.packets_lost} lost, {client.packets_malformed} malformed",
    )
