"""Every object a track: an identity, a state, a covariance and a life for each object
the detect stage confirms, beside the one target the turret's tracker is locked on.

Each track is a constant-velocity Kalman filter (``track.cv_bank``: the model, the
measurement noise and the association cost J with its two gates), associated with
all of the frame's clusters by global nearest neighbour.

A track unseen for longer than ``stale_s`` (0.3 s: the detect stage's N − M + 1 = 3
frames) is matched only with a confirmed candidate's cluster, or a cluster within
``stale_gate_m`` (5 m) of its prediction: its gate has grown with
its covariance (σ ≈ 6 m after 1.5 s at σ_a = 15 m/s²), and a lone false return in it
would otherwise carry it off (``default`` seed 0: a duplicate of the drone's track
jumped 24 m to a stray return and wandered 60 m away for 4 s, holding the drone's
hover).  A matched track is updated (Joseph form, ``track.kalman``).  A track is **born** on
a confirmed candidate of the detect stage (M-of-N, ``detect.tentative``) whose
cluster no track took and that is no piece of a track's object; it starts at the
candidate's centroid with the tentative track's velocity.  A piece is a candidate
within ``merge_m`` of the path a track sweeps over the frame's integration period
T = 2 (t − t_z), p ± v T, with the track within ``merge_m`` of the candidate's own
path too (``one_object``): a drone at 15 m/s leaves its returns of a 0.1 s frame
along 1.5 m, and the clustering may cut them in two, while a second object beside it
or crossing it lies off the path.  Of a still track the path is a point, and the
test is the distance ``merge_m`` (see below).

A track **dies** once it has been missed for ``coast_s``: in the sensor's field of view
without an update since its last one (without a field of view given, all the time
since), or ``unseen_s`` after its last update wherever it was: a drone the turret has
turned away from lives on, to be looked at again (``control.choose``).  A track no
cluster has updated since its birth dies once missed for ``probation_s``
(``track.probation``: in a run 15 frames, 1.5 s at 10 Hz, the misses in a row that a
real object confirmed on 2 returns of 4 frames gives with probability ≤ 0.01).  The
sensor's own false returns now and then pass the detect stage's M-of-N by chance
(``outdoor-two-drones`` seed 16: single-point clusters 3-20 m out), and the tracks
born on them would otherwise live ``coast_s`` in view as unknown objects, possible
drones to a C2.  It also dies
when it has followed another track's object: two tracks that have stayed one object's
by their places for ``merge_s`` are one (``track.same_object``).
Identities are consecutive integers from 1, never reused in a run.

**At the cap** (``max_tracks``) the tracks the classes hold no drone end first (see
``_births``).  Their objects are still there, so such a track *rests* for ``coast_s``
(``track.rest``): a birth within ``merge_m`` of its last fix is its heir, a new
identity to which the classes give the resting track's life (``heirs``), so a
structure's fragment reborn after its track was classed static is static at once.

**The lock carries an identity.**  The turret's tracker follows one object with its
own filter (``note_lock``: after each frame its estimate and the track it holds, or,
while it stays locked, the one it held last).
When the held track misses a frame's cluster and a track would be born within
``SAME_TARGET_M`` (2 m) of the lock's estimate predicted to the frame, the held track
takes that cluster instead: it restarts there, as a birth would, but keeps its
identity and its life (a hover seen earlier says it is a drone).  A Kalman track on a
drone 60 m out with few returns can lose it for a frame while the particle filter
holds it (``outdoor-clutter`` seed 0: a new identity each time, classed bird, as a
drone flying fast that never hovered).

Why global nearest neighbour and not JPDA: the candidates of one frame lie metres
apart at the ranges we track (a drone's returns form one cluster within ε = 1 m), so
a gate rarely holds two clusters; where it does (two drones crossing), the assignment
keeps each on the cluster its prediction points at.  JPDA's blending would pull both
estimates to the midpoint of the two clusters at the crossing.  The figures measured
on the two-drone scenarios are in docs/results.md (Several objects).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from dronetrack.detect.lock import SAME_TARGET_M
from dronetrack.geometry.transforms import FloatArray
from dronetrack.track.cv_bank import (
    INFEASIBLE,
    Floor,
    associate,
    cv_predict,
    cv_update,
    gate_costs,
    ground_bound,
    measurement_noise,
    on_or_above,
)
from dronetrack.track.rest import Resting, keep_at_cap, match_rested
from dronetrack.track.same_object import PairClocks, one_object
from dronetrack.track.track_settings import TrackSettings
from dronetrack.types import Candidates, Detections, TrackEstimate, Tracks

LockNote = tuple[int, FloatArray, FloatArray, float]  # held id, estimate p, v, its time
InView = Callable[[FloatArray], NDArray[np.bool_]]  # positions (K, 3) → seen this frame

__all__ = [
    "Floor",
    "InView",
    "MultiTargetTracker",
    "TrackSettings",
]


_NO_HEIRS = (np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64))


def _cluster_of(candidates: Candidates, found: Detections) -> NDArray[np.intp]:
    """The index of the cluster each confirmed candidate is (its centroid this frame),
    −1 for none: as the detect stage recorded it, else found by its position."""
    if len(candidates) == 0 or len(found) == 0:
        return np.full(len(candidates), -1, dtype=np.intp)
    if np.all(candidates.clusters >= 0):
        return candidates.clusters.astype(np.intp)
    gap = np.linalg.norm(candidates.positions[:, None, :] - found.centroids[None, :, :], axis=2)
    nearest = np.argmin(gap, axis=1)
    return np.where(gap[np.arange(len(candidates)), nearest] <= 1e-9, nearest, -1)


class MultiTargetTracker:
    """The tracks of every confirmed object (see the module docstring); ``step`` once per
    tracking frame with its clusters and confirmed candidates."""

    def __init__(self, settings: TrackSettings | None = None) -> None:
        self.settings = settings if settings is not None else TrackSettings()
        self._gate = self.settings.gate
        self._next_id = 1
        self._lock: LockNote | None = None
        self._unlikely: NDArray[np.int64] = np.empty(0, dtype=np.int64)
        self.reset()

    def reset(self) -> None:
        """Forget every track (identities go on counting)."""
        self.ids = np.empty(0, dtype=np.int64)
        self.x = np.empty((0, 6))  # state [p, v] at time t [m, m/s]
        self.P = np.empty((0, 6, 6))
        self.t = np.empty(0)  # time of the state [s]
        self.born = np.empty(0)  # birth time [s]
        self.t_update = np.empty(0)  # time of the last update [s]
        self.p_update = np.empty((0, 3))  # position after the last update [m]
        self.updates = np.empty(0, dtype=np.int64)  # updates over its life
        self.updated = np.empty(0, dtype=bool)  # updated in the last step
        self.cluster = np.empty(0, dtype=np.intp)  # cluster index of that update (-1: none)
        self.hovered = np.empty(0, dtype=bool)  # a candidate of it hovered (detect.tentative)
        self.away = np.empty(0)  # time out of view since the last update [s]
        self.looked = np.empty(0, dtype=bool)  # in the sensor's view at the last step
        self._t_step: float | None = None  # the clusters' time of the last step [s]
        self._pairs = PairClocks()
        self._lock = None
        self._rest = Resting()
        self._heirs = _NO_HEIRS

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def resting(self) -> NDArray[np.int64]:
        """The identities at rest (``track.rest``): ended for room, an heir may take
        their lives."""
        return self._rest.ids.copy()

    @property
    def heirs(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """(new identities, the identities at rest whose lives they take) of the last
        step's births (``track.rest``)."""
        return self._heirs[0].copy(), self._heirs[1].copy()

    def step(
        self,
        t: float,
        found: Detections,
        confirmed: Candidates,
        t_meas: float | None = None,
        in_view: InView | None = None,
        floor: Floor | None = None,
    ) -> Tracks:
        """Predict every track to the clusters' time ``t_meas`` (default ``t``), update it
        with the cluster assigned to it, start tracks on the confirmed candidates no track
        explains, end those missed for ``coast_s`` (never updated since their birth:
        ``probation_s``) or unseen for ``unseen_s``, and predict
        them all to ``t``; the tracks after the step.  ``in_view`` tells which positions
        (K, 3) the sensor saw this frame (None: all); ``floor`` the ground's height under
        points (K, 2), which every predicted state is kept on or above (``on_or_above``;
        None: no bound).

        A LiDAR frame's returns span its integration period, so its clusters' centroids
        describe its middle (a rosette crosses its dense centre many times a frame), not
        its end: at 15 m/s the half-period of 0.05 s is 0.75 m.
        """
        s = self.settings
        t_z = t if t_meas is None else min(t_meas, t)
        self._heirs = _NO_HEIRS
        self._predict(t_z, floor)
        R = measurement_noise(found, s.sigma_meas)
        reach = s.v_max * np.maximum(t_z - self.t_update, 0.0) + s.gate_m
        cost = gate_costs(self.x, self.P, self.p_update, reach, found.centroids, R, self._gate)
        # a track unseen for longer than stale_s takes a confirmed candidate's cluster only
        stale = t_z - self.t_update > s.stale_s
        of = _cluster_of(confirmed, found)  # each candidate's cluster
        confirmed_cluster = np.zeros(len(found), dtype=bool)
        confirmed_cluster[of[of >= 0]] = True
        gap = np.linalg.norm(self.x[:, None, :3] - found.centroids[None, :, :], axis=2)
        near = gap <= s.stale_gate_m
        cost[stale[:, None] & ~confirmed_cluster[None, :] & ~near] = INFEASIBLE
        if s.unseen_s is not None and s.unseen_s > s.coast_s:
            # a track that lived on out of view (unseen for longer than coast_s) takes a
            # cluster only within |z − p̂| ≤ stale_gate_m + σ_v,birth (t − t_update) of
            # its prediction: its covariance and its speed gate have grown to take anything
            since = t_z - self.t_update
            wide = s.stale_gate_m + s.birth_sigma_v * since
            cost[(since > s.coast_s)[:, None] & (gap > wide[:, None])] = INFEASIBLE
        rows, cols = associate(cost)
        if len(rows):
            self.x[rows], self.P[rows] = cv_update(
                self.x[rows], self.P[rows], found.centroids[cols], R[cols]
            )
        self.updated = np.zeros(len(self), dtype=bool)
        self.updated[rows] = True
        self.cluster = np.full(len(self), -1, dtype=np.intp)
        self.cluster[rows] = cols
        self.t_update[rows] = t_z
        self.p_update[rows] = self.x[rows, :3]
        self.updates[rows] += 1
        self._note_hover(confirmed, of)
        # missed = (t − t_update) − away, away += Δt where out of view, 0 where updated
        # in view: where the field of view at the frame's end holds it, or seen this frame
        # (a cluster of the frame updated it: the turret may have slewed it out of the
        # field since its returns came in)
        self.looked = np.ones(len(self), dtype=bool) if in_view is None else in_view(self.x[:, :3])
        self.looked |= self.updated
        if self._t_step is not None:
            self.away += max(t_z - self._t_step, 0.0) * ~self.looked
        self._t_step = t_z
        self.away[self.updated] = 0.0
        unseen = s.coast_s if s.unseen_s is None else s.unseen_s
        missed = self._missed_now()
        # a track no cluster has updated since its birth lives probation_s missed
        probation = s.coast_s if s.probation_s is None else min(s.probation_s, s.coast_s)
        coast = np.where(self.updates <= 1, probation, s.coast_s)
        self._drop((missed <= coast) & (t_z - self.t_update <= unseen))
        merge = (s.merge_m, s.share_m, s.merge_s)
        self._drop(
            ~self._pairs.ending(t_z, self.ids, self.x[:, :3], self.updated, self.updates, merge)
        )
        taken = np.zeros(len(found), dtype=bool)
        taken[cols] = True
        self._rest.expire(t_z, s.coast_s)
        # the frame spans T = 2 (t − t_z): its clusters describe its middle
        self._births(t_z, confirmed, found, of, taken, R, period=2.0 * (t - t_z))
        self._predict(t, floor)
        return self.snapshot()

    def note_lock(self, tracks: Tracks, estimate: TrackEstimate) -> None:
        """The turret's tracker after a frame: the track it holds (``tracks.locked``, none
        when the estimate is not locked; while it stays locked, the track it held last)
        and its estimate."""
        held = np.flatnonzero(tracks.locked)
        last = self._lock
        self._lock = None
        if not estimate.tracked:
            return
        p, v = np.asarray(estimate.position).copy(), np.asarray(estimate.velocity).copy()
        if len(held):
            self._lock = (int(tracks.ids[held[0]]), p, v, float(estimate.t))
        elif last is not None and np.any(self.ids == last[0]):
            # still locked, the track it held left behind: the lock keeps its identity
            self._lock = (last[0], p, v, float(estimate.t))

    def note_unlikely(self, ids: NDArray[np.int64]) -> None:
        """The tracks the classes hold no drone after a frame (classed static, or with
        evidence against a drone): at the cap they die first."""
        self._unlikely = np.asarray(ids, dtype=np.int64).copy()

    def _hand_over(
        self, t: float, c: Candidates, clusters: NDArray[np.intp], R: FloatArray
    ) -> NDArray[np.bool_]:
        """(B,) which of the births ``c`` (their clusters ``clusters``, measurement noises
        ``R``) the held track takes (see the module docstring): at most one, the nearest
        to the lock's estimate predicted to ``t``, p_L = p + v (t − t_L), within
        SAME_TARGET_M, if the held track missed this frame.  It restarts there as a
        birth would, keeping its identity, its age, its updates and its hover."""
        taken = np.zeros(len(c), dtype=bool)
        if self._lock is None or len(c) == 0:
            return taken
        ident, p, v, t_lock = self._lock
        row = np.flatnonzero(self.ids == ident)
        if len(row) == 0 or self.updated[row[0]]:
            return taken
        gap = np.linalg.norm(c.positions - (p + v * max(t - t_lock, 0.0)), axis=1)
        i = int(np.argmin(gap))
        if gap[i] > SAME_TARGET_M:
            return taken
        k = int(row[0])
        self.x[k] = np.concatenate([c.positions[i], c.velocities[i]])
        self.P[k] = 0.0
        self.P[k, :3, :3] = R[i]
        self.P[k, 3:, 3:] = self.settings.birth_sigma_v**2 * np.eye(3)
        self.t[k] = self.t_update[k] = t
        self.p_update[k] = c.positions[i]
        self.updates[k] += 1
        self.updated[k] = True
        self.cluster[k] = clusters[i]
        self.hovered[k] |= bool(c.hovered[i])
        self.away[k] = 0.0
        taken[i] = True
        return taken

    def _predict(self, t: float, floor: Floor | None = None) -> None:
        """Every track's state at ``t`` (none goes back in time), on or above the
        ``floor``'s ground (``on_or_above``; None: no bound)."""
        dt = np.maximum(t - self.t, 0.0)
        self.x, self.P = cv_predict(self.x, self.P, dt, self.settings.sigma_acc)
        self.t = np.maximum(self.t, t)
        if floor is not None and len(self):
            self.x = on_or_above(self.x, ground_bound(self.x, self.p_update, floor))

    def _note_hover(self, confirmed: Candidates, of: NDArray[np.intp]) -> None:
        """A track whose cluster is a candidate that hovered has hovered (one-way);
        ``of``: each candidate's cluster."""
        if len(confirmed) == 0 or len(self) == 0:
            return
        hovered_clusters = set(of[confirmed.hovered & (of >= 0)].tolist())
        for k in np.flatnonzero(self.updated):
            if int(self.cluster[k]) in hovered_clusters:
                self.hovered[k] = True

    def _births(
        self,
        t: float,
        confirmed: Candidates,
        found: Detections,
        of: NDArray[np.intp],
        taken: NDArray[np.bool_],
        R_all: FloatArray,
        period: float,
    ) -> None:
        """Start tracks on the confirmed candidates whose clusters (``of``) no track took
        (``taken``) and that are no piece of a track's object (a piece lies within
        ``merge_m`` of the path a track sweeps over the frame's ``period`` [s], and the
        track within ``merge_m`` of the piece's: ``one_object``); but the one the lock's
        track takes (``_hand_over``).  ``R_all`` is every cluster's measurement noise; a
        candidate with a non-finite state is never born."""
        s = self.settings
        new = np.flatnonzero((of >= 0) & ~taken[np.maximum(of, 0)])
        # each one's cluster's centroid and velocity, as the piece test takes them
        pieces = np.concatenate([found.centroids[of[new]], confirmed.velocities[new]], axis=1)
        finite = np.isfinite(pieces).all(axis=1) & np.isfinite(confirmed.positions[new]).all(axis=1)
        new, pieces = new[finite], pieces[finite]
        if len(new) and len(self):
            # (B, K): birth b a piece of track k's object
            piece = one_object(pieces[:, None, :], self.x[None, :, :], period, s.merge_m)
            new = new[~piece.any(axis=1)]
        if len(new) == 0:
            return
        c, R = confirmed.take(new), R_all[of[new]]
        born = np.flatnonzero(~self._hand_over(t, c, of[new], R))
        new, R, c = new[born], R[born], c.take(born)
        if len(new) == 0:
            return
        k = len(new)
        x = np.concatenate([c.positions, c.velocities], axis=1)
        P = np.zeros((k, 6, 6))
        P[:, :3, :3] = R
        P[:, 3:, 3:] = s.birth_sigma_v**2 * np.eye(3)
        ids = self._next_id + np.arange(k, dtype=np.int64)
        self._next_id += k
        # a birth on the object of a track at rest is its heir (``track.rest``)
        back, rested = match_rested(c.positions, self._rest.p_update, s.merge_m)
        self._heirs = (ids[back], self._rest.ids[rested])
        gone = np.ones(len(self._rest), dtype=bool)
        gone[rested] = False
        self._rest.keep(gone)
        self.ids = np.concatenate([self.ids, ids])
        self.x = np.concatenate([self.x, x])
        self.P = np.concatenate([self.P, P])
        self.t = np.concatenate([self.t, np.full(k, t)])
        self.born = np.concatenate([self.born, np.full(k, t)])
        self.t_update = np.concatenate([self.t_update, np.full(k, t)])
        self.p_update = np.concatenate([self.p_update, c.positions])
        self.updates = np.concatenate([self.updates, np.ones(k, dtype=np.int64)])
        self.updated = np.concatenate([self.updated, np.ones(k, dtype=bool)])
        self.cluster = np.concatenate([self.cluster, of[new]])
        self.hovered = np.concatenate([self.hovered, c.hovered])
        self.away = np.concatenate([self.away, np.zeros(k)])
        self.looked = np.concatenate([self.looked, np.ones(k, dtype=bool)])
        excess = len(self) - s.max_tracks
        if excess > 0:  # at the cap: those the classes hold no drone die first
            unlikely = np.isin(self.ids, self._unlikely)
            held = self.ids == (self._lock[0] if self._lock is not None else -1)
            keep = keep_at_cap(self.ids, self.updates, self.t_update, unlikely, held, s.max_tracks)
            # their objects are still there: those held no drone rest (``track.rest``)
            rest = ~keep & unlikely
            self._rest.add(t, self.ids[rest], self.p_update[rest])
            self._drop(keep)

    def _missed_now(self) -> FloatArray:
        """(K,) each track's time in view without an update, to the last step's clusters."""
        t_z = self._t_step if self._t_step is not None else self.t
        return np.asarray(t_z - self.t_update - self.away, dtype=np.float64)

    def _drop(self, keep: NDArray[np.bool_]) -> None:
        if keep.all():
            return
        for name in (
            "ids",
            "x",
            "P",
            "t",
            "born",
            "t_update",
            "p_update",
            "updates",
            "updated",
            "cluster",
            "hovered",
            "away",
            "looked",
        ):
            setattr(self, name, getattr(self, name)[keep])

    def snapshot(self, estimate: TrackEstimate | None = None) -> Tracks:
        """The tracks as they stand, the one nearest a locked ``estimate`` of the turret's
        tracker (within ``detect.lock``'s SAME_TARGET_M) marked locked."""
        k = len(self)
        tracks = Tracks(
            ids=self.ids.copy(),
            positions=self.x[:, :3].copy(),
            velocities=self.x[:, 3:].copy(),
            covariances=self.P.copy(),
            born=self.born.copy(),
            updated=self.updated.copy(),
            hovered=self.hovered.copy(),
            locked=np.zeros(k, dtype=bool),
            clusters=np.where(self.updated, self.cluster, -1),
            last_seen=self.t_update.copy(),
            missed_s=np.maximum(self._missed_now(), 0.0),
            in_view=self.looked.copy(),
        )
        return tracks if estimate is None else tracks.with_locked(estimate, SAME_TARGET_M)
