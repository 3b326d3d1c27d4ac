"""The bounded queue of whole frames between a live source's reader thread and the run.

The reader puts frames in; the run takes them out, oldest first.  The queue never
grows past ``max_frames``: when the run falls behind, the oldest whole frame is
dropped and counted (``dropped``), so the pipeline always works on recent data.  The
reader ends the stream (``end``) or fails it (``fail``: the run raises its error when
the queue runs dry); a stop request (the source's ``stop`` event, or Ctrl-C) ends the
wait at once.  ``cond`` is the queue's lock, which a source may share for state of
its own that the reader hands over.
"""

from __future__ import annotations

import threading
from collections import deque
from typing import Generic, TypeVar

from dronetrack.errors import DronetrackError
from dronetrack.interrupt import stop_requested

__all__ = ["POLL_S", "FrameQueue"]

POLL_S = 0.05  # longest a wait blocks before it looks at the stop request [s]
T = TypeVar("T")


class FrameQueue(Generic[T]):
    """At most ``max_frames`` frames, the oldest dropped first (see the module)."""

    def __init__(self, max_frames: int, stop: threading.Event) -> None:
        self.max_frames = max_frames
        self.dropped = 0
        self.cond = threading.Condition()
        self._items: deque[T] = deque()
        self._stop = stop
        self._error: DronetrackError | None = None
        self._ended = False

    def put(self, item: T) -> None:
        """Queue ``item``, dropping the oldest frame if the queue is full."""
        with self.cond:
            if len(self._items) >= self.max_frames:
                self._items.popleft()
                self.dropped += 1
            self._items.append(item)
            self.cond.notify_all()

    def fail(self, exc: DronetrackError) -> None:
        """The stream failed: ``get`` raises ``exc`` once the queue is empty."""
        with self.cond:
            self._error = exc
            self.cond.notify_all()

    def end(self) -> None:
        """The stream ended: ``get`` returns None once the queue is empty."""
        with self.cond:
            self._ended = True
            self.cond.notify_all()

    def get(self) -> T | None:
        """The oldest queued frame, waiting for one; None once the stream has ended or a
        stop was asked for; the reader's error if it failed."""
        with self.cond:
            while not self._items:
                if self._error is not None:
                    raise self._error
                if self._ended or self._stop.is_set() or stop_requested():
                    return None
                self.cond.wait(POLL_S)
            return self._items.popleft()
