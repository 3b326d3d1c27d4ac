"""One frame as a viewer shows it, and the interface of the viewer writers.

``simulate`` and ``track`` fill a ``ViewFrame`` per frame and hand it to every
open ``ViewerSink`` (``--foxglove FILE.mcap``, ``--rerun FILE.rrd``).
Everything is in the world frame [m], times in seconds from the run's start.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from dronetrack.geometry.transforms import FloatArray
from dronetrack.pipeline import StepResult
from dronetrack.types import Frame

__all__ = ["NamedTransform", "ViewFrame", "ViewerSink", "view_frame"]


@dataclass(frozen=True, slots=True)
class NamedTransform:
    """parent_T_child (4, 4), as a /tf edge."""

    parent: str
    child: str
    matrix: FloatArray


@dataclass(frozen=True, slots=True)
class ViewFrame:
    """What a viewer shows of one frame."""

    t: float  # frame end [s]
    points: FloatArray  # (N, 3) the frame's returns, world frame
    foreground: FloatArray  # (M, 3) the points the tracker was given
    estimate: FloatArray | None  # (3,) the tracker's position, None while scanning
    tracked: bool
    truth: FloatArray | None  # (3,) ground truth, None when unknown
    particles: FloatArray | None  # (P, 3) a particle filter's particles
    transforms: tuple[NamedTransform, ...]  # world → turret links → sensor, at the frame end


class ViewerSink(Protocol):
    """A writer of a viewer file."""

    def log(self, frame: ViewFrame) -> None:
        """Add one frame."""
        ...

    def close(self) -> None:
        """Finish the file."""
        ...


def view_frame(
    frame: Frame,
    result: StepResult,
    truth: FloatArray | None,
    transforms: Sequence[NamedTransform],
) -> ViewFrame:
    """What a viewer shows of one frame."""
    est = result.estimate
    return ViewFrame(
        t=frame.end,
        points=result.world if len(result.world) == len(frame) else frame.world_points(),
        foreground=result.foreground,
        estimate=None if est is None else est.position,
        tracked=bool(est is not None and est.tracked),
        truth=truth if truth is not None and np.all(np.isfinite(truth)) else None,
        particles=None if est is None else est.particles,
        transforms=tuple(transforms),
    )
