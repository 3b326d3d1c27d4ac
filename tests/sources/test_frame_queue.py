"""The bounded frame queue between a live source's reader and the run."""

from __future__ import annotations

import threading
import time

import pytest

from dronetrack.errors import DeviceError
from dronetrack.sources.frame_queue import FrameQueue


def test_the_oldest_frames_go_when_the_run_falls_behind() -> None:
    q: FrameQueue[int] = FrameQueue(2, threading.Event())
    for k in range(5):
        q.put(k)
    assert q.dropped == 3
    q.end()
    assert [q.get(), q.get(), q.get()] == [3, 4, None]


def test_a_failed_stream_raises_once_its_frames_are_taken() -> None:
    q: FrameQueue[int] = FrameQueue(3, threading.Event())
    q.put(1)
    q.fail(DeviceError("lidar: silent for 1 s"))
    assert q.get() == 1
    with pytest.raises(DeviceError, match="silent"):
        q.get()


@pytest.mark.slow
def test_a_waiting_get_wakes_for_a_frame_and_for_a_stop() -> None:
    stop = threading.Event()
    q: FrameQueue[str] = FrameQueue(2, stop)
    threading.Timer(0.05, q.put, args=("frame",)).start()
    t0 = time.monotonic()
    assert q.get() == "frame"
    threading.Timer(0.05, stop.set).start()
    assert q.get() is None
    assert time.monotonic() - t0 < 1.0
