"""Tentative tracks: which of the detect stage's clusters persist, and which move
plausibly, so that a track can start on them.

Every frame the clusters are associated with the tentative tracks by global
nearest neighbour (scipy's ``linear_sum_assignment`` on the distances to the
predicted positions p̂ = p + v Δt), inside a speed gate: a cluster may continue a
track only if

    |c − p| ≤ v_max Δt + g                                       (the speed gate)

that is, a target at the highest expected speed could have moved there since the
track was last detected, plus g for the jitter of a few points' centroid.  A
track's velocity is the centroids' motion, smoothed:

    v ← (c − p) / Δt                      on its second detection,
    v ← v + a ((c − p) / Δt − v)          after that (a = 1/2).

The gate is the plausibility check on motion: every step of a track is at most
v_max Δt + g, so its velocity stays below v_max + g / Δt.  A track is **confirmed**
when it was detected in at least M of the last N frames (M-of-N) and in this one.
It is dropped after N − M + 1 frames in a row without a detection, when it can no
longer reach M of N.  So a single false return, or a flicker of foliage that does
not come back at a plausible place, never confirms.

A track not yet confirmed but detected in at least ``cue_hits`` of the last N frames
is a **cue**: worth a look.  Far out, off the sensor's dense centre, a drone gives
a return in some frames only, too few for M of N; a turret that turns to a cue puts
the dense centre on it, and a real target then confirms within a few frames.  Two
hits inside the speed gate, not one, make a cue: the sensor's random false returns
(a few a frame) rarely fall twice within a gate of each other.  One detection of
``cue_points`` returns or more is a cue too: the false returns come one at a time,
while a drone at the edge of reach, crossed by the search's dense centre, gives two or
three in one frame and then none for a second or more as the search moves on
(``outdoor-incoming``: first returns 148 m out, acquire_s 3.8 → 0.5 s on seed 0).

A track has **hovered** once its speed stayed below v_hover for K detections in a row:

    hovered ← hovered ∨ (run of |v| < v_hover) ≥ K          (v_hover = 4 m/s, K = 3)

A bird cannot do that: it must keep its airspeed above the stall speed, about 5 m/s
for the smallest, while a multirotor hovers, and takes off and lands at 1-3 m/s.  The
cue is one-way: a track that never hovered may still be a drone in fast flight.
Measured on ``outdoor-clutter``, seeds 0-4 (birds at 5-15 m/s): no bird's confirmed
track stayed below 4 m/s for more than one frame in a row; 21 of the drone's 80
tracks hovered, every one that began at take-off or during a hover among them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import linear_sum_assignment

from dronetrack.detect.crowding import crowded
from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Candidates, Detections

__all__ = [
    "ConfirmationSettings",
    "TentativeTracks",
    "gated_assignment",
    "kept",
    "reach",
    "within_reach",
]

SMOOTHING = 0.5  # a: the weight of a new velocity measurement
_INFEASIBLE = 1e12  # an assignment cost no feasible pair can reach [m]


@dataclass(frozen=True, slots=True)
class ConfirmationSettings:
    """M-of-N confirmation with a speed gate (see the module docstring).

    v_max: the highest speed a target may have [m/s]; gate_m: g [m]; hits: M;
    frames: N; max_tracks: the tentative tracks kept at most, which bounds the work
    when clutter floods the foreground; crowd_gap_m: g_c of the crowded test
    (``detect.crowding``; None: every cluster counts as standing alone); crowded_share:
    the share of max_tracks that crowded tracks may hold (see ``kept``).
    """

    v_max: float = 15.0
    gate_m: float = 1.0
    hits: int = 2
    frames: int = 4
    max_tracks: int = 64
    cue_hits: int = 2
    cue_points: int = 0  # a single detection of this many returns is a cue too (0: off)
    hover_speed: float = 4.0  # v_hover [m/s]
    hover_frames: int = 3  # K
    crowd_gap_m: float | None = None
    crowded_share: float = 0.5

    def __post_init__(self) -> None:
        if not (self.v_max > 0 and self.gate_m >= 0):
            raise ConfigError(f"need v_max > 0 and gate ≥ 0, got {self.v_max}, {self.gate_m}")
        if not 1 <= self.hits <= self.frames <= 62:
            raise ConfigError(
                f"need 1 ≤ hits ≤ frames ≤ 62 for M-of-N confirmation, got "
                f"{self.hits} of {self.frames}"
            )
        if not 1 <= self.cue_hits <= self.hits:
            raise ConfigError(f"need 1 ≤ cue_hits ≤ hits, got {self.cue_hits} (hits {self.hits})")
        if self.cue_points < 0:
            raise ConfigError(f"cue_points must be 0 (off) or more, got {self.cue_points}")
        if self.crowd_gap_m is not None and not self.crowd_gap_m >= 0:
            raise ConfigError(f"crowd_gap_m must be 0 or more, got {self.crowd_gap_m}")
        if not 0 <= self.crowded_share <= 1:
            raise ConfigError(f"crowded_share must be in [0, 1], got {self.crowded_share}")
        if self.max_tracks < 1:
            raise ConfigError(f"max_tracks must be positive, got {self.max_tracks}")
        if not (self.hover_speed >= 0 and self.hover_frames >= 1):
            raise ConfigError(
                f"need hover_speed ≥ 0 and hover_frames ≥ 1, got {self.hover_speed}, "
                f"{self.hover_frames}"
            )

    @property
    def max_misses(self) -> int:
        """N − M + 1: misses in a row after which M of N is out of reach."""
        return self.frames - self.hits + 1

    @property
    def max_crowded(self) -> int:
        """The crowded tracks kept at most: ⌊crowded_share · max_tracks⌋."""
        return int(self.crowded_share * self.max_tracks)


def kept(
    detections: NDArray[np.int64],
    ids: NDArray[np.int64],
    crowded: NDArray[np.bool_],
    max_tracks: int,
    max_crowded: int,
) -> NDArray[np.bool_]:
    """Which tracks to keep: at most ``max_tracks``, of which at most ``max_crowded``
    crowded; within each kind the most detected first, of equals the older (lower id).

        n_alone = min(#alone, max_tracks)
        n_crowded = min(#crowded, max_crowded, max_tracks − n_alone)

    The room a crowded track may not take stays free for the tracks that stand alone.
    """
    order = np.lexsort((ids, -detections))
    alone, crowd = order[~crowded[order]], order[crowded[order]]
    n_alone = min(len(alone), max_tracks)
    n_crowded = min(len(crowd), max_crowded, max_tracks - n_alone)
    keep = np.zeros(len(ids), dtype=bool)
    keep[alone[:n_alone]] = True
    keep[crowd[:n_crowded]] = True
    return keep


def gated_assignment(
    predicted: FloatArray, last: FloatArray, reach: FloatArray, centroids: FloatArray
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Global nearest-neighbour pairs (track i, cluster j) inside the speed gate.

    predicted, last: (T, 3) p̂ and p of each track; reach: (T,) v_max Δt + g;
    centroids: (D, 3).  Minimises Σ |c_j − p̂_i| over the pairs with
    |c_j − p_i| ≤ reach_i; returns the indices of the feasible pairs only.
    """
    if len(predicted) == 0 or len(centroids) == 0:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    cost = np.linalg.norm(predicted[:, None, :] - centroids[None, :, :], axis=2)
    moved = np.linalg.norm(last[:, None, :] - centroids[None, :, :], axis=2)
    feasible = moved <= reach[:, None]
    rows, cols = linear_sum_assignment(np.where(feasible, cost, _INFEASIBLE))
    keep = feasible[rows, cols]
    return rows[keep], cols[keep]


def within_reach(
    candidates: Candidates, dt: float, position: FloatArray, v_max: float, gate_m: float
) -> Candidates:
    """The candidates a target last fixed at ``position``, ``dt`` [s] ago, could have
    reached, in their order (best first):

        keep |c − p| ≤ v_max Δt + g

    After a loss this keeps a new start on what the lost target could be, rather than
    on a bird or a swaying crown elsewhere in view; the reach grows with the time lost,
    so a target that reappears far away is still found once it could be there.
    """
    inside = np.linalg.norm(candidates.positions - position, axis=1) <= reach(dt, v_max, gate_m)
    return candidates.take(np.flatnonzero(inside))


def reach(dt: float, v_max: float, gate_m: float) -> float:
    """How far [m] a target may have gone in ``dt`` [s]: v_max Δt + g (Δt < 0 as 0)."""
    return v_max * max(dt, 0.0) + gate_m


def _popcount(history: NDArray[np.int64]) -> NDArray[np.int64]:
    """Set bits of each history word (N ≤ 62)."""
    count = np.zeros_like(history)
    h = history.copy()
    while np.any(h):
        count += h & 1
        h >>= 1
    return count


class TentativeTracks:
    """The tentative tracks, updated once per frame with its clusters.

    At most ``max_tracks`` are kept, and of them at most ``max_crowded`` whose
    clusters were crowded (``detect.crowding``) in more than half of their detections;
    the most detected first (``kept``).  A far structure that the map lacks yet (a
    tree line the turret turns to) breaks into 150 clusters a frame, each one detected
    in every frame.  Were the most detected kept first whatever they are, they would
    fill the room for seconds, and a drone that came into view among them would be
    dropped at its first detection in every frame until the map learnt them.  Such
    fragments stand close to each other, while a drone flies in free space
    (``classify.observe``: crowded in 84 % and 0.1 % of their frames on
    ``outdoor-unscanned``).  The crowded tracks that are kept are the most detected, so
    the same fragments keep their tracks rather than taking turns.
    """

    def __init__(self, settings: ConfirmationSettings = ConfirmationSettings()) -> None:
        self.settings = settings
        self.reset()

    def reset(self) -> None:
        """Forget every tentative track."""
        self.p = np.empty((0, 3))  # latest centroid [m]
        self.v = np.zeros((0, 3))  # velocity [m/s]
        self.t_last = np.empty(0)  # time of the latest detection [s]
        self.history = np.empty(0, dtype=np.int64)  # bit k: detected k frames ago
        self.detections = np.empty(0, dtype=np.int64)  # detections over its life
        self.misses = np.empty(0, dtype=np.int64)  # frames in a row without one
        self.size = np.empty(0)  # largest extent in the latest detection [m]
        self.count = np.empty(0, dtype=np.int64)  # returns in the latest detection
        self.slow = np.empty(0, dtype=np.int64)  # detections in a row with |v| < v_hover
        self.hovered = np.empty(0, dtype=bool)
        self.crowds = np.empty(0, dtype=np.int64)  # detections of a crowded cluster
        self.cluster = np.empty(0, dtype=np.int64)  # this frame's cluster (-1: missed)
        self.ids = np.empty(0, dtype=np.int64)
        self._next_id = 0

    def __len__(self) -> int:
        return len(self.p)

    def update(self, t: float, found: Detections, sensor: FloatArray | None = None) -> Candidates:
        """Take the clusters of the frame ending at ``t`` [s], seen from ``sensor`` (3,)
        (the crowded test's range; None: the gap is g_c); the confirmed candidates."""
        s = self.settings
        every = np.arange(len(found))
        if s.crowd_gap_m is None:
            crowd = np.zeros(len(found), dtype=bool)
        else:
            crowd = crowded(found, every, s.crowd_gap_m, sensor)
        dt = np.maximum(t - self.t_last, 0.0)
        # p̂ = p + v Δt;  reach = v_max Δt + g
        predicted = self.p + self.v * dt[:, None]
        rows, cols = gated_assignment(predicted, self.p, s.v_max * dt + s.gate_m, found.centroids)
        hit = np.zeros(len(self), dtype=bool)
        hit[rows] = True
        # v ← (c − p)/Δt on the second detection, else v + a ((c − p)/Δt − v)
        step = found.centroids[cols] - self.p[rows]
        v_meas = step / np.maximum(dt[rows], 1e-9)[:, None]
        first = self.detections[rows] == 1
        self.v[rows] = np.where(
            first[:, None], v_meas, self.v[rows] + SMOOTHING * (v_meas - self.v[rows])
        )
        self.p[rows] = found.centroids[cols]
        self.cluster = np.full(len(self), -1, dtype=np.int64)
        self.cluster[rows] = cols
        self.t_last[rows] = t
        self.size[rows] = found.extents[cols, 0]
        self.count[rows] = found.counts[cols]
        self.crowds[rows] += crowd[cols]
        self.detections[rows] += 1
        # a run of detections below v_hover, once the velocity is measured (2nd on)
        slow = np.linalg.norm(self.v[rows], axis=1) < s.hover_speed
        self.slow[rows] = np.where(slow, self.slow[rows] + 1, 0)
        self.hovered[rows] |= self.slow[rows] >= s.hover_frames
        self.misses = np.where(hit, 0, self.misses + 1)
        window = (1 << s.frames) - 1
        self.history = ((self.history << 1) | hit.astype(np.int64)) & window
        self._drop(self.misses < s.max_misses)
        unmatched = np.ones(len(found), dtype=bool)
        unmatched[cols] = False
        self._add(t, found, np.flatnonzero(unmatched), crowd)
        # a track is crowded in more than half of its detections: 2 n_c > n
        is_crowded = 2 * self.crowds > self.detections
        self._drop(kept(self.detections, self.ids, is_crowded, s.max_tracks, s.max_crowded))
        return self._confirmed(t)

    def _drop(self, keep: NDArray[np.bool_]) -> None:
        if keep.all():
            return
        for name in (
            "p",
            "v",
            "t_last",
            "history",
            "detections",
            "misses",
            "size",
            "count",
            "slow",
            "hovered",
            "crowds",
            "cluster",
            "ids",
        ):
            setattr(self, name, getattr(self, name)[keep])

    def _add(
        self, t: float, found: Detections, new: NDArray[np.intp], crowd: NDArray[np.bool_]
    ) -> None:
        k = len(new)
        if k == 0:
            return
        self.p = np.concatenate([self.p, found.centroids[new]])
        self.v = np.concatenate([self.v, np.zeros((k, 3))])
        self.t_last = np.concatenate([self.t_last, np.full(k, t)])
        self.history = np.concatenate([self.history, np.ones(k, dtype=np.int64)])
        self.detections = np.concatenate([self.detections, np.ones(k, dtype=np.int64)])
        self.misses = np.concatenate([self.misses, np.zeros(k, dtype=np.int64)])
        self.size = np.concatenate([self.size, found.extents[new, 0]])
        self.count = np.concatenate([self.count, found.counts[new]])
        self.slow = np.concatenate([self.slow, np.zeros(k, dtype=np.int64)])
        self.hovered = np.concatenate([self.hovered, np.zeros(k, dtype=bool)])
        self.crowds = np.concatenate([self.crowds, crowd[new].astype(np.int64)])
        self.cluster = np.concatenate([self.cluster, new.astype(np.int64)])
        self.ids = np.concatenate([self.ids, self._next_id + np.arange(k, dtype=np.int64)])
        self._next_id += k

    def _confirmed(self, t: float) -> Candidates:
        """Detected now and in M of the last N frames; best first."""
        hits = _popcount(self.history)
        idx = self._best(hits, (self.t_last == t) & (hits >= self.settings.hits))
        return Candidates(
            self.p[idx],
            self.v[idx],
            hits[idx],
            self.size[idx],
            self.ids[idx],
            self.hovered[idx],
            self.cluster[idx],
        )

    def cues(self, t: float) -> Candidates:
        """The tracks worth a look at ``t``: in ``cue_hits`` of the last N frames, or
        with ``cue_points`` returns in their latest detection, and not confirmed now;
        best first, at their predicted positions p + v Δt."""
        s = self.settings
        hits = _popcount(self.history)
        confirmed = (self.t_last == t) & (hits >= s.hits)
        big = (s.cue_points > 0) & (self.count >= s.cue_points)
        idx = self._best(hits, ~confirmed & ((hits >= s.cue_hits) | big))
        dt = np.maximum(t - self.t_last[idx], 0.0)
        predicted = self.p[idx] + self.v[idx] * dt[:, None]
        return Candidates(
            predicted, self.v[idx], hits[idx], self.size[idx], self.ids[idx], self.hovered[idx]
        )

    def _best(self, hits: NDArray[np.int64], ok: NDArray[np.bool_]) -> NDArray[np.intp]:
        """The indices of the tracks where ``ok``, best first: those that hovered (no
        bird), then most detections in the window, then over its life, then the older."""
        idx = np.flatnonzero(ok)
        keys = (self.ids[idx], -self.detections[idx], -hits[idx], ~self.hovered[idx])
        return idx[np.lexsort(keys)]
