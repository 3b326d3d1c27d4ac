"""The live soak's memory: this process's resident set size, sampled in a thread, and
its growth after a warm-up (``experiments.bench.live``)."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

from dronetrack.errors import ConfigError

__all__ = ["RssSampler", "resident_mb", "rss_growth_pct"]


def resident_mb() -> float:
    """This process's resident set size [MB] now (``/proc/self/statm``, Linux):
    resident pages × the page size.  ConfigError where there is no such file."""
    try:
        fields = Path("/proc/self/statm").read_text().split()
    except OSError as exc:
        raise ConfigError(f"the soak reads /proc/self/statm (Linux only): {exc}") from None
    return int(fields[1]) * os.sysconf("SC_PAGE_SIZE") / 1e6


def rss_growth_pct(samples: list[tuple[float, float]], warmup_s: float) -> float:
    """Growth after warm-up [%]: 100 · (max RSS after it − RSS at its end) / RSS at its
    end, over (t [s since the run's start], RSS [MB]) samples; the end of warm-up is
    the first sample at or after ``warmup_s``.  ConfigError if there is none."""
    after = [rss for t, rss in samples if t >= warmup_s]
    if not after:
        raise ConfigError(f"no memory sample after the {warmup_s:g} s warm-up: soak longer")
    return 100.0 * (max(after) - after[0]) / after[0]


class RssSampler:
    """A daemon thread that samples ``resident_mb`` every ``period_s`` from ``start``."""

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self.samples: list[tuple[float, float]] = []
        self._stop = threading.Event()
        self._t0 = 0.0
        self._thread = threading.Thread(target=self._loop, name="rss-sampler", daemon=True)

    def start(self) -> None:
        self._t0 = time.monotonic()
        self._thread.start()

    def _loop(self) -> None:
        while True:
            self.samples.append((time.monotonic() - self._t0, resident_mb()))
            if self._stop.wait(self.period_s):
                return

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
