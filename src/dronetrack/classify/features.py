"""What a track's life says of it: each frame's observations of a track
(``classify.observe``), summed over its life into features that tell a drone from a
bird and from the static world.

Over a track's life its observations (``classify.observe``: grounded, joined,
crowded, cut, propped, beyond reach, its speed |v| and its clusters' centroids) give
its age, how long it was watched (the spacing of its updates, each counted up to
``SEEN_GAP_S``, so not the time it was out of view or missed), how far it ever moved
from its first position (d_max; an heir's from its own first,
``TrackLives._inherit``) and how far across (the same in the horizontal plane), the
shares of its observations grounded, joined, crowded, cut, propped or beyond reach,
its largest extent, *aloft*: the share of its recent observations not grounded (an
exponential average over about the last three, a ← (1 − α) a + α [not grounded], α =
``ALOFT_ALPHA``, from a = 1: off the ground until seen on it), so a drone that
lifted off is off the ground again within a few frames while a person stays on it,
and whether it *hovered*: |v| < v_hover for ``hover_frames`` updates in a row while
in the air (neither grounded nor cut), which no bird can (stall speed ≈ 5 m/s for
the smallest), or its candidate hovered (``detect.tentative``) and a cluster of it
that is neither grounded nor cut updated it; and whether it *hovered in free space*:
the same in observations that are neither joined, propped nor crowded either (the
world holds still too).  Given the share of frames the drone returns a point at each
track's range (``classify.return_share``), whether it returned *too often*: in more
of the frames it was in view after its first observation than the drone could.

Its *height spread* (``classify.spread``): the heights of its clusters against the
line through the two before each, summed as Q over its triples, and the height its
returns land over.

An observation made where the ground was not known yet (a far cell, early in a run
without a clean scan: ``preprocess.ground`` learns it from the returns) could not be
grounded.  It is kept aside, with the highest bottom z_lo among such, and judged by
the first later observation that knows the ground there, while the track's clusters
stayed within half a ground cell across (the same ground): grounded, and showing the
world, if max z_lo ≤ g + h_g, in the air otherwise (``site-busy`` seed 1: a
structure 146 m out, first seen 1.9 s into the run, grounded in each of its later
observations, waited for ``min_observed`` clusters for the one that knew no ground).

A frame in which its track was *engulfed* (no cluster updated it, but a cluster too
large to be a candidate holds its place, ``classify.observe``) is an observation too,
a joined one: its object showed as part of something larger than a drone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.classify.observe import Observations
from dronetrack.classify.return_share import more_often_than_drone
from dronetrack.classify.spread import (
    SPREAD_GAP_S,
    spread_deviation,
    spread_height,
    spread_scale,
)
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Tracks

__all__ = [
    "SEEN_GAP_S",
    "LifeFeatures",
    "TrackLives",
]

ALOFT_ALPHA = 0.3
SEEN_GAP_S = 0.3  # the longest gap between two updates that counts as watched (``seen_s``)


@dataclass(frozen=True, slots=True)
class LifeFeatures:
    """Each track's life so far (K,), in the order of the ``Tracks`` they were asked for."""

    age: FloatArray  # since its first observation [s]
    seen_s: FloatArray  # how long it was watched: its updates' spacing, each ≤ SEEN_GAP_S [s]
    observed: NDArray[np.int64]  # frames a cluster updated it or it was engulfed
    moved: FloatArray  # d_max: the farthest it has been from its first position [m]
    moved_xy: FloatArray  # the same across, in the horizontal plane [m]
    range_m: FloatArray  # the farthest it was seen from the sensor [m]
    grounded: FloatArray  # share of its observations grounded
    joined: FloatArray
    beyond_reach: FloatArray
    crowded: FloatArray
    cut: FloatArray
    propped: FloatArray
    # share of its observations that showed the world: any of grounded, joined, propped,
    # crowded or cut (one observation counts once, whichever it showed)
    world_seen: FloatArray
    extent: FloatArray  # the largest extent seen [m]
    hovered: NDArray[np.bool_]
    # hovered in free space: in observations neither grounded, cut, joined, propped nor
    # crowded (the world holds still too)
    hovered_free: NDArray[np.bool_]
    min_speed: FloatArray  # its lowest speed over its observed frames after the first [m/s]
    aloft: FloatArray  # its recent observations' share in the open air
    # returned points in more of the frames it was in view after its birth than the
    # drone could at its ranges (``classify.return_share``; False where not known)
    too_often: NDArray[np.bool_]
    # the height spread of its clusters (see the module docstring): Q = Σ d²/(c σ_d²)
    # over n triples, and √(Σ 12 d²/c / n), the height its returns land over [m]
    # (NaN: no triple)
    spread_q: FloatArray
    spread_n: NDArray[np.int64]
    spread_m: FloatArray


