"""A VLP-16's packet stream in time: its hour-long timestamps unwrapped, lost packets
counted, the spin rate, and the moments a revolution starts.

Time.  A packet's timestamp counts microseconds past the hour (``formats.velodyne``),
so it wraps to 0 every hour.  ``PacketClock`` unwraps the stamps into one time base,
nanoseconds since the top of the first hour seen:

    t = (h · 3 600 000 000 + stamp) · 1000 ns,   h += 1 where the stamp falls back by
                                                   more than half an hour

Loss.  Consecutive packets are P = 24 · 55.296 µs apart (12 sequences in dual-return
mode), so a gap g between two packets' times counts

    lost = round(g / P) − 1      when g > 1.5 P,   else 0

packets lost (as the Livox SDK 1 link does; a stamp that goes back restarts the
check).  Lost packets at the very end of a stream cannot be seen.

Revolutions.  ``RevolutionCuts`` finds where the head's azimuth passes the cut angle
α_c.  With a = (α − α_c) mod 360° the angle past it, a revolution starts between
two blocks i and i + 1 (in time order) where a falls, at the time the azimuth
reaches α_c, linear between the blocks:

    t* = t_i + (t_{i+1} − t_i) · (360° − a_i) / (360° − a_i + a_{i+1})

The very first block seen starts one only if it lies exactly on α_c (a = 0).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dronetrack.formats import velodyne as fv

__all__ = ["PacketClock", "RevolutionCuts", "spin_advance", "spin_rpm"]


class PacketClock:
    """Unwraps packet timestamps and counts lost packets (module docstring).
    Counter: ``lost``."""

    def __init__(self) -> None:
        self.lost = 0
        self._hours = 0
        self._prev_us: int | None = None  # the last stamp seen, µs past its hour
        self._prev_t: int | None = None  # the last packet's time [µs]

    def times_ns(
        self, stamp_us: NDArray[np.int64], span_ns: NDArray[np.int64]
    ) -> NDArray[np.int64]:
        """The times [ns] of packets with ``stamp_us`` (in arrival order) whose firings
        span ``span_ns`` each (``fv.packet_span_ns`` of their return mode)."""
        s = np.asarray(stamp_us, np.int64)
        if len(s) == 0:
            return np.zeros(0, np.int64)
        prev = s[0] if self._prev_us is None else self._prev_us
        # h += 1 where the stamp falls back by more than half an hour
        wraps = np.diff(np.r_[prev, s]) < -fv.HOUR_US // 2
        hours = self._hours + np.cumsum(wraps)
        t_us = hours * fv.HOUR_US + s
        self._hours = int(hours[-1])
        self._prev_us = int(s[-1])
        before = t_us[0] if self._prev_t is None else self._prev_t
        gap_ns = np.diff(np.r_[before, t_us]) * 1000
        span = np.asarray(span_ns, np.int64)
        late = 2 * gap_ns > 3 * span  # g > 1.5 P
        self.lost += int(np.sum(np.rint(gap_ns[late] / span[late]).astype(np.int64) - 1))
        self._prev_t = int(t_us[-1])
        return t_us * 1000


class RevolutionCuts:
    """The times a revolution starts: where the blocks' azimuth passes ``cut_deg``
    (module docstring).  It remembers the last block of the previous call."""

    def __init__(self, cut_deg: float = 0.0) -> None:
        self.cut = round(cut_deg * 100) % 36_000
        self._prev: tuple[int, int] | None = None  # (t [ns], a [0.01°]) of the last block

    def cuts(self, t_ns: NDArray[np.int64], azimuth: NDArray[np.uint16]) -> list[int]:
        """The starts [ns] among blocks at times ``t_ns`` with azimuths ``azimuth``
        [0.01°] (flat, in time order)."""
        t = np.asarray(t_ns, np.int64).ravel()
        if len(t) == 0:
            return []
        a = (np.asarray(azimuth, np.int64).ravel() - self.cut) % 36_000
        out: list[int] = []
        if self._prev is None:
            if a[0] == 0:
                out.append(int(t[0]))
        else:
            t = np.r_[self._prev[0], t]
            a = np.r_[self._prev[1], a]
        self._prev = (int(t[-1]), int(a[-1]))
        dt = np.diff(t)
        falls = (np.diff(a) < 0) & (dt > 0)
        # a restart of the clock (time going back) starts afresh, as the first block
        restart = np.flatnonzero(dt < 0) + 1
        i = np.flatnonzero(falls)
        if len(i):
            # t* = t_i + (t_{i+1} − t_i) · (360° − a_i) / (360° − a_i + a_{i+1})
            left = 36_000 - a[i]
            frac = left / (left + a[i + 1])
            out.extend(int(v) for v in t[i] + np.rint(dt[i] * frac).astype(np.int64))
        out.extend(int(t[j]) for j in restart if a[j] == 0)
        return sorted(set(out))


def spin_advance(t_ns: NDArray[np.int64], azimuth: NDArray[np.uint16]) -> tuple[int, int]:
    """How far the head turned [0.01°] and over how long [ns] across blocks at times
    ``t_ns`` with azimuths ``azimuth`` [0.01°] (flat, in time order): the advance
    between consecutive blocks whose time grows, modulo a turn."""
    t = np.asarray(t_ns, np.int64).ravel()
    a = np.asarray(azimuth, np.int64).ravel()
    dt = np.diff(t)
    step = dt > 0
    return int((np.diff(a)[step] % 36_000).sum()), int(dt[step].sum())


def spin_rpm(t_ns: NDArray[np.int64], azimuth: NDArray[np.uint16]) -> float | None:
    """The head's spin rate [rpm] over those blocks (``spin_advance``); None over less
    than 1 ms."""
    advance, span_ns = spin_advance(t_ns, azimuth)
    if span_ns < 1_000_000:
        return None
    # rpm = (turns / s) · 60, turns = advance / 36000
    return advance / 36_000 / (span_ns * 1e-9) * 60.0
