"""The three seams of a run: where frames come from, where commands go, who watches.

    Source ──Sample──▶ Pipeline.step ──TurretCommand──▶ Actuator
                            │
                       StepResult ──▶ Sinks

``pipeline.run(source, pipeline, actuator, sinks)`` is the one loop every command
uses.  The simulator is a Source and an Actuator; a recording is a Source with no
turret to command; a live rig's LiDAR is a Source and its servos an Actuator.

Who owns time: the **Source**.  Every time in a run is a float64 second on the
source's clock: its frames' stamps and per-point times, the pose samples, the
truth.  The pipeline only follows it (the tracker's clock advances by whole filter
periods up to each frame's end) and stamps each command at the frame's end plus
the modelled latency.  The **Actuator** executes a command at its stamp on that
same clock (a simulated turret) or at once (a real one, whose clock is the
source's by construction of the rig).  Sinks write what they are given and keep no
clock of their own.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Protocol

from dronetrack.types import Sample, StepResult, TurretCommand, TurretState

__all__ = ["Actuator", "Sink", "Source"]


class Source(Protocol):
    """Frames, one integration period each, in time order (the source's own clock).

    Iterating yields each frame as a ``Sample``: the frame (points in the sensor
    frame, per-point times, and the sensor poses during the frame), plus the
    target's truth and the turret's measured state where the source knows them.
    A closed loop's source produces the next frame only when asked, after the
    actuator has received the previous frame's command.
    """

    @property
    def period(self) -> float:
        """The nominal frame period [s]."""
        ...

    def __iter__(self) -> Iterator[Sample]: ...


class Actuator(Protocol):
    """A turret: takes the pipeline's commands and reports its measured joint state."""

    def command(self, command: TurretCommand) -> None:
        """Execute ``command`` from its stamp on (a position goal or a rate)."""
        ...

    def state(self) -> TurretState | None:
        """The latest measured joint state; None if the turret reports none."""
        ...


class Sink(Protocol):
    """Receives every frame's result, in order: a run folder, a viewer, a log, a writer.

    A sink is written after the actuator has the frame's command and before the
    source makes the next frame.  Whoever opens a sink closes it.
    """

    def write(self, sample: Sample, result: StepResult) -> None: ...