# the per-track counters of ``TrackLives``, each an int64 array from 0
_COUNTS = (
    "observed",
    "grounded",
    "joined",
    "beyond",
    "crowded",
    "cut",
    "propped",
    "world_seen",
    "slow_run",
    "free_run",
    "looked",  # frames in view after its first observation
    "looked_hits",  # of those, the frames a cluster updated it
    "spread_n",  # triples of updates the height spread took
    "unjudged",  # observations not grounded where the ground was not known yet
    "unjudged_free",  # of those, the ones that showed no other sign of the world
)

# the other per-track arrays of ``TrackLives``
_LIFE = (
    "first_t",
    "last_t",
    "seen_s",
    "first_p",
    "moved",
    "moved_xy",
    "extent",
    "range_m",
    "hovered",
    "hovered_free",
    "min_speed",
    "aloft",
    "expected_hits",  # Σ P(r_i) over the frames ``looked``: the drone's expected hits
    "spread_q",  # Σ d²/(c σ_d²) of the height spread
    "spread_u",  # Σ 12 d²/c [m²]
    "last_z",  # (K, 2) the heights of its last two clusters, older first [m]
    "last_zt",  # (K, 2) their times [s]
    "unjudged_low",  # the highest bottom z_lo of the ``unjudged`` observations [m]
)


