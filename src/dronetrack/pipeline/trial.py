"""While not locked, which track the single-target tracker is started on, held for a
while (``StartTrial``): rule 5 of ``pipeline.selection``."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dronetrack.control.choose import DRONE, ChooseSettings, worth_a_look
from dronetrack.types import Tracks

__all__ = ["TRIAL_MISSED_S", "StartTrial"]

# A trial gives way once its track has been missed (in the sensor's view, no cluster)
# this long [s]: three frames at 10 Hz, the detect stage's N − M + 1, after which its
# candidate cannot be confirmed again.  A single false return's track otherwise held
# the trial, and the turret's aim, for look_s while the drone's candidate came back
# elsewhere (``outdoor-escape`` seed 1: re-acquired 1.5 s after its return).
TRIAL_MISSED_S = 0.3


class StartTrial:
    """While not locked, the track the tracker is started on, held for a while.

    Among many candidates the ranking changes from frame to frame (a new fragment of a
    structure is unknown, 0.5, as long as a drone not told yet), and a tracker
    restarted on whichever comes first each frame never settles on any.  A trial holds
    one track's candidates first for ``look_s`` (or until the tracker locks); a track
    whose trial ended without a lock is tried again only after ``revisit_s``, unless
    every candidate has been.  A trial ends at once when its track ends, when the
    classes hold it no drone (``worth_a_look``), when it has been missed for
    ``TRIAL_MISSED_S``, or when another candidate's track is classed drone and its own
    is not.  That last trial was pre-empted, not tried: its track may be tried again
    at once.  Marked tried, the drone's own track (unknown, its p_drone a little under
    the even 0.5 as it flew without hovering) waited ``revisit_s`` behind the fresh
    fragments of unmapped structures, tried one a frame, after a fragment classed
    drone for a moment had pre-empted it (``outdoor-unscanned`` seed 3: acquired
    2.2 s after it came into view within reach, 1.7 s when not marked).
    """

    def __init__(self, settings: ChooseSettings) -> None:
        self.settings = settings
        self.ident: int | None = None  # the track tried
        self.since = 0.0  # since when [s]
        self.tried: dict[int, float] = {}  # track → when its trial ended without a lock

    def end(self, t: float | None) -> None:
        """The trial ends: at ``t`` without a lock (tried), or None: the tracker locked."""
        if self.ident is not None and t is not None:
            self.tried[self.ident] = t
        self.ident = None

    def step(self, t: float, tracks: Tracks, owner: NDArray[np.intp]) -> int:
        """The index of the track to try after the frame ending at ``t`` (−1: none), of
        the candidates' tracks ``owner`` (``candidate_tracks``, best candidate first)."""
        s = self.settings
        alive = set(tracks.ids.tolist())
        self.tried = {i: v for i, v in self.tried.items() if i in alive and t - v < s.revisit_s}
        k = self._current(t, tracks, owner)
        if k >= 0:
            return k
        fresh = [
            int(j)
            for j in owner
            if j >= 0 and (int(tracks.ids[j]) not in self.tried or tracks.classes[j] == DRONE)
        ]
        if fresh:
            k = fresh[0]
        elif (owner >= 0).any():  # every one tried: the longest ago first
            k = min((int(j) for j in owner if j >= 0), key=lambda j: self.tried[int(tracks.ids[j])])
        else:
            return -1
        self.ident, self.since = int(tracks.ids[k]), t
        return k

    def _current(self, t: float, tracks: Tracks, owner: NDArray[np.intp]) -> int:
        """The index of the trial's track while its trial goes on, else −1 (ending it)."""
        if self.ident is None:
            return -1
        at = np.flatnonzero(tracks.ids == self.ident)
        if len(at) == 0:
            self.ident = None
            return -1
        k = int(at[0])
        others = owner[(owner >= 0) & (owner != k)]
        drone = tracks.classes == DRONE
        outranked = not drone[k] and bool(drone[others].any())
        unlikely = not worth_a_look(tracks, self.settings.min_p)[k]
        gone = tracks.missed_s[k] > TRIAL_MISSED_S + 1e-9
        if outranked:  # pre-empted, not tried (``end`` would mark it tried)
            self.ident = None
            return -1
        if unlikely or gone or t - self.since >= self.settings.look_s - 1e-9:
            self.end(t)
            return -1
        return k
