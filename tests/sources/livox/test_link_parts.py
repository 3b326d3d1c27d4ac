"""The parts a Livox link is made of, on their own: the keep-alive's clock, the bounded
packet queue between the reader thread and the consumer, and the ACK hand-over between
the control thread and a caller; against known answers, with every wait bounded."""

from __future__ import annotations

import threading
import time

import pytest

from dronetrack.errors import DeviceError
from dronetrack.sources.livox.keepalive import KeepAlive
from dronetrack.sources.queues import AckBox, PacketQueue


def test_keep_alive_is_due_every_period_and_counts_the_unanswered() -> None:
    beat = KeepAlive(1.0, 3.0)  # the SDK 1 heartbeat
    beat.answered(0.0)  # connected
    assert beat.due(0.0)
    beat.was_sent(0.0, ok=True)
    assert (beat.sent, beat.missed, beat.pending) == (1, 0, True)
    assert not beat.due(0.99)
    assert beat.due(1.0)
    beat.was_sent(1.0, ok=True)  # the first still unanswered: missed
    assert (beat.sent, beat.missed) == (2, 1)
    beat.answered(1.2)
    beat.was_sent(2.0, ok=False)  # a failed send is not counted as sent, nor missed
    assert (beat.sent, beat.missed, beat.pending) == (2, 1, False)
    assert not beat.due(2.5)
    assert beat.due(3.0)
    # dead once more than 3 s passed since the last answer (1.2 s)
    assert not beat.expired(4.0)
    assert beat.expired(4.25)


def test_the_packet_queue_keeps_the_newest_and_counts_the_dropped() -> None:
    queue = PacketQueue(3)
    for k in range(5):
        queue.put(bytes([k]))
    assert (queue.received, queue.dropped) == (5, 2)
    assert queue.last_arrival > 0
    assert queue.take(0.0, lambda: None) == [b"\x02", b"\x03", b"\x04"]
    assert queue.empty()


@pytest.mark.slow
def test_an_empty_queue_waits_checking_and_wakes_on_a_packet() -> None:
    queue = PacketQueue(10)
    checks: list[float] = []
    start = time.monotonic()
    assert queue.take(0.12, lambda: checks.append(time.monotonic())) == []
    assert 0.12 <= time.monotonic() - start < 1.0
    assert len(checks) >= 3  # at least every 50 ms
    timer = threading.Timer(0.05, queue.put, [b"x"])
    timer.start()
    start = time.monotonic()
    assert queue.take(2.0, lambda: None) == [b"x"]
    assert time.monotonic() - start < 1.0
    timer.join()

    def stalled() -> None:
        raise DeviceError("no point packet")

    with pytest.raises(DeviceError, match="no point packet"):
        queue.take(1.0, stalled)


@pytest.mark.slow
def test_acks_go_to_their_caller_once_and_the_unclaimed_are_bounded() -> None:
    box = AckBox(keep=2)
    box.put(7, b"seven")
    assert box.wait(7, time.monotonic()) == b"seven"
    assert box.wait(7, time.monotonic()) is None  # taken once
    for seq in (1, 2, 3):
        box.put(seq, bytes([seq]))
    assert box.wait(1, time.monotonic()) is None  # the oldest let go
    assert box.wait(3, time.monotonic()) == b"\x03"
    timer = threading.Timer(0.05, box.put, [9, b"late"])
    timer.start()
    assert box.wait(9, time.monotonic() + 2.0) == b"late"
    timer.join()
    start = time.monotonic()
    assert box.wait(10, start + 0.1) is None
    assert 0.1 <= time.monotonic() - start < 1.0
