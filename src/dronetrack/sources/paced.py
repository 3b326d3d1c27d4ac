"""A recording played at wall-clock speed: ``dronetrack live --lidar file://RECORDING``.

Frame k of the recording is due at

    τ_k = τ_0 + (e_k − s_0)        e_k: the frame's end, s_0: the first frame's start

on the host's ``perf_counter`` clock, τ_0 being when the first frame was asked for:
the moment a live sensor would have delivered its last point.  The source sleeps
until then (in slices, so a stop request ends it at once) and hands the frame on
with ``received = τ_k``, so ``pipeline.run`` measures the latency from there as for
a live sensor.

Falling behind.  As ``sources.live.LiveSource`` holds at most ``max_frames``
complete frames, a frame still waiting when ``max_frames`` later frames have
become due, i.e. when

    now ≥ τ_k + max_frames · T            T: the nominal frame period,

is dropped whole and counted (``frames_dropped``).  The recording's own poses and
truth are kept: a turret commanded during the run does not move a recorded sensor.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from dataclasses import replace

from dronetrack.errors import ConfigError
from dronetrack.interrupt import stop_requested
from dronetrack.seams import Source
from dronetrack.types import Sample

__all__ = ["FILE_SCHEME", "PacedSource"]

FILE_SCHEME = "file://"
SLICE_S = 0.05  # longest single sleep, so a stop request is seen within it


class PacedSource:
    """The frames of ``source`` at wall-clock speed (see the module docstring).

    ``duration_s``: only the frames that start within this much source time of the
    first frame's start (None: the whole recording).  ``clock`` and
    ``sleep`` are the host's (``time.perf_counter``, ``time.sleep``); tests give
    their own.
    """

    def __init__(
        self,
        source: Source,
        *,
        max_frames: int = 2,
        duration_s: float | None = None,
        clock: Callable[[], float] = time.perf_counter,
        sleep: Callable[[float], None] = time.sleep,
        name: str = "recording",
    ) -> None:
        if max_frames < 1:
            raise ConfigError(f"the frame queue needs room for 1 frame, got {max_frames}")
        self.source = source
        self.max_frames = max_frames
        self.duration_s = duration_s
        self.clock = clock
        self.sleep = sleep
        self.name = name
        self.frames_dropped = 0
        self.frames_delivered = 0
        # a recording has no packets: nothing is lost or malformed on the way
        self.packets_lost = 0
        self.packets_malformed = 0

    @property
    def period(self) -> float:
        return self.source.period

    def _wait_until(self, due: float) -> bool:
        """Sleep until ``due``; False if a stop request came first."""
        while True:
            if stop_requested():
                return False
            left = due - self.clock()
            if left <= 0:
                return True
            self.sleep(min(left, SLICE_S))

    def __iter__(self) -> Iterator[Sample]:
        tau0: float | None = None
        s0 = 0.0
        late = self.max_frames * self.period
        for sample in self.source:
            frame = sample.frame
            if tau0 is None:
                tau0, s0 = self.clock(), frame.stamp
            if self.duration_s is not None and frame.stamp - s0 >= self.duration_s - 1e-9:
                return  # the frames that start within the duration are done
            due = tau0 + (frame.end - s0)  # τ_k = τ_0 + (e_k − s_0)
            if self.clock() >= due + late:  # max_frames later frames are already due
                self.frames_dropped += 1
                continue
            if not self._wait_until(due):
                return
            self.frames_delivered += 1
            yield replace(sample, received=due)
