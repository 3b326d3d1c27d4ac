"""Which target the single-target tracker follows among the frame's objects.

The tracker follows one target; the track layer follows every object and classes it
(``track.multi``, ``classify``).  Each frame, with the lock's history
(``detect.lock``) and the chooser's turns (``control.choose``):

1. a lock on a track classed static, or out of the open air, for ``STATIC_HOLD_S`` is
   given up;
2. with the chooser on, it names the track to serve: while it serves one, the tracker
   takes only that track's candidates, and when it is not the one held the tracker
   lets go and the turret looks where the track is predicted (``look``) until it has;
3. while locked on what never hovered, the tracker restarts on a candidate that did
   (``LockBook.switch``);
4. otherwise, while locked on what no drone-class track follows, it restarts on the
   most threatening candidate whose track is classed drone
   (``control.choose.drone_instead``), unless the chooser is turning the turret to a
   track (``look``);
5. otherwise, while not locked, it starts on the candidates within the lost target's
   reach, the likeliest drones first (``LockBook.reachable``).

Rule 5 holds for a drone-class track too.  Rule 4 applied while not locked (a
drone-class track taken at once, wherever it is) was measured on ``outdoor-unscanned``
(seeds 0-9), where fragments of unmapped structures are classed drone for seconds
before they are classed static: the turret went to them instead of the drone it had
lost (seed 2: lock-on while visible 89.1 → 69.9 %), and gained 0.8 s on the one seed
where it found the drone sooner.
"""

from __future__ import annotations

import logging
from typing import Protocol

import numpy as np

from dronetrack.control.choose import (
    DRONE,
    ChooseSettings,
    TargetChooser,
    candidate_tracks,
    drone_instead,
    held_track,
    servable,
)
from dronetrack.detect.lock import SAME_TARGET_M, LockBook
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Candidates, Detections, Tracks

__all__ = ["STATIC_HOLD_S", "Restartable", "TargetSelection", "held", "rank"]

log = logging.getLogger(__name__)
# A lock on a track classed static this long [s] is given up: the turret holds a static
# object at most this long after its class, within the second the issue allows.
STATIC_HOLD_S = 0.5


class Restartable(Protocol):
    """A tracker the selection restarts (``track.base.Tracker`` and ``CandidateStart``)."""

    def reset(self) -> None: ...
    def acquire(self, candidates: Candidates) -> None: ...


def held(tracks: Tracks, lock: LockBook, within: float) -> int:
    """The index of the track the lock holds, the nearest its estimate within ``within``
    [m] (``control.choose.held_track``); −1 when nothing is locked or none is that near."""
    if not lock.locked or lock.estimate is None:
        return -1
    return held_track(tracks, lock.estimate.position, within)


def rank(
    candidates: Candidates, found: Detections | None, tracks: Tracks | None
) -> FloatArray | None:
    """Each candidate's track's p_drone (0.5 without one): the turret starts on the
    likeliest drone, not on whatever the clustering listed first (None: no tracks)."""
    if found is None or tracks is None or len(candidates) == 0:
        return None
    owner = candidate_tracks(candidates, found, tracks)
    out = np.full(len(candidates), 0.5)
    out[owner >= 0] = tracks.p_drone[owner[owner >= 0]]
    return out


