"""What the threads of a Livox host client hand each other: the point packets the
reader thread receives for the consumer (a bounded queue that drops its oldest packet
when the consumer falls behind) and the command ACKs the control thread receives for
the callers waiting on them (by sequence number)."""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

from dronetrack.sources.udp import POLL_S

__all__ = ["AckBox", "PacketQueue"]


class PacketQueue:
    """At most ``max_packets`` packets, oldest first.  Counters: ``received`` (every
    packet put), ``dropped`` (the oldest let go to make room); ``last_arrival`` is the
    monotonic time of the last packet put (0 before the first)."""

    def __init__(self, max_packets: int) -> None:
        self.max_packets = max_packets
        self.received = 0
        self.dropped = 0
        self.last_arrival = 0.0
        self._items: deque[bytes] = deque()
        self._lock = threading.Lock()
        self._arrived = threading.Condition(self._lock)

    def put(self, packet: bytes) -> None:
        """Queue ``packet`` (the reader thread), dropping the oldest when full."""
        with self._lock:
            self.received += 1
            self.last_arrival = time.monotonic()
            if len(self._items) >= self.max_packets:
                self._items.popleft()
                self.dropped += 1
            self._items.append(packet)
            self._arrived.notify()

    def empty(self) -> bool:
        return not self._items

    def take(self, timeout_s: float, check: Callable[[], None]) -> list[bytes]:
        """Every packet queued, waiting up to ``timeout_s`` for the first ([] if none
        came).  While the queue is empty, ``check`` runs (under the queue's lock) at
        least every ``POLL_S``; what it raises ends the wait."""
        until = time.monotonic() + timeout_s
        with self._lock:
            while not self._items:
                check()
                left = until - time.monotonic()
                if left <= 0:
                    return []
                self._arrived.wait(min(left, POLL_S))
            out = list(self._items)
            self._items.clear()
        return out


class AckBox:
    """ACK payloads by the sequence number of their command, from the thread that
    receives them to the caller that waits; of more than ``keep`` that nobody took, the
    oldest are let go (the keep-alive's, or a late answer to a command given up)."""

    def __init__(self, keep: int = 64) -> None:
        self.keep = keep
        self._acks: dict[int, bytes] = {}
        self._acked = threading.Condition(threading.Lock())

    def put(self, seq: int, payload: bytes) -> None:
        with self._acked:
            self._acks[seq] = payload
            while len(self._acks) > self.keep:
                self._acks.pop(next(iter(self._acks)))
            self._acked.notify_all()

    def wait(self, seq: int, until: float) -> bytes | None:
        """The ACK of ``seq``, taken out, once it comes; None if it has not come by the
        monotonic time ``until``."""
        with self._acked:
            while seq not in self._acks and time.monotonic() < until:
                self._acked.wait(max(until - time.monotonic(), 0.0))
            return self._acks.pop(seq, None)
