"""Which objects the turret may serve: the confirmed candidates of tracks not classed
static, and whether the target held is a static one (``classify``).

A candidate of the detect stage (a confirmed tentative track) and a track of the track
layer (``track.multi``) meet in the frame's cluster: the candidate's position is its
cluster's centroid, and a track records the cluster that updated it.  A static-class
track (an object the background map lacks: a far building's edge, a parked car) is
never offered to the tracker, and a lock on one is given up as soon as its track is
classed static, so the turret never holds one for longer than a frame after that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TRACK_CLASSES, Candidates, Detections, Tracks

__all__ = [
    "DRONE",
    "STATIC",
    "ChooseSettings",
    "TargetChooser",
    "candidate_tracks",
    "drone_instead",
    "held_track",
    "more_threatening",
    "not_static",
    "servable",
    "threat",
    "track_threats",
]

STATIC = TRACK_CLASSES.index("static")
_SAME = 1e-9  # a candidate is its cluster's centroid, to the bit


def candidate_tracks(candidates: Candidates, found: Detections, tracks: Tracks) -> NDArray[np.intp]:
    """(K,) the index into ``tracks`` of the track each candidate's cluster updated, −1
    where none did."""
    out = np.full(len(candidates), -1, dtype=np.intp)
    if len(candidates) == 0 or len(found) == 0 or len(tracks) == 0:
        return out
    cluster = candidates.clusters.astype(np.intp)
    if np.any(cluster < 0):  # not recorded by the detect stage: found by position
        gap = np.linalg.norm(candidates.positions[:, None, :] - found.centroids[None, :, :], axis=2)
        nearest = np.argmin(gap, axis=1)
        exact = gap[np.arange(len(candidates)), nearest] <= _SAME
        cluster = np.where(exact, nearest, -1)
    # owner[j]: the track cluster j updated
    owner = np.full(len(found), -1, dtype=np.intp)
    took = tracks.clusters >= 0
    owner[tracks.clusters[took]] = np.flatnonzero(took)
    has = cluster >= 0
    out[has] = owner[cluster[has]]
    return out


def not_static(candidates: Candidates, found: Detections, tracks: Tracks) -> Candidates:
    """The candidates whose track is not classed static and is in the open air (not on
    the ground nor part of a structure by its evidence: ``Tracks.open_air``), in their
    order: a person walking or a car driving is no target for the turret."""
    owner = candidate_tracks(candidates, found, tracks)
    barred = np.zeros(len(candidates), dtype=bool)
    has = owner >= 0
    barred[has] = ~servable(tracks)[owner[has]]
    return candidates.take(np.flatnonzero(~barred))


def servable(tracks: Tracks) -> NDArray[np.bool_]:
    """(K,) the tracks the turret may serve: not classed static, in the open air."""
    out: NDArray[np.bool_] = (tracks.classes != STATIC) & tracks.open_air
    return out


def held_track(tracks: Tracks, position: FloatArray, within: float) -> int:
    """The index of the track nearest ``position`` within ``within`` [m], −1 if none."""
    if len(tracks) == 0:
        return -1
    gap = np.linalg.norm(tracks.positions - position, axis=1)
    k = int(np.argmin(gap))
    return k if gap[k] <= within else -1


# --- which track the turret serves -----------------------------------------------------


DRONE = TRACK_CLASSES.index("drone")


def worth_a_look(tracks: Tracks, min_p: float) -> NDArray[np.bool_]:
    """(K,) the tracks the turret shares itself among: those classed drone, and those
    it may serve (``servable``) with p_drone ≥ ``min_p``: with the default 0.2 a track
    the classes cannot tell yet (unknown, 0.5), not one with evidence against it (a
    steady flight watched for over 6 s, < 0.2; grounded, joined or propped, ≤ 0.05)."""
    maybe = servable(tracks) & (tracks.p_drone >= min_p)
    out: NDArray[np.bool_] = (tracks.classes == DRONE) | maybe
    return out


def threat(
    positions: FloatArray,
    velocities: FloatArray,
    p_drone: FloatArray,
    protected: FloatArray,
    d_ref: float,
    v_ref: float,
) -> FloatArray:
    """Each track's threat (K,): p_drone times its closeness to the protected point q and
    its closing speed,

        threat = p · d_ref / (d_ref + |p − q|) · (1 + max(0, −v · (p − q) / |p − q|) / v_ref)

    so a likely drone near q, flying at it, comes first."""
    rel = positions - protected
    d = np.linalg.norm(rel, axis=1)
    closing = -np.einsum("ij,ij->i", velocities, rel) / np.maximum(d, 1e-9)
    out: FloatArray = p_drone * d_ref / (d_ref + d) * (1.0 + np.maximum(closing, 0.0) / v_ref)
    return out


def track_threats(tracks: Tracks, settings: ChooseSettings) -> FloatArray:
    """Each track's ``threat`` (K,) with the settings' protected point and scales."""
    return threat(
        tracks.positions,
        tracks.velocities,
        tracks.p_drone,
        np.asarray(settings.protected),
        settings.d_ref,
        settings.v_ref,
    )


def drone_instead(
    owner: NDArray[np.intp],
    tracks: Tracks,
    held: int,
    settings: ChooseSettings,
) -> int:
    """While the target held is no drone's (its track ``held`` not classed drone, or
    −1: no track follows it), the candidate to turn to: of those whose track (``owner``,
    ``candidate_tracks``) is classed drone, the most threatening (``threat``), if it is
    ``hysteresis`` times as threatening as the held track (0 without one); −1 if none.

        pick = argmax_k threat_k over owner_k classed drone, owner_k ≠ held
        turn if threat_pick > hysteresis · threat_held
    """
    if held >= 0 and tracks.classes[held] == DRONE:
        return -1
    return more_threatening(owner, tracks, held, settings, tracks.classes == DRONE)


def more_threatening(
    owner: NDArray[np.intp],
    tracks: Tracks,
    held: int,
    settings: ChooseSettings,
    eligible: NDArray[np.bool_],
) -> int:
    """The candidate whose track (``owner``) is ``eligible`` (K,), not the ``held`` one,
    and the most threatening (``threat``), if it is ``hysteresis`` times as threatening
    as the held track (0 without one, ``held`` −1); −1 if none.

        pick = argmax_k threat_k over eligible owner_k ≠ held
        turn if threat_pick > hysteresis · threat_held
    """
    ok = owner >= 0
    ok[ok] = eligible[owner[ok]] & (owner[ok] != held)
    if not ok.any():
        return -1
    score = track_threats(tracks, settings)
    cand = np.flatnonzero(ok)
    best = int(cand[np.argmax(score[owner[cand]])])
    held_score = float(score[held]) if held >= 0 else 0.0
    return best if score[owner[best]] > settings.hysteresis * held_score else -1


@dataclass(frozen=True, slots=True)
class ChooseSettings:
    """How the turret shares itself among the tracks (SI units; see ``TargetChooser``).

    protected: the point the site protects [m]; d_ref, v_ref: the threat's scales;
    hysteresis: another track must be this much more threatening (1.5: 50 % more) to
    take the turret; hold_s: the least time a served track keeps it; revisit_s: the
    longest a candidate waits for the turret (a look at it starts look_s before);
    look_s: how long a look at a track out of view lasts before it is given up;
    fresh_s: a track missed for longer (in the sensor's view without an update:
    ``Tracks.missed_s``) is no candidate; apart_m:
    a track this close to the held one is a second track on the same drone, no
    candidate; min_p: the least p_drone of a candidate not classed drone
    (``worth_a_look``).
    """

    protected: tuple[float, float, float] = (0.0, 0.0, 0.0)
    d_ref: float = 100.0
    v_ref: float = 15.0
    hysteresis: float = 1.5
    hold_s: float = 1.0
    revisit_s: float = 10.0
    look_s: float = 1.5
    fresh_s: float = 1.0
    apart_m: float = 5.0
    min_p: float = 0.2

    def __post_init__(self) -> None:
        for name in ("d_ref", "v_ref", "revisit_s", "look_s", "fresh_s"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"choose: {name} must be positive, got {getattr(self, name)}")
        if not 0.0 <= self.min_p <= 1.0:
            raise ConfigError(f"choose: min_p must be in [0, 1], got {self.min_p}")
        if not self.hysteresis >= 1.0 or not self.hold_s >= 0.0:
            raise ConfigError(
                f"choose: need hysteresis ≥ 1 and hold_s ≥ 0, got {self.hysteresis}, {self.hold_s}"
            )


class TargetChooser:
    """The track the turret serves, once a frame (``choose``).

    The candidates are the tracks worth a look (``worth_a_look``: classed drone, or
    not told yet) missed for no longer than ``fresh_s`` (and the held track, whatever
    its class).  A track out of the sensor's view is not missed: the track layer keeps
    it while the turret serves another (``track.multi``), so that a drone far away in
    angle is looked at again where it is predicted.  The served track keeps the turret
    for ``hold_s`` at least; then it gives way to a candidate never served yet (so each
    new object gets a look at once), to a candidate not served for ``revisit_s`` less
    ``look_s`` (the most overdue first), so that two drones far apart in angle share
    the turret and a look that lands within ``look_s`` lands within ``revisit_s``, or to
    a candidate ``hysteresis`` times as threatening (``threat``).  A served track that the
    tracker does not hold after ``look_s`` (it was not found where it was predicted)
    gives way too and is not chosen again until it is seen anew.  Until then a greater
    threat does not cut the look short: it would end every look at a less likely drone
    before the turret got there.  While it looks, a new track born within the
    looked-for track's gate (d² ≤ χ²₃(0.99) on its position covariance, grown while it
    coasted) is taken for the object found and served at once.  With one candidate or
    none nothing is chosen: the single-target acquisition decides alone.

    On ``outdoor-two-drones`` and ``outdoor-swarm`` (seeds 0-9), revisits due at
    ``revisit_s`` and looks cut short by the threat after ``hold_s`` kept a drone
    waiting for the turret up to 12.4 and 10.8 s a run (the mean of the runs' longest
    wait): the look at the drone out of view started only when ``revisit_s`` was up,
    took a second to land, and a look at a drone whose steady flight had lowered its
    p_drone was given up after the hold, the turret back on the other.  With the three
    rules the longest waits are 10.0 and 9.5 s, and the identity switches 0.3 and 0.4
    a run (from 0.9 and 0.5).  More looks mean more entries into view, each a couple of
    frames before the detect stage confirms the drone anew: the share of the unwatched
    drone's visible frames its track matched fell from 91.4 to 89.3 % (two drones; the
    worst drone of each run) and from 95.5 to 95.2 % (swarm).
    """

    def __init__(self, settings: ChooseSettings | None = None) -> None:
        self.settings = settings if settings is not None else ChooseSettings()
        self.reset()

    def reset(self) -> None:
        self.served: int | None = None
        self.since = 0.0  # when the served track was chosen [s]
        self.held_at: dict[int, float] = {}  # when each track was last held [s]
        self.first_seen: dict[int, float] = {}
        self.given_up: dict[int, float] = {}  # track → its last_seen when a look failed
        self.looked: set[int] = set()  # the tracks served so far, held or not

    def choose(self, t: float, tracks: Tracks, locked: int | None) -> int | None:
        """The identity of the track to serve after the frame ending at ``t`` (None: let
        the single-target acquisition decide); ``locked`` is the identity of the track the
        tracker holds."""
        s = self.settings
        alive = set(tracks.ids.tolist())  # identities are never reused: forget the ended
        self.first_seen = {i: v for i, v in self.first_seen.items() if i in alive}
        self.held_at = {i: v for i, v in self.held_at.items() if i in alive}
        self.given_up = {i: v for i, v in self.given_up.items() if i in alive}
        self.looked &= alive
        for ident in alive:
            self.first_seen.setdefault(ident, t)
        if locked is not None:
            self.held_at[locked] = t
        ok = worth_a_look(tracks, s.min_p) & (tracks.missed_s <= s.fresh_s)
        held = self._position(tracks.ids, locked)
        if held is not None:  # a second track on the held drone is none of another
            ok &= np.linalg.norm(tracks.positions - tracks.positions[held], axis=1) > s.apart_m
            ok[held] = True
        for k in np.flatnonzero(ok):
            gave_up = self.given_up.get(int(tracks.ids[k]))
            if gave_up is not None and tracks.last_seen[k] <= gave_up:
                ok[k] = False
        idx = np.flatnonzero(ok)
        if len(idx) < 2:
            self.served = None
            return None
        score = track_threats(tracks, s)[idx]
        ids = tracks.ids[idx]
        current = self._position(ids, self.served)
        if current is None:  # start with the held track if it is a fair choice
            held = self._position(ids, locked)
            best = int(np.argmax(score))
            pick = held if held is not None and score[held] * s.hysteresis >= score[best] else best
            return self._serve(t, int(ids[pick]))
        looking = self.served != locked  # the turret looks for the served track
        new = [self._new(int(i)) for i in ids]
        if looking:  # a new track in the looked-for one's gate is it, found
            found = _found_in_gate(tracks, idx, current, new)
            if found >= 0:
                return self._serve(t, int(ids[found]))
        if t - self.since < s.hold_s:
            return self.served
        if looking and t - self.since >= s.look_s:  # not found: give way
            self.given_up[int(ids[current])] = float(tracks.last_seen[idx[current]])
            others = np.flatnonzero(ids != ids[current])
            return self._serve(t, int(ids[others[np.argmax(score[others])]]))
        # due: not served for revisit_s − look_s (a look then lands within revisit_s), or
        # never served at all (a first look is given once, so two tracks that cannot be
        # found do not take turns for good)
        waits = [
            (t - self.held_at.get(int(i), self.first_seen[int(i)]), n)
            for n, i in enumerate(ids)
            if i != self.served
        ]
        late = [(wait, n) for wait, n in waits if new[n] or wait >= s.revisit_s - s.look_s]
        if late:
            return self._serve(t, int(ids[max(late)[1]]))
        if looking:
            return self.served  # a look goes on for look_s: no threat cuts it short
        best = int(np.argmax(score))
        if score[best] > s.hysteresis * score[current]:
            return self._serve(t, int(ids[best]))
        return self.served

    @staticmethod
    def _position(ids: NDArray[np.int64], ident: int | None) -> int | None:
        if ident is None:
            return None
        at = np.flatnonzero(ids == ident)
        return int(at[0]) if len(at) else None

    def _new(self, ident: int) -> bool:
        """Whether the track has never been served nor held."""
        return ident not in self.looked and ident not in self.held_at

    def _serve(self, t: float, ident: int) -> int:
        if ident != self.served:
            self.served, self.since = ident, t
        self.looked.add(ident)
        return ident


# χ²(3) at 0.99: a position within the gate of a track's position covariance
GATE_D2 = 11.34


def _found_in_gate(tracks: Tracks, idx: NDArray[np.intp], looked: int, new: list[bool]) -> int:
    """Of the candidates ``idx`` (indices into ``tracks``), the position in ``idx`` of the
    new track (``new``) nearest the looked-for one ``looked`` (a position in ``idx``) by
    the Mahalanobis distance on its position covariance P, if within the gate; −1 if none.

        d² = (p_k − p̂)ᵀ P⁻¹ (p_k − p̂) ≤ χ²₃(0.99)"""
    k = idx[looked]
    others = [n for n in range(len(idx)) if new[n] and n != looked]
    if not others:
        return -1
    gap = tracks.positions[idx[others]] - tracks.positions[k]
    try:
        d2 = np.einsum("ij,ij->i", gap, np.linalg.solve(tracks.covariances[k, :3, :3], gap.T).T)
    except np.linalg.LinAlgError:  # a singular P: no spread to gate on
        return -1
    best = int(np.argmin(d2))
    return others[best] if d2[best] <= GATE_D2 else -1
