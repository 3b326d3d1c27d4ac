"""``run``: the loop every command runs, a source's frames through a stage to an
actuator and sinks."""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Protocol

from dronetrack.interrupt import stop_requested, stoppable
from dronetrack.seams import Actuator, Sink, Source
from dronetrack.types import Frame, StepResult

__all__ = ["RunStats", "Stage", "run"]


class Stage(Protocol):
    """What ``run`` steps: a ``Pipeline``, or anything else that turns frames into results."""

    def step(self, frame: Frame) -> StepResult: ...


@dataclass(frozen=True, slots=True)
class RunStats:
    """How a run went: frames done, the source time they span, the wall time they took."""

    frames: int
    start: float  # the first frame's start [s] on the source's clock; NaN if none
    end: float  # the last frame's end [s]; NaN if none
    wall_s: float
    interrupted: bool  # Ctrl-C ended the run before the source did

    @property
    def span_s(self) -> float:
        """Source time covered, first frame's start to last frame's end [s]."""
        return self.end - self.start if self.frames else 0.0


def run(
    source: Source,
    pipeline: Stage,
    actuator: Actuator | None = None,
    sinks: Sequence[Sink] = (),
    *,
    followers: Sequence[tuple[Stage, Sequence[Sink]]] = (),
    progress: Callable[[int, int], None] | None = None,
    total: int | None = None,
) -> RunStats:
    """The loop every command runs: for each frame of ``source``, step ``pipeline``, send
    its command to ``actuator``, then hand the frame and the result to each sink.

    ``followers`` are more stages fed the same frames, each with its own sinks; their
    commands go nowhere, so they see exactly the frames the leading pipeline's turret
    produced (a lockstep comparison).  ``progress`` is told (frames done, ``total``)
    after each frame.  A Ctrl-C handled by ``dronetrack.interrupt`` ends the loop after
    the frame in hand, so no sink holds half a frame.
    """
    for sink in sinks:  # a sink that takes tasks (a C2 link) gets the pipeline's look_at
        attach = getattr(sink, "attach", None)
        if attach is not None:
            attach(pipeline)
    begin = time.perf_counter()
    n = 0
    start = end = float("nan")
    with stoppable():
        for sample in source:
            frame = sample.frame
            result = pipeline.step(frame)
            if actuator is not None and result.command is not None:
                actuator.command(result.command)
            if sample.received is not None:
                # latency: the frame's last point's arrival to its command being sent
                latency = 1000.0 * (time.perf_counter() - sample.received)
                result = replace(result, latency_ms=latency)
            for sink in sinks:
                sink.write(sample, result)
            for stage, stage_sinks in followers:
                other = stage.step(frame)
                for sink in stage_sinks:
                    sink.write(sample, other)
            n += 1
            start = frame.stamp if n == 1 else start
            end = frame.end
            if progress is not None:
                progress(n, max(n, total or 0))
            if stop_requested():
                break
        interrupted = stop_requested()
    return RunStats(n, start, end, time.perf_counter() - begin, interrupted)
