"""Which target the single-target tracker follows among the frame's objects.

The tracker follows one target; the track layer follows every object and classes it
(``track.multi``, ``classify``).  Each frame, with the lock's history
(``detect.lock``) and the chooser's turns (``control.choose``):

1. a lock on a track classed static, or out of the open air, or on a cluster too
   large for a candidate where no track is, for a net ``STATIC_HOLD_S`` (the time so,
   less the time not: ``barred_time``) is given up;
2. with the chooser on, it names the track to serve: while it serves one, the tracker
   takes only that track's candidates, and when it is not the one held the tracker
   lets go and the turret looks where the track is predicted (``look``) until it has;
3. while locked on what never hovered, the tracker restarts on a candidate that did
   (``LockBook.switch``) whose track is worth a look (``control.choose.worth_a_look``):
   the world holds still too, and the classes say which still object is no drone.
   Restarted on any that hovered, the lock went, now and then, from the drone's own
   track to a structure's fragment classed static or counted out (``outdoor-unscanned``
   seed 3: three times in 2.4 s, the estimate sent 110 m off each time);
4. otherwise, while locked on what no drone-class track follows, it restarts on the
   most threatening candidate whose track is classed drone
   (``control.choose.drone_instead``), and while locked on a track that is no drone's
   (``no_drone``: it held still with the world's evidence), on the most threatening
   whose track is worth a look and no such track (``control.choose.more_threatening``),
   unless the chooser is turning the turret to a track (``look``).  Without the
   second, a lock on a still fragment of an unmapped structure (p_drone 0.00) held
   while the drone's own track, unknown, flew in beside it (``outdoor-unscanned``,
   seeds 0-9: the drone acquired 0.85 s after it came into view within reach, 0.52 s
   with it; seeds 10-29: 1.18 and 1.12 s), every other figure of the ``multi`` suite
   within its spread;
5. otherwise, while not locked, it starts on the candidates within the lost target's
   reach, the most threatening first (``rank``, ``LockBook.reachable``), and of those
   on one track's for a while (``StartTrial``): the trial's track is tried for
   ``look_s`` (1.5 s) before the next, and the turret aims at it, where it is
   predicted while it has no candidate.  Restarted each frame on whichever candidate
   ranked first, the tracker settled on none among the fragments of an unmapped tree
   line (``outdoor-unscanned``, seeds 0-9: the drone acquired 4.6 s after it came
   into view, 2.6 s with the trials).  When a trial fails the tracker is reset, so the
   next one's candidate takes the whole cloud (``birth_share`` keeps half of it where
   it was: on the failed trial's object, which goes on returning points), and so it
   is when the next trial is on the same track (a drone-class track is tried again at
   once), whose filter drifted without a lock; a first trial after a loss keeps the
   cloud, which may wait where the lost drone reappears
   (with the reset there too, ``outdoor-clutter``'s lock-on while visible fell from
   98.4 to 95.2 %), unless the cloud waits on what is no drone: the lock held, in its
   last frame, what rule 1 bars (a track classed static or out of the open air, an
   oversized cluster) or a track that held still and is not worth a look
   (``no_drone``), or, as the trial begins, the tracker's estimate lies on such
   a track.  No drone reappears there.  A fragment of an unmapped structure classed
   static was lost just before rule 1 gave it up, and the cloud left on it dragged
   the trial's estimate 85 m across to the drone over 0.6 s (``outdoor-unscanned``
   seed 5: the drone acquired 1.9 s after it came into view within reach, 1.2 s with
   the reset).  A steady flight's evidence against a drone, which a drone may show
   too, resets nothing: with it, ``default``'s IDF1 went from 0.862 to 0.848.

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
from numpy.typing import NDArray

from dronetrack.control.choose import (
    DRONE,
    ChooseSettings,
    TargetChooser,
    candidate_tracks,
    held_track,
    more_threatening,
    servable,
    threat,
    worth_a_look,
)
from dronetrack.detect.candidates import engulfed
from dronetrack.detect.lock import SAME_TARGET_M, LockBook
from dronetrack.geometry.transforms import FloatArray
from dronetrack.pipeline.trial import StartTrial
from dronetrack.types import Candidates, Detections, Tracks

__all__ = [
    "STATIC_HOLD_S",
    "Restartable",
    "TargetSelection",
    "barred_time",
    "held",
    "rank",
]

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
    candidates: Candidates,
    found: Detections | None,
    tracks: Tracks | None,
    settings: ChooseSettings,
) -> FloatArray | None:
    """Each candidate's threat (``control.choose.threat``: its track's p_drone, 0.5
    without one, times its closeness to the protected point and its closing speed): the
    turret starts on the likeliest drone nearest the site, not on whatever the
    clustering listed first (None: no tracks).  By p_drone alone, the fragments of an
    unmapped tree line 125-190 m out, fresh and unknown (0.5), ranked over the drone
    70 m out, whose steady flight had taken its p_drone just under 0.5, and the trials
    went to them first (``outdoor-unscanned``, seeds 0-9, with rules 3 and 5 as they
    are: the drone acquired 1.47 s after it came into view within reach, 0.85 s by
    threat)."""
    if found is None or tracks is None or len(candidates) == 0:
        return None
    owner = candidate_tracks(candidates, found, tracks)
    p = np.full(len(candidates), 0.5)
    p[owner >= 0] = tracks.p_drone[owner[owner >= 0]]
    protected = np.asarray(settings.protected, dtype=float)
    return threat(
        candidates.positions, candidates.velocities, p, protected, settings.d_ref, settings.v_ref
    )


class TargetSelection:
    """The rules of the module docstring, with the chooser's state (None: no chooser)."""

    def __init__(self, chooser: TargetChooser | None = None) -> None:
        self.chooser = chooser
        # the chooser's settings, or the defaults' (the threat's and ``min_p``) without one
        self.settings = chooser.settings if chooser is not None else ChooseSettings()
        self.look: Candidates | None = None  # where the served track is, out of view
        # what rule 5 started the tracker on, the trial's candidate first, or where the
        # trial's track is predicted while it has none: the turret aims there while not
        # locked (None: rule 5 did not run this frame)
        self.aim: Candidates | None = None
        self.trial = StartTrial(self.settings)
        # (the lock's net time barred [s], barred in the last frame, that frame's t)
        self._barred: tuple[float, bool, float] | None = None
        # whether the lock, in the last frame it was locked, held what rule 1 bars or a
        # track that held still and is not worth a look (``no_drone``)
        self._lost_on_no_drone = False

    def _let_go(self, tracker: Restartable, lock: LockBook) -> None:
        """Reset the tracker and the lock, and the lock's time barred with them."""
        tracker.reset()
        lock.reset()
        self._barred = None
        self._lost_on_no_drone = False

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
        if self._held_static(t, found, tracks, lock):
            log.info("frame ending %.3f s: the locked target is no drone's; lock given up", t)
            self._let_go(tracker, lock)
        offered = self._serve(t, found, tracks, offered, lock, tracker)
        other = self.hovered_instead(found, tracks, offered, lock)
        if other is not None:
            log.info("frame ending %.3f s: lock moved to a target that hovered", t)
            self._let_go(tracker, lock)
            tracker.acquire(other)
            return offered
        if not lock.locked:
            self._start(t, found, tracks, offered, lock, tracker)
            return offered
        self.trial.end(None)
        other = self.likelier_instead(found, tracks, offered, lock) if self.look is None else None
        if other is not None:
            log.info("frame ending %.3f s: lock moved to a likelier track (rule 4)", t)
            self._let_go(tracker, lock)
            tracker.acquire(other)
        return offered

    def _start(
        self,
        t: float,
        found: Detections,
        tracks: Tracks | None,
        offered: Candidates,
        lock: LockBook,
        tracker: Restartable,
    ) -> None:
        """Rule 5: start the tracker on the candidates within the lost target's reach,
        the trial's first (``StartTrial``), and aim at them (``aim``); while the trial's
        track has no candidate, start on none and aim where the track is predicted."""
        start = lock.reachable(t, offered, rank(offered, found, tracks, self.settings))
        if start is None:
            return
        if tracks is not None:
            before = (self.trial.ident, self.trial.since)
            owner = candidate_tracks(start, found, tracks)
            k = self.trial.step(t, tracks, owner)
            begun = (self.trial.ident, self.trial.since) != before
            moved = before[0] is not None and begun
            waits_on_no_drone = self._lost_on_no_drone or (
                begun and _on_no_drone(tracks, lock, self.settings.min_p)
            )
            if k >= 0 and (moved or waits_on_no_drone):
                # a trial that failed left part of the cloud on what was not the target;
                # so did one tried again on the same track (a drone-class track always
                # is): the filter drifted there; and a cloud left by a lock on no drone,
                # or lying on a track that is no drone's, waits where no drone
                # reappears: it starts afresh
                log.debug("frame ending %.3f s: trial moves to track %d", t, self.trial.ident)
                tracker.reset()
                self._lost_on_no_drone = False
            if k >= 0:
                mine = owner == k
                if not mine.any():
                    self.aim = _at_track(tracks, k)
                    return
                start = start.take(np.concatenate([np.flatnonzero(mine), np.flatnonzero(~mine)]))
        if len(start) > 0:
            tracker.acquire(start)
            self.aim = start

    def hovered_instead(
        self, found: Detections, tracks: Tracks | None, offered: Candidates, lock: LockBook
    ) -> Candidates | None:
        """Rule 3: while locked on what never hovered, the offered candidates elsewhere
        that did (``LockBook.switch``), of those whose track is worth a look
        (``control.choose.worth_a_look``); else None.  A candidate no track follows
        has no class to say it is no drone's, and is not taken."""
        other = lock.switch(offered)
        if other is None or tracks is None:
            return other
        owner = candidate_tracks(other, found, tracks)
        keep = owner >= 0
        keep[keep] = worth_a_look(tracks, self.settings.min_p)[owner[keep]]
        return other.take(np.flatnonzero(keep)) if keep.any() else None

    def likelier_instead(
        self, found: Detections, tracks: Tracks | None, offered: Candidates, lock: LockBook
    ) -> Candidates | None:
        """Rule 4: while locked on what no drone-class track follows, an offered
        candidate whose track is classed drone and more threatening
        (``control.choose.drone_instead``); while locked on a track that is no drone's
        (``no_drone``), one whose track is worth a look and no such track
        (``control.choose.more_threatening``); else None."""
        if tracks is None or not lock.locked or lock.estimate is None or len(offered) == 0:
            return None
        settings = self.settings
        drones = tracks.classes == DRONE
        # the filter's estimate lags a fast drone by metres: within apart_m is the same
        k = held(tracks, lock, settings.apart_m)
        unlikely = no_drone(tracks, settings.min_p)
        if k >= 0 and unlikely[k]:
            eligible = worth_a_look(tracks, settings.min_p) & ~unlikely
        elif drones.any() and not (k >= 0 and drones[k]):
            eligible = drones
        else:
            return None
        away = np.linalg.norm(offered.positions - lock.estimate.position, axis=1) > settings.apart_m
        owner = candidate_tracks(offered, found, tracks)
        pick = more_threatening(np.where(away, owner, -1), tracks, k, settings, eligible)
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
        self.aim = None  # set by rule 5 only
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
            self._let_go(tracker, lock)
        if len(mine) == 0:
            self.look = _at_track(tracks, k)
        return mine

    def _held_static(
        self, t: float, found: Detections, tracks: Tracks | None, lock: LockBook
    ) -> bool:
        """Whether the lock has held a track classed static, or out of the open air
        (``control.choose.servable``), for a net ``STATIC_HOLD_S``: the time barred less
        the time not (``barred_time``).  A drone may be classed static for a frame or
        two as it lifts off or stops; a fragment of a structure whose class flips
        between drone and static from frame to frame (its evidence near a feature's
        half-its-frames mark) is held static in most frames.  A lock that holds no
        track but lies on a cluster too large to be a candidate
        (``detect.candidates.engulfed``, within ``SAME_TARGET_M``) is barred too: the
        particle filter weighs every foreground point, and once the turret centred a
        structure whose track it held, the structure's whole shape returned, its
        cluster was dropped as too large and its track left, but the filter stayed on
        it (``outdoor-unscanned`` seed 9: a shed's corner 151 m out, held 1.2 s with
        the drone in view).

        The count is the lock's, whichever track it holds: on a structure the map
        lacks, the filter's estimate lies now on one fragment's track, now on another's
        2-4 m away, now on none, and a count restarted with each held track never
        reached the hold (``outdoor-unscanned`` seed 22: a lock on a structure's static
        fragments 105 m out for 2.9 s).  Nor does the count restart when the tracker
        loses its lock and takes it again on its own: there the filter, drifting over
        the structure, lost and retook it every four or five frames.  A frame on no
        track or without a lock counts as not barred; only letting go of the lock here
        (``_let_go``) restarts the count."""
        barred = unlikely = False
        if lock.locked and lock.estimate is not None:
            k = -1 if tracks is None else held(tracks, lock, SAME_TARGET_M)
            if k >= 0 and tracks is not None:
                barred = not bool(servable(tracks)[k])
                unlikely = bool(no_drone(tracks, self.settings.min_p)[k])
            else:
                position = lock.estimate.position[None, :]
                barred = bool(engulfed(found, position, SAME_TARGET_M)[0])
        if lock.locked:
            self._lost_on_no_drone = barred or unlikely
        net = 0.0
        if self._barred is not None:
            net, was, t_prev = self._barred
            net = barred_time(net, was, t - t_prev)
        self._barred = (net, barred, t)
        return barred and net >= STATIC_HOLD_S - 1e-9


