"""Tracks at rest: those the layer ended for room while the classes held them no drone
(``MultiTargetTracker``'s cap), kept a while so that a birth on the same object is
their heir and takes their life.

What such a track followed is still there: a structure the background map does not
hold yet, whose fragments fill the layer.  Its clusters give birth to a track again
within the detect stage's M-of-N frames, whose life, and class, would start from
nothing: on ``outdoor-unscanned`` (seed 0) 1037 of a run's 1788 tracks were born
within 1 m of where a track held no drone had ended in the 5 s before, and the three
tracks of the static world the turret locked on were all such births, unknown
(p_drone 0.5) where the track before them had been classed static.

The heir is a new identity, and the classes give it the life of the track at rest
(``classify.features.TrackLives``).  Giving it the old identity back was measured
too: one identity then stood for an object across its stays in the layer, absent
from the output between them, and its class waited on observations gathered only
in those stays (``outdoor-unscanned``, seeds 0-9: static tracks not classed within
3 s, 3.3 → 46.7 a run).

A track at rest is matched to a birth by its last fix p_u: the nearest birth within
``radius`` of it (the clustering's ε, the layer's test of one object), one birth each,
by ``scipy.optimize.linear_sum_assignment`` on the distances.  It rests for ``keep_s``
after it ended (the layer's ``coast_s``: a missed object's track lives that long).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray
from dronetrack.track.cv_bank import INFEASIBLE, associate

__all__ = ["Resting", "keep_at_cap", "match_rested"]


def match_rested(
    births: FloatArray, rested: FloatArray, radius: float
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The pairs (birth rows, rested rows) of the least-distance assignment of the
    births' positions (B, 3) to the rested tracks' last fixes (R, 3) within ``radius``
    [m]: ‖b − p_u‖ ≤ radius, each at most once.  Non-finite positions match nothing."""
    if len(births) == 0 or len(rested) == 0:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    d = np.linalg.norm(births[:, None, :] - rested[None, :, :], axis=2)
    cost = np.where(np.isfinite(d) & (d <= radius), d, INFEASIBLE)
    return associate(cost)


def keep_at_cap(
    ids: NDArray[np.int64],
    updates: NDArray[np.int64],
    t_update: FloatArray,
    unlikely: NDArray[np.bool_],
    held: NDArray[np.bool_],
    cap: int,
) -> NDArray[np.bool_]:
    """(K,) the tracks that live when there are more than ``cap``: the held track
    lives; those the classes hold no drone (``unlikely``) die first; then the longest
    unseen (the earliest last update ``t_update``); of equals, the least updated, then
    the younger (the greater identity): an established track outlives the births of a
    cluttered frame.  Ended under the lock, a track on a lamp post that the classes
    were about to call static left the tracker locked on what no track followed, which
    nothing gives up (``outdoor-unscanned`` seed 1: 1.1 s)."""
    order = np.lexsort((ids, -updates, -t_update, unlikely, ~held))
    keep = np.zeros(len(ids), dtype=bool)
    keep[order[:cap]] = True
    return keep


@dataclass
class Resting:
    """The tracks at rest: identity, last fix p_u [m] and when it ended [s], one row each."""

    ids: NDArray[np.int64] = field(default_factory=lambda: np.empty(0, dtype=np.int64))
    p_update: FloatArray = field(default_factory=lambda: np.empty((0, 3)))
    ended: FloatArray = field(default_factory=lambda: np.empty(0))

    def __len__(self) -> int:
        return len(self.ids)

    def add(self, t: float, ids: NDArray[np.int64], p_update: FloatArray) -> None:
        """Rest the tracks ``ids`` that ended at ``t``, last fixed at ``p_update``."""
        self.ids = np.concatenate([self.ids, ids])
        self.p_update = np.concatenate([self.p_update, p_update])
        self.ended = np.concatenate([self.ended, np.full(len(ids), t)])

    def keep(self, rows: NDArray[np.bool_]) -> None:
        """Keep the rows ``rows`` (R,), forget the others."""
        for name in ("ids", "p_update", "ended"):
            setattr(self, name, getattr(self, name)[rows])

    def expire(self, t: float, keep_s: float) -> None:
        """Forget those that ended more than ``keep_s`` before ``t``."""
        self.keep(t - self.ended <= keep_s)
