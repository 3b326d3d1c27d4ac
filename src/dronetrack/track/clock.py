"""The filters' clock: whole filter periods up to each frame's end.

The clock advances by whole periods, so frames that arrive at other intervals
neither drift nor lose time.  A repeated or older frame runs no period; a gap runs
one per missed period; a jump of more than ``max_gap_s`` either way starts the
clock again on the new time line (and the caller restarts its filter).
"""

from __future__ import annotations

import math

__all__ = ["MAX_GAP_S", "FilterClock"]

MAX_GAP_S = 5.0  # a longer jump in time restarts the filter instead of predicting across it


class FilterClock:
    """The end of the last filter period run, and how many periods a new frame needs."""

    def __init__(self, period: float, max_gap_s: float = MAX_GAP_S) -> None:
        self.period = period
        self.max_gap_s = max_gap_s
        self.time: float | None = None  # the end of the last period run [s]

    def advance(self, end: float, flags: list[str]) -> int:
        """Periods to run for a frame ending at ``end`` [s]; the problems met go to ``flags``:
        ``bad_time``, ``time_jump`` (restart the filter), ``repeated``, ``out_of_order``, ``gap``.
        """
        if not math.isfinite(end):
            flags.append("bad_time")
            return 0
        if self.time is None:
            self.time = end
            return 1
        elapsed = end - self.time
        if elapsed > self.max_gap_s or elapsed < -self.max_gap_s:
            flags.append("time_jump")
            self.time = end
            return 1
        # k = ⌊Δt / T + ½⌋: whole periods up to this frame's end (half a period of slack
        # for jitter)
        steps = math.floor(elapsed / self.period + 0.5)
        if steps <= 0:
            # The clock sums whole periods, so "the same time" allows rounding.
            flags.append("repeated" if abs(elapsed) <= 1e-6 * self.period else "out_of_order")
            return 0
        self.time += steps * self.period
        if steps > 1:
            flags.append("gap")
        return steps