def barred_time(net: float, barred: bool, dt: float) -> float:
    """The net time [s] a held track has been barred after ``dt`` [s] more in the
    state ``barred``: a leaky count, n ← max(0, n ± Δt), up while barred, down while
    not; a track barred from one frame on reaches t after t."""
    return max(0.0, net + (dt if barred else -dt))


def no_drone(tracks: Tracks, min_p: float) -> NDArray[np.bool_]:
    """(K,) the tracks that are no drone's: classed static or out of the open air
    (``control.choose.servable``), or held still and not worth a look
    (``control.choose.worth_a_look``).  A hover in free air is a drone's evidence
    (+4), so what holds a still track under ``min_p`` is the world's (grounded,
    joined, propped, crowded), not a steady flight's, which a drone may show too."""
    out: NDArray[np.bool_] = ~servable(tracks) | (tracks.hovered & ~worth_a_look(tracks, min_p))
    return out


def _on_no_drone(tracks: Tracks, lock: LockBook, min_p: float) -> bool:
    """Whether the tracker's estimate lies on a track that is no drone's
    (``no_drone``)."""
    if lock.estimate is None:
        return False
    k = held_track(tracks, lock.estimate.position, SAME_TARGET_M)
    return k >= 0 and bool(no_drone(tracks, min_p)[k])


def _at_track(tracks: Tracks, k: int) -> Candidates:
    """A candidate where track ``k`` is predicted: a look at it while it has none."""
    return Candidates(
        tracks.positions[k : k + 1],
        tracks.velocities[k : k + 1],
        np.ones(1, dtype=np.int64),
        np.zeros(1),
        tracks.ids[k : k + 1],
    )
