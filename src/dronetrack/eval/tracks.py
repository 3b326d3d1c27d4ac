"""The per-frame log of every object's track (``tracks.csv``): one row per track per
tracking frame."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.types import Tracks

__all__ = ["TRACK_COLUMNS", "TracksLog"]

# The tracks.csv contract, in this order (more columns may follow).
TRACK_COLUMNS = (
    "t",
    "id",
    "class",
    "p_drone",
    "x",
    "y",
    "z",
    "vx",
    "vy",
    "vz",
    "pos_sigma_m",
    "locked",
)

_ROW = np.dtype(
    [
        ("t", np.float64),
        ("id", np.int64),
        ("cls", np.int64),  # index into TRACK_CLASSES
        ("p_drone", np.float64),
        ("position", np.float64, (3,)),
        ("velocity", np.float64, (3,)),
        ("pos_sigma", np.float64),
        ("locked", np.bool_),
        ("updated", np.bool_),  # a cluster of the frame updated it (else it coasted)
        ("in_view", np.bool_),  # in the sensor's field of view
    ]
)


class TracksLog:
    """Every track of every tracking frame, as arrays (``rows`` reads them so far)."""

    __slots__ = ("_chunks", "_frames", "_n", "_rows")

    def __init__(self) -> None:
        self._chunks: list[NDArray[Any]] = []
        self._rows: NDArray[Any] = np.zeros(0, dtype=_ROW)
        self._n = 0
        self._frames = 0

    def append(self, t: float, tracks: Tracks) -> None:
        """The tracks after the frame ending at ``t`` [s]."""
        self._frames += 1
        k = len(tracks)
        if k == 0:
            return
        chunk = np.zeros(k, dtype=_ROW)
        chunk["t"] = t
        chunk["id"] = tracks.ids
        chunk["cls"] = tracks.classes
        chunk["p_drone"] = tracks.p_drone
        chunk["position"] = tracks.positions
        chunk["velocity"] = tracks.velocities
        chunk["pos_sigma"] = tracks.position_sigma
        chunk["locked"] = tracks.locked
        chunk["updated"] = tracks.updated
        chunk["in_view"] = tracks.in_view
        self._chunks.append(chunk)
        self._n += k

    def __len__(self) -> int:
        """Rows (tracks × frames) so far."""
        return self._n

    @property
    def frames(self) -> int:
        """Tracking frames appended (with or without tracks)."""
        return self._frames

    @property
    def rows(self) -> NDArray[Any]:
        """Every row so far, a structured array (t, id, cls, p_drone, position,
        velocity, pos_sigma, locked, updated, in_view); read-only."""
        if self._chunks:
            self._rows = np.concatenate([self._rows, *self._chunks])
            self._chunks = []
        view = self._rows.view()
        view.flags.writeable = False
        return view