class TrackLives:
    """Every track's life, kept by its identity (``update`` once a frame)."""

    def __init__(
        self,
        hover_speed: float = 4.0,
        hover_frames: int = 3,
        drone_size_m: float = 0.4,
        ground_cell_m: float = 5.0,
    ) -> None:
        self.hover_speed = hover_speed
        self.hover_frames = hover_frames
        self.drone_size_m = drone_size_m
        self.ground_cell_m = ground_cell_m
        self._row: dict[int, int] = {}
        n = 0
        self.first_t = np.empty(n)
        self.last_t = np.empty(n)
        self.seen_s = np.empty(n)
        self.first_p = np.empty((n, 3))
        self.moved = np.empty(n)
        self.moved_xy = np.empty(n)
        self.observed = np.empty(n, dtype=np.int64)
        self.grounded = np.empty(n, dtype=np.int64)
        self.joined = np.empty(n, dtype=np.int64)
        self.beyond = np.empty(n, dtype=np.int64)
        self.crowded = np.empty(n, dtype=np.int64)
        self.cut = np.empty(n, dtype=np.int64)
        self.propped = np.empty(n, dtype=np.int64)
        self.world_seen = np.empty(n, dtype=np.int64)
        self.extent = np.empty(n)
        self.range_m = np.empty(n)
        self.slow_run = np.empty(n, dtype=np.int64)
        self.free_run = np.empty(n, dtype=np.int64)
        self.hovered = np.empty(n, dtype=bool)
        self.hovered_free = np.empty(n, dtype=bool)
        self.min_speed = np.empty(n)
        self.aloft = np.empty(n)
        self.looked = np.empty(n, dtype=np.int64)
        self.looked_hits = np.empty(n, dtype=np.int64)
        self.expected_hits = np.empty(n)
        self.spread_n = np.empty(n, dtype=np.int64)
        self.spread_q = np.empty(n)
        self.spread_u = np.empty(n)
        self.last_z = np.empty((n, 2))
        self.last_zt = np.empty((n, 2))
        self.unjudged = np.empty(n, dtype=np.int64)
        self.unjudged_free = np.empty(n, dtype=np.int64)
        self.unjudged_low = np.empty(n)

    def __len__(self) -> int:
        return len(self._row)

    def update(
        self,
        t: float,
        tracks: Tracks,
        obs: Observations,
        resting: NDArray[np.int64] | None = None,
        heirs: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None,
        share: FloatArray | None = None,
    ) -> LifeFeatures:
        """Take the frame ending at ``t``: give each heir its life (``heirs``: the new
        identities and those whose lives they take), forget tracks that ended (but the
        identities ``resting``, an heir may come), start new ones, add each updated
        track's observation; the features of ``tracks``.  ``share`` (K,): the share of
        frames the drone returns a point at each track's range (``return_share``; None:
        not known), counted over the frames each track is in view after its first
        observation."""
        if heirs is not None:
            self._inherit(*heirs)
        alive = set(tracks.ids.tolist())
        if resting is not None:
            alive.update(np.asarray(resting).tolist())
        self._forget(alive)
        rows = np.array([self._row_of(int(i), t) for i in tracks.ids], dtype=np.intp)
        u = obs.updated
        if share is not None:
            # after its birth, in view: n += 1, k += [updated], μ += P(r)
            looked = tracks.in_view & (self.observed[rows] > 0)
            at = rows[looked]
            self.looked[at] += 1
            self.looked_hits[at] += u[looked]
            self.expected_hits[at] += share[looked]
        r = rows[u]
        first = self.observed[r] == 0
        anchor = np.isnan(self.first_p[r, 0])  # its first cluster, or an heir's own first
        self.first_p[r[anchor]] = obs.centroid[u][anchor]
        # watched: Σ min(t_k − t_{k−1}, SEEN_GAP_S) over its updates (not the time it was
        # out of view or missed)
        self.seen_s[r] += np.where(first, 0.0, np.minimum(t - self.last_t[r], SEEN_GAP_S))
        self.last_t[r] = t
        self.observed[r] += 1
        away = obs.centroid[u] - self.first_p[r]
        self.moved[r] = np.maximum(self.moved[r], np.linalg.norm(away, axis=1))
        self.moved_xy[r] = np.maximum(self.moved_xy[r], np.hypot(away[:, 0], away[:, 1]))
        self.grounded[r] += obs.grounded[u]
        air = ~obs.grounded[u]
        self.aloft[r] = (1.0 - ALOFT_ALPHA) * self.aloft[r] + ALOFT_ALPHA * air
        self.joined[r] += obs.joined[u]
        self.beyond[r] += obs.beyond_reach[u]
        self.crowded[r] += obs.crowded[u]
        self.cut[r] += obs.cut[u]
        self.propped[r] += obs.propped[u]
        world = obs.grounded | obs.joined | obs.propped | obs.crowded | obs.cut
        self.world_seen[r] += world[u]
        self._judge(r, obs.grounded[u], world[u], obs.low[u], obs.lift[u])
        self._spread(r, t, obs.centroid[u, 2], obs.range_m[u])
        self.extent[r] = np.fmax(self.extent[r], obs.extent[u])
        self.range_m[r] = np.fmax(self.range_m[r], obs.range_m[u])
        later = self.observed[r] > 1  # a track's first velocity is the birth's guess
        self.min_speed[r[later]] = np.minimum(self.min_speed[r[later]], obs.speed[u][later])
        # hovered: |v| < v_hover for K updates in a row, in the air
        seen_free = ~obs.grounded & ~obs.cut & u
        slow = (obs.speed[u] < self.hover_speed) & seen_free[u] & later
        self.slow_run[r] = np.where(slow, self.slow_run[r] + 1, 0)
        self.hovered[r] |= self.slow_run[r] >= self.hover_frames
        self.hovered[rows] |= tracks.hovered & seen_free
        # and in free space: the same, in observations nothing says are of the world
        free = u & ~world
        slow_free = slow & free[u]
        self.free_run[r] = np.where(slow_free, self.free_run[r] + 1, 0)
        self.hovered_free[r] |= self.free_run[r] >= self.hover_frames
        self.hovered_free[rows] |= tracks.hovered & free
        # engulfed: its object seen as part of something larger than a drone, an
        # observation that shows the world beside it, as joined does (``observe``)
        e = rows[obs.engulfed]
        self.observed[e] += 1
        self.joined[e] += 1
        self.world_seen[e] += 1
        n = np.maximum(self.observed[rows], 1)
        return LifeFeatures(
            age=t - self.first_t[rows],
            seen_s=self.seen_s[rows].copy(),
            observed=self.observed[rows].copy(),
            moved=self.moved[rows].copy(),
            moved_xy=self.moved_xy[rows].copy(),
            range_m=self.range_m[rows].copy(),
            grounded=self.grounded[rows] / n,
            joined=self.joined[rows] / n,
            beyond_reach=self.beyond[rows] / n,
            crowded=self.crowded[rows] / n,
            cut=self.cut[rows] / n,
            propped=self.propped[rows] / n,
            world_seen=self.world_seen[rows] / n,
            extent=self.extent[rows].copy(),
            hovered=self.hovered[rows].copy(),
            hovered_free=self.hovered_free[rows].copy(),
            min_speed=self.min_speed[rows].copy(),
            aloft=self.aloft[rows].copy(),
            too_often=(
                more_often_than_drone(self.looked_hits[rows], self.expected_hits[rows])
                if share is not None
                else np.zeros(len(rows), dtype=bool)
            ),
            spread_q=self.spread_q[rows].copy(),
            spread_n=self.spread_n[rows].copy(),
            spread_m=spread_height(self.spread_u[rows], self.spread_n[rows]),
        )

    def _judge(
        self,
        r: NDArray[np.intp],
        grounded: NDArray[np.bool_],
        world: NDArray[np.bool_],
        low: FloatArray,
        lift: FloatArray,
    ) -> None:
        """Judge the observations of rows ``r`` made before the ground under them was
        known, once it is: each not grounded then (``grounded``) is kept aside, with the
        highest of their bottoms ``low``; when an observation of the row knows the
        ground, g + h_g = ``lift``, while its clusters stayed within half a ground
        cell across (d_max,xy ≤ cell/2: the same ground), they count as grounded, and
        as showing the world, if max z_lo ≤ g + h_g, and as in the air otherwise."""
        unknown = ~grounded & np.isnan(lift)
        at = r[unknown]
        self.unjudged[at] += 1
        self.unjudged_free[at] += ~world[unknown]
        self.unjudged_low[at] = np.fmax(self.unjudged_low[at], low[unknown])
        known = np.isfinite(lift) & (self.unjudged[r] > 0)
        known &= self.moved_xy[r] <= 0.5 * self.ground_cell_m
        on = known & (self.unjudged_low[r] <= lift)  # max z_lo ≤ g + h_g
        self.grounded[r[on]] += self.unjudged[r[on]]
        self.world_seen[r[on]] += self.unjudged_free[r[on]]
        done = r[known]
        self.unjudged[done] = 0
        self.unjudged_free[done] = 0
        self.unjudged_low[done] = np.nan

    def _spread(self, r: NDArray[np.intp], t: float, z: FloatArray, rng: FloatArray) -> None:
        """Add the update at ``t`` of rows ``r`` (heights ``z``, ranges ``rng``) to their
        height spread, where their last two updates make a triple with it."""
        (z2, z1), (t2, t1) = self.last_z[r].T, self.last_zt[r].T
        g0, g1 = t - t1, t1 - t2
        ok = (g1 > 0) & (g1 <= SPREAD_GAP_S + 1e-9) & (g0 <= SPREAD_GAP_S + 1e-9)  # NaN: no
        d, c = spread_deviation(z[ok], z1[ok], z2[ok], g0[ok] / g1[ok])
        at = r[ok]
        self.spread_q[at] += d**2 / (c * spread_scale(self.drone_size_m, rng[ok]) ** 2)
        self.spread_u[at] += 12.0 * d**2 / c
        self.spread_n[at] += 1
        self.last_z[r] = np.column_stack([z1, z])
        self.last_zt[r] = np.column_stack([t1, np.full(len(r), t)])

    def _row_of(self, ident: int, t: float) -> int:
        row = self._row.get(ident)
        if row is not None:
            return row
        row = len(self.first_t)
        self._row[ident] = row
        self.first_t = np.append(self.first_t, t)
        self.last_t = np.append(self.last_t, t)
        self.seen_s = np.append(self.seen_s, 0.0)
        self.first_p = np.concatenate([self.first_p, np.full((1, 3), np.nan)])
        self.moved = np.append(self.moved, 0.0)
        self.moved_xy = np.append(self.moved_xy, 0.0)
        for name in _COUNTS:
            setattr(self, name, np.append(getattr(self, name), 0))
        self.extent = np.append(self.extent, np.nan)
        self.range_m = np.append(self.range_m, np.nan)
        self.hovered = np.append(self.hovered, False)
        self.hovered_free = np.append(self.hovered_free, False)
        self.min_speed = np.append(self.min_speed, np.inf)
        self.aloft = np.append(self.aloft, 1.0)
        self.expected_hits = np.append(self.expected_hits, 0.0)
        self.spread_q = np.append(self.spread_q, 0.0)
        self.spread_u = np.append(self.spread_u, 0.0)
        self.last_z = np.concatenate([self.last_z, np.full((1, 2), np.nan)])
        self.last_zt = np.concatenate([self.last_zt, np.full((1, 2), np.nan)])
        self.unjudged_low = np.append(self.unjudged_low, np.nan)
        return row

    def _inherit(self, new: NDArray[np.int64], old: NDArray[np.int64]) -> None:
        """A copy of the life of each identity ``old`` for the new one beside it (those
        without a life, or whose heir has one already, are passed over), but for how
        far it moved: the heir's d_max counts from its own first cluster.  An heir is
        the resting track's object by its place, within ``merge_m`` of its last fix,
        not by its path: a long structure's fragments, ended for room and reborn hop
        by hop, chain along it, and the chain's d_max is the structure's length, not
        any fragment's motion (on ``outdoor-unscanned``, seeds 0-9, heirs over tree
        lines 115-190 m out carried 5-12 m, past the 2 θ_c r a fragment may land
        within, and were never classed static)."""
        rows: list[int] = []
        for heir, of in zip(np.asarray(new).tolist(), np.asarray(old).tolist(), strict=True):
            row = self._row.get(int(of))
            if row is None or int(heir) in self._row:
                continue
            self._row[int(heir)] = len(self.first_t) + len(rows)
            rows.append(row)
        if rows:
            for name in (*_LIFE, *_COUNTS):
                column = getattr(self, name)
                setattr(self, name, np.concatenate([column, column[rows]]))
            # d_max counts from the heir's own first cluster (see ``_inherit``), and its
            # height spread's next triple from its own clusters
            self.first_p[-len(rows) :] = np.nan
            self.moved[-len(rows) :] = 0.0
            self.moved_xy[-len(rows) :] = 0.0
            self.last_zt[-len(rows) :] = np.nan

    def _forget(self, alive: set[int]) -> None:
        """Drop the lives of tracks that ended (their rows are compacted)."""
        gone = [i for i in self._row if i not in alive]
        if not gone:
            return
        keep_ids = [i for i in self._row if i in alive]
        keep = np.array([self._row[i] for i in keep_ids], dtype=np.intp)
        for name in (*_LIFE, *_COUNTS):
            setattr(self, name, getattr(self, name)[keep])
        self._row = {i: n for n, i in enumerate(keep_ids)}
