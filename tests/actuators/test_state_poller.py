"""StatePoller with a scripted reader (no serial line): the rate, fresh readings, one
miss tolerated, three in a row ending the polling with the reader's error, and a
bounded thread.  Every wait has a deadline."""

from __future__ import annotations

import itertools
import threading
import time

import pytest

from dronetrack.actuators.state_poller import FAIL_AFTER, JOIN_S, StatePoller
from dronetrack.errors import ConfigError, DeviceError
from dronetrack.types import TurretState


class Script:
    """A reader that stamps each call on time.monotonic and fails on the calls listed
    (counted from 1), or on every call from ``fail_from`` on."""

    def __init__(self, fail_on: tuple[int, ...] = (), fail_from: int | None = None) -> None:
        self.calls = 0
        self.fail_on = fail_on
        self.fail_from = fail_from
        self.lock = threading.Lock()

    def __call__(self) -> TurretState:
        with self.lock:
            self.calls += 1
            n = self.calls
        if n in self.fail_on or (self.fail_from is not None and n >= self.fail_from):
            raise DeviceError(f"servo ID 2 (tilt): read {n} timed out")
        return TurretState(time.monotonic(), pan=0.001 * n, tilt=0.0)


def _poller(script: Script, rate_hz: float = 100.0, **kw: int) -> StatePoller:
    return StatePoller(script, rate_hz, name="test turret", **kw)


def test_readings_come_at_the_rate_in_order_and_each_once() -> None:
    script = Script()
    poller = _poller(script, 100.0)
    poller.start()
    try:
        time.sleep(0.5)
        got = poller.take()
        more = poller.take(fresh=got[-1].stamp + 0.001, timeout_s=1.0)
    finally:
        poller.stop()
    # 100 Hz for 0.5 s: 50 reads due; a loaded machine may delay some, never add any
    assert 30 <= len(got) <= 52
    stamps = [s.stamp for s in got + more]
    assert all(b > a for a, b in itertools.pairwise(stamps))  # in order, none twice
    # the reads are spaced by the period on average: (n - 1) periods between first and last
    assert (got[-1].stamp - got[0].stamp) / (len(got) - 1) == pytest.approx(0.01, rel=0.3)


def test_take_waits_for_a_fresh_reading() -> None:
    poller = _poller(Script(), 20.0)  # a reading every 50 ms
    poller.start()
    try:
        first = poller.take(timeout_s=1.0)
        fresh = first[-1].stamp + 0.12  # newer than the next two
        got = poller.take(fresh=fresh, timeout_s=1.0)
        assert got[-1].stamp >= fresh
        assert time.monotonic() >= fresh
        assert len(got) >= 3
    finally:
        poller.stop()


def test_one_miss_is_tolerated() -> None:
    script = Script(fail_on=(3, 6, 7))  # never FAIL_AFTER in a row
    poller = _poller(script, 200.0)
    poller.start()
    try:
        deadline = time.monotonic() + 2.0
        while script.calls < 12 and time.monotonic() < deadline:
            time.sleep(0.01)
        got = poller.take()
    finally:
        poller.stop()
    assert poller.misses == 3
    assert len(got) >= 9
    assert poller.reads + poller.misses == script.calls  # every call counted once


def _ended(poller: StatePoller) -> bool:
    """Whether the polling thread has ended, waiting for it at most ``JOIN_S``."""
    assert poller._thread is not None
    poller._thread.join(timeout=JOIN_S)
    return not poller.running


def test_misses_in_a_row_end_polling_with_the_readers_error() -> None:
    """take raises the reader's own error (read 6), not its time-out's, once FAIL_AFTER
    reads in a row failed; the poller reads no more and its thread ends."""
    script = Script(fail_from=4)
    poller = _poller(script, 200.0)
    poller.start()
    try:
        with pytest.raises(DeviceError, match=r"servo ID 2 \(tilt\): read 6 timed out"):
            poller.take(fresh=float("inf"), timeout_s=2.0)
        assert (poller.reads, poller.misses) == (3, FAIL_AFTER)
        assert script.calls == 3 + FAIL_AFTER  # it stopped reading
        assert _ended(poller)
        with pytest.raises(DeviceError, match="read 6"):  # and every later take says so
            poller.take()
    finally:
        poller.stop()


def test_no_fresh_reading_in_time_is_a_device_error() -> None:
    poller = _poller(Script(), 10.0)
    poller.start()
    try:
        poller.take(timeout_s=1.0)
        with pytest.raises(DeviceError, match=r"test turret: no present position read for 0\.05 s"):
            poller.take(fresh=time.monotonic() + 10.0, timeout_s=0.05)
    finally:
        poller.stop()


def test_stop_ends_the_thread_and_take_then_fails() -> None:
    """stop joins the thread (it has ended when stop returns, no read after it); take
    then fails, and a stopped poller does not start again."""
    script = Script()
    poller = _poller(script, 100.0)
    poller.start()
    poller.take(timeout_s=1.0)
    poller.stop()
    calls = script.calls
    assert poller._thread is not None
    assert not poller._thread.is_alive()
    assert not poller.running
    assert poller._thread.daemon
    with pytest.raises(DeviceError, match="no longer read"):
        poller.take(fresh=float("inf"))
    poller.stop()  # twice is fine
    poller.start()  # and a stopped poller does not start again
    assert not poller.running
    assert script.calls == calls


def test_readings_not_taken_are_bounded() -> None:
    poller = _poller(Script(), 500.0, keep=8)
    poller.start()
    try:
        time.sleep(0.2)
        got = poller.take()
    finally:
        poller.stop()
    assert len(got) == 8
    assert poller.reads > 8


@pytest.mark.parametrize(("rate", "kw"), [(0.0, {}), (2000.0, {}), (10.0, {"fail_after": 0})])
def test_bad_settings_are_config_errors(rate: float, kw: dict[str, int]) -> None:
    with pytest.raises(ConfigError):
        _poller(Script(), rate, **kw)


def test_no_read_starts_while_held() -> None:
    """hold keeps reads from starting until release, or until its time is up."""
    script = Script()
    poller = _poller(script, 200.0)
    poller.start()
    try:
        poller.take(timeout_s=1.0)
        poller.hold(10.0)
        time.sleep(0.02)  # a read under way when held may still finish
        held_at = script.calls
        time.sleep(0.2)  # 40 reads would have been due
        assert script.calls == held_at
        poller.release()
        time.sleep(0.1)
        assert script.calls >= held_at + 5
        poller.hold(0.05)  # not released: reads start again after 50 ms
        time.sleep(0.01)
        held_at = script.calls
        time.sleep(0.2)
        assert script.calls >= held_at + 5
    finally:
        poller.stop()