class TargetSelection:
    """The rules of the module docstring, with the chooser's state (None: no chooser)."""

    def __init__(self, chooser: TargetChooser | None = None) -> None:
        self.chooser = chooser
        self.look: Candidates | None = None  # where the served track is, out of view
        self._static_since: tuple[int, float] | None = None  # (held track, since when)

    @property
    def settings(self) -> ChooseSettings:
        return self.chooser.settings if self.chooser is not None else ChooseSettings()

    def step(
        self,
        t: float,
        found: Detections,
        tracks: Tracks | None,
        offered: Candidates,
        lock: LockBook,
        tracker: Restartable,
    ) -> Candidates:
        """Apply the rules to the frame ending at ``t``, restarting ``tracker`` as they
        say; the candidates it may take (``offered``, those of a served track)."""
        if self._held_static(t, tracks, lock):
            log.info("frame ending %.3f s: the locked target is no drone's; lock given up", t)
            tracker.reset()
            lock.reset()
        offered = self._serve(t, found, tracks, offered, lock, tracker)
        other = lock.switch(offered)
        if other is not None:
            log.info("frame ending %.3f s: lock moved to a target that hovered", t)
            tracker.reset()
            lock.reset()
            tracker.acquire(other)
            return offered
        if not lock.locked:
            start = lock.reachable(t, offered, rank(offered, found, tracks))
            if start is not None and len(start) > 0:
                tracker.acquire(start)
            return offered
        drone = self.drone_instead(found, tracks, offered, lock) if self.look is None else None
        if drone is not None:
            log.info("frame ending %.3f s: lock moved to a drone's track", t)
            tracker.reset()
            lock.reset()
            tracker.acquire(drone)
        return offered

    def drone_instead(
        self, found: Detections, tracks: Tracks | None, offered: Candidates, lock: LockBook
    ) -> Candidates | None:
        """While locked on what no drone-class track follows, an offered candidate whose
        track is classed drone and more threatening (``control.choose.drone_instead``);
        else None."""
        if tracks is None or not lock.locked or lock.estimate is None:
            return None
        drones = tracks.classes == DRONE
        if not drones.any() or len(offered) == 0:
            return None  # the common case, decided without the geometry below
        settings = self.settings
        # the filter's estimate lags a fast drone by metres: within apart_m is the same
        k = held(tracks, lock, settings.apart_m)
        if k >= 0 and drones[k]:
            return None
        away = np.linalg.norm(offered.positions - lock.estimate.position, axis=1) > settings.apart_m
        owner = candidate_tracks(offered, found, tracks)
        pick = drone_instead(np.where(away, owner, -1), tracks, k, settings)
        return offered.take(np.array([pick])) if pick >= 0 else None

    def _serve(
        self,
        t: float,
        found: Detections,
        tracks: Tracks | None,
        offered: Candidates,
        lock: LockBook,
        tracker: Restartable,
    ) -> Candidates:
        """The candidates the tracker may take after the chooser's turn: with two tracks
        or more worth the turret, the one to serve; when it is not the one held, the
        tracker lets go, takes the served track's candidate if it has one this frame,
        and the turret looks where the track is predicted (``look``) until it has."""
        self.look = None
        if self.chooser is None or tracks is None:
            return offered
        apart = self.chooser.settings.apart_m
        h = held(tracks, lock, apart)
        held_id = int(tracks.ids[h]) if h >= 0 else None
        served = self.chooser.choose(t, tracks, held_id)
        if served is None:
            return offered
        k = int(np.flatnonzero(tracks.ids == served)[0])
        mine = offered.take(np.flatnonzero(candidate_tracks(offered, found, tracks) == k))
        if served == held_id:
            return mine  # no other (not one that hovered: ``detect.lock``) while it serves
        if (
            lock.locked
            and lock.estimate is not None
            and np.linalg.norm(tracks.positions[k] - lock.estimate.position) <= apart
        ):
            return mine  # the served track is where the tracker already is
        if lock.locked:
            log.info("frame ending %.3f s: the turret turns to track %d", t, served)
            tracker.reset()
            lock.reset()
        if len(mine) == 0:
            self.look = Candidates(
                tracks.positions[k : k + 1],
                tracks.velocities[k : k + 1],
                np.ones(1, dtype=np.int64),
                np.zeros(1),
                tracks.ids[k : k + 1],
            )
        return mine

    def _held_static(self, t: float, tracks: Tracks | None, lock: LockBook) -> bool:
        """Whether the locked target's track has been classed static, or out of the open
        air (``control.choose.servable``), for ``STATIC_HOLD_S`` (a track may be classed
        static for a frame or two as it lifts off or stops)."""
        k = -1 if tracks is None else held(tracks, lock, SAME_TARGET_M)
        if k < 0 or tracks is None or servable(tracks)[k]:
            self._static_since = None
            return False
        ident = int(tracks.ids[k])
        if self._static_since is None or self._static_since[0] != ident:
            self._static_since = (ident, t)
        return t - self._static_since[1] >= STATIC_HOLD_S - 1e-9
