"""Decoded Livox points as the batch a live source cuts into frames: the points with a
return, with their laser lines, in time order."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from dronetrack.formats.livox.common import LivoxPoints
from dronetrack.sources.assembly import PointBatch

__all__ = ["hits_in_time_order"]


def hits_in_time_order(
    parts: Sequence[LivoxPoints], lines: Sequence[NDArray[np.uint8]]
) -> PointBatch:
    """The points with a return of ``parts`` (with their ``lines``), sorted by time."""
    if not parts:
        u8 = np.zeros(0, np.uint8)
        return PointBatch(np.zeros((0, 3)), np.zeros(0, np.int64), u8, u8)
    pts = LivoxPoints.concat(parts)
    line = np.concatenate(lines)
    hit = pts.hit
    order = np.argsort(pts.t_ns[hit], kind="stable")
    return PointBatch(
        pts.points[hit][order], pts.t_ns[hit][order], pts.reflectivity[hit][order], line[hit][order]
    )
