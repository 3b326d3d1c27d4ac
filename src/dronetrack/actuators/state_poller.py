"""A turret's present state, read at a fixed rate in a thread of its own.

``StatePoller`` calls ``read`` (one time-stamped measurement of both joints, e.g. a
sync read of the servos' present position) every 1/rate seconds in a daemon thread
and keeps what it reads for the consumer, who ``take``s the new readings once a
frame.  So the serial round trip is out of the frame's path: the frame only waits
when the newest reading is older than it may be.

Schedule.  Reads are due at t₀ + k/f; a read that ends after the next one was due
is followed at once by the next (no burst to catch up the ones missed).  ``hold``
keeps the poller from starting a read for a while (until ``release``, at most the
time given), so that a caller who will soon need the line (a frame between taking
its readings and sending its command) does not wait behind a read; a read already
under way finishes.

Failures.  A read that raises ``DeviceError`` is a miss (counted in ``misses``);
``fail_after`` misses in a row end the polling with the last error, which every
``take`` then raises, so the run ends naming the device.  One miss alone does
not: a status packet lost to line noise, or a slow answer on a loaded machine, is
followed by the next read a period later.

Bounds.  The readings not yet taken are at most ``keep`` (older ones go); the
thread is a daemon, ends on ``stop`` (which joins it with a time-out) or on the
failure, and never outlives the port it reads (the owner stops it first).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable

from dronetrack.errors import ConfigError, DeviceError
from dronetrack.types import TurretState

__all__ = ["FAIL_AFTER", "StatePoller"]

FAIL_AFTER = 3  # misses in a row that end the polling
JOIN_S = 1.0  # longest ``stop`` waits for the thread (a read under way ends first)


class StatePoller:
    """Polls ``read`` at ``rate_hz`` (see the module docstring); ``name`` names the device
    in errors and the thread.  Counters: ``reads`` (successful), ``misses``."""

    def __init__(
        self,
        read: Callable[[], TurretState],
        rate_hz: float,
        *,
        name: str,
        fail_after: int = FAIL_AFTER,
        keep: int = 256,
    ) -> None:
        if not 0 < rate_hz <= 1000:
            raise ConfigError(f"a turret is polled at 1-1000 Hz, got {rate_hz:g} Hz")
        if fail_after < 1 or keep < 1:
            raise ConfigError(f"fail_after and keep must be >= 1, got {fail_after}, {keep}")
        self.read = read
        self.period_s = 1.0 / rate_hz
        self.name = name
        self.fail_after = fail_after
        self.reads = 0
        self.misses = 0
        self._pending: deque[TurretState] = deque(maxlen=keep)
        self._newest: TurretState | None = None
        self._error: DeviceError | None = None
        self._cond = threading.Condition()
        self._held_until = 0.0  # time.monotonic() before which no read starts
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    @property
    def newest(self) -> TurretState | None:
        """The newest reading (taken or not); None before the first."""
        return self._newest

    def start(self) -> None:
        """Start polling (once; later calls do nothing)."""
        if self._thread is None and not self._stop.is_set():
            self._thread = threading.Thread(target=self._loop, name="turret-poller", daemon=True)
            self._thread.start()

    def _loop(self) -> None:
        due = time.monotonic()
        in_a_row = 0
        while not self._stop.is_set():
            self._wait_while_held()
            if self._stop.is_set():
                return
            try:
                state = self.read()
            except DeviceError as exc:
                self.misses += 1
                in_a_row += 1
                if in_a_row >= self.fail_after:
                    with self._cond:
                        self._error = exc
                        self._cond.notify_all()
                    return
            else:
                in_a_row = 0
                with self._cond:
                    self.reads += 1
                    self._newest = state
                    self._pending.append(state)
                    self._cond.notify_all()
            due += self.period_s
            now = time.monotonic()
            if due < now:
                due = now  # behind: the next read now, none of the missed ones
            self._stop.wait(due - now)

    def _wait_while_held(self) -> None:
        with self._cond:
            while not self._stop.is_set():
                left = self._held_until - time.monotonic()
                if left <= 0:
                    return
                self._cond.wait(left)

    def hold(self, max_s: float) -> None:
        """Start no read for ``max_s`` seconds at most, or until ``release``."""
        with self._cond:
            self._held_until = time.monotonic() + max_s

    def release(self) -> None:
        """Let reads start again (after ``hold``)."""
        with self._cond:
            self._held_until = 0.0
            self._cond.notify_all()

    def take(self, fresh: float = float("-inf"), timeout_s: float = 1.0) -> list[TurretState]:
        """The readings made since the last ``take``, oldest first, once the newest is
        stamped at or after ``fresh`` (on ``read``'s clock): waits up to ``timeout_s``
        for one.  Raises the error that ended the polling, or DeviceError if no fresh
        reading came in time or the poller is stopped."""
        deadline = time.monotonic() + timeout_s
        with self._cond:
            while True:
                if self._error is not None:
                    raise self._error
                newest = self._newest
                if newest is not None and newest.stamp >= fresh:
                    break
                if self._stop.is_set():
                    raise DeviceError(f"{self.name}: present position is no longer read")
                left = deadline - time.monotonic()
                if left <= 0:
                    raise DeviceError(f"{self.name}: no present position read for {timeout_s:g} s")
                self._cond.wait(left)
            out = list(self._pending)
            self._pending.clear()
            return out

    def stop(self) -> None:
        """Stop polling and join the thread (at most ``JOIN_S``); safe to call twice."""
        self._stop.set()
        with self._cond:
            self._cond.notify_all()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout=JOIN_S)
