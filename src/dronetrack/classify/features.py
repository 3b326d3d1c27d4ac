"""What a track's life says of it: per-frame observations of each track, summed over
its life into features that tell a drone from a bird and from the static world.

Each frame, for each track a cluster updated (``track.multi``), with c the cluster's
centroid, z_lo its lowest point, e its largest extent and r its range from the sensor:

- *grounded*: its bottom lies on the ground, or on the crop box's floor, which cuts
  off what stands on the ground:  z_lo ≤ max(g(c) + h_g, z_floor + h_f)
  (g from ``preprocess.ground``; h_g 0.5 m: a person's or a car's bottom is the
  ground, a drone in flight is metres above it);
- *joined*: the background map holds a cell just beside the cluster (probes at
  c ± (e/2 + m) along x and y): a tree's crown or a building's edge that the map lacks
  part of, rather than something in the open air;
- *crowded*: another of the frame's clusters lies within a gap of it,
  |c − c'| − (e + e')/2 ≤ min(g_c, θ_c r) (``detect.crowding``): a drone flies in
  free space, while a far structure that the map lacks breaks into fragments a little
  more than ε apart (on ``outdoor-unscanned`` the drone's cluster had such a neighbour
  in 0.1 % of frames, the structures' fragments in 84 %).  With the gap at 2ε, not
  θ_c r, a person standing beside a drone hovering 2 m from a Mid-360 made it crowded
  in 41 % of its frames (``mid360-static`` seed 6);
- *cut*: its bottom lies at the floor of the sensor's view in its direction,
  ε(z_lo) ≤ ε_floor(α) + δ: the elevation from the sensor of its lowest point
  against the lowest elevation of the frame's other returns in its 5° azimuth sector
  and the two beside it (``view_floor``; the object hides the floor behind it; δ = 1°,
  a few times the sensors' angular sampling).  What is below
  it is out of view, so nothing says it is in the open air: a person 3 m from a
  Mid-360 1.1 m up is seen from 0.8 m up (the view's floor is 7° down), legs cut
  off, like a small object holding still in the air;
- *propped*: a return of the frame (not the ground's: z > g + h_g) lies in the column
  just below the cluster, within r_c = max(r_min, θ_b r) of its centroid across and
  within d_p (1.5 m) below its bottom z_lo: a mast's or a tree's top stands on its
  pole or trunk, while a drone has free air below it (θ_b 5 mrad, the Avia's beam
  divergence, its footprint at r; r_min 0.5 m; where the ground under it is not known,
  every return counts).  On ``outdoor-unscanned`` seed 0, the clusters on a lattice
  mast's top 12 m up and 125 m out, outside the map, had such returns in 29 % of their
  observations, the drone's in none of 369;
- *beyond reach*: r > r_lim, the range beyond which the drone model the site guards
  returns no point to the sensor (``[pipeline.evaluation] limit_m``, measured per
  sensor and drone: 195 m for an Avia and a Phantom 4, 1.5 × its reach, where a drone
  on the axis still returns points in 80 % of frames; 50 m for a Mid-360): what
  returns there is larger or brighter than a drone;
- its speed |v| (the track's filter), and how far its clusters' centroids have moved
  from the first one (the measurements, not the filter's state: a filter that follows
  a far object's jittering centroid gains a velocity and carries the state away).

Over a track's life these give its age, how long it was watched (the spacing of its
updates, each counted up to ``SEEN_GAP_S``, so not the time it was out of view or
missed), how far it ever moved from its first position (d_max), the shares of its
observations grounded, joined, crowded, cut, propped or beyond reach, its largest
extent, *aloft*: the share of its recent
observations not grounded (an exponential average over about the last three,
a ← (1 − α) a + α [not grounded], α = ``ALOFT_ALPHA``, from a = 1: off the ground
until seen on it), so a drone that lifted off is off the ground again within a few
frames while a person stays on it, and whether it *hovered*: |v| < v_hover for
``hover_frames`` updates in a row while in the air (neither grounded nor cut), which
no bird can (stall speed ≈ 5 m/s for the smallest), or its candidate hovered
(``detect.tentative``) and a cluster of it that is neither grounded nor cut updated
it; and whether it *hovered in free space*: the same in observations that are
neither joined, propped nor crowded either (the world holds still too).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.detect.crowding import crowded as crowded_test
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Detections, Tracks

__all__ = [
    "SEEN_GAP_S",
    "LifeFeatures",
    "Observations",
    "TrackLives",
    "observe",
    "view_floor",
]

BackgroundTest = Callable[[FloatArray], NDArray[np.bool_]]
ALOFT_ALPHA = 0.3
VIEW_SECTORS = 72  # azimuth sectors of the view's floor, 5° each
CUT_MARGIN_RAD = math.radians(1.0)  # δ of the cut test
PROP_DEPTH_M = 1.5  # d_p of the propped test
PROP_RADIUS_M = 0.5  # r_min
PROP_BEAM_RAD = 0.005  # θ_b
SEEN_GAP_S = 0.3  # the longest gap between two updates that counts as watched (``seen_s``)


@dataclass(frozen=True, slots=True)
class Observations:
    """One frame's observations of K tracks (``observe``); NaN or False where a track
    had no cluster this frame (``updated`` False)."""

    updated: NDArray[np.bool_]
    centroid: FloatArray  # (K, 3) the cluster's [m]
    range_m: FloatArray  # from the sensor [m]
    speed: FloatArray
    grounded: NDArray[np.bool_]
    joined: NDArray[np.bool_]
    beyond_reach: NDArray[np.bool_]
    extent: FloatArray
    crowded: NDArray[np.bool_]
    cut: NDArray[np.bool_]
    propped: NDArray[np.bool_]


def view_floor(points: FloatArray, sensor: FloatArray, sectors: int = VIEW_SECTORS) -> FloatArray:
    """(sectors,) the lowest elevation [rad] of ``points`` (N, 3) seen from ``sensor`` in
    each azimuth sector (sector k: α ∈ [−π + 2πk/S, −π + 2π(k+1)/S)); NaN where none."""
    d = np.asarray(points, dtype=np.float64) - sensor
    h = np.hypot(d[:, 0], d[:, 1])
    keep = np.isfinite(d).all(axis=1) & (h > 0)  # none straight above or below it
    d, h = d[keep], h[keep]
    lowest = np.full(sectors, np.inf)
    if len(d):
        # α = atan2(dy, dx); the least tan ε = dz / √(dx² + dy²) (tan rises with ε)
        np.minimum.at(lowest, _sector(d, sectors), d[:, 2] / h)
    floor: FloatArray = np.where(np.isfinite(lowest), np.arctan(lowest), np.nan)
    return floor


def _sector(d: FloatArray, sectors: int) -> NDArray[np.intp]:
    """The azimuth sector of each offset ``d`` (N, 3) from the sensor."""
    k = np.floor((np.arctan2(d[:, 1], d[:, 0]) + np.pi) * sectors / (2.0 * np.pi))
    out: NDArray[np.intp] = k.astype(np.intp) % sectors
    return out


def observe(
    tracks: Tracks,
    found: Detections,
    sensor: FloatArray,
    ground: FloatArray,
    *,
    floor_z: float = -np.inf,
    ground_margin: float = 0.5,
    floor_margin: float = 0.3,
    probe_margin: float = 0.5,
    limit_m: float | None = None,
    is_background: BackgroundTest | None = None,
    crowd_gap_m: float | None = None,
    floor: FloatArray | None = None,
    below: FloatArray | None = None,
) -> Observations:
    """This frame's observations of each track (see the module docstring); ``ground``
    (K,) is g under each track (NaN: unknown), ``sensor`` (3,) the sensor's position,
    ``crowd_gap_m`` g_c (None: the feature is off; the gap is min(g_c, θ_c r)),
    ``floor`` the view's floor (``view_floor`` of the frame's other returns; None: the
    cut test is off),
    ``below`` (N, 3) the returns the propped test probes (None: it is off)."""
    k = len(tracks)
    j = tracks.clusters
    updated = tracks.updated & (j >= 0)
    idx = np.flatnonzero(updated)
    c = found.centroids[j[idx]]
    assert found.lows is not None  # Detections fills it
    low = found.lows[j[idx]]
    ext = found.extents[j[idx], 0]
    grounded = np.zeros(k, dtype=bool)
    # z_lo ≤ max(g + h_g, z_floor + h_f)
    lift = np.where(np.isfinite(ground[idx]), ground[idx] + ground_margin, -np.inf)
    grounded[idx] = low <= np.maximum(lift, floor_z + floor_margin)
    rng = np.full(k, np.nan)
    rng[idx] = np.linalg.norm(c - sensor, axis=1)
    beyond = np.zeros(k, dtype=bool)
    if limit_m is not None:
        beyond[idx] = rng[idx] > limit_m
    joined = np.zeros(k, dtype=bool)
    if is_background is not None and len(idx):
        joined[idx] = _touches_background(c, low, ext, probe_margin, is_background)
    extent = np.full(k, np.nan)
    extent[idx] = ext
    centroid = np.full((k, 3), np.nan)
    centroid[idx] = c
    crowded = np.zeros(k, dtype=bool)
    if crowd_gap_m is not None and len(idx):
        crowded[idx] = crowded_test(found, j[idx], crowd_gap_m, sensor)
    cut = np.zeros(k, dtype=bool)
    if floor is not None and len(idx):
        d = np.column_stack([c[:, :2], low]) - sensor  # the cluster's bottom
        elevation = np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1]))
        # ε(z_lo) ≤ min(ε_floor over its sector and the two beside it) + δ: the object
        # hides the view's floor behind it in its own sector (False where none: NaN)
        sec, n = _sector(d, len(floor)), len(floor)
        near = np.fmin(np.fmin(floor[(sec - 1) % n], floor[sec]), floor[(sec + 1) % n])
        cut[idx] = elevation <= near + CUT_MARGIN_RAD
    propped = np.zeros(k, dtype=bool)
    if below is not None and len(idx):
        propped[idx] = stands_on(c, low, rng[idx], lift, below)  # above g + h_g
    speed = np.linalg.norm(tracks.velocities, axis=1)
    return Observations(
        updated, centroid, rng, speed, grounded, joined, beyond, extent, crowded, cut, propped
    )


def stands_on(
    c: FloatArray, low: FloatArray, r: FloatArray, lift: FloatArray, points: FloatArray
) -> NDArray[np.bool_]:
    """(K,) whether a return of ``points`` (N, 3) lies in the column below each cluster
    (centroid ``c`` (K, 3), bottom ``low``, range ``r``) and above ``lift`` (K,), the
    ground plus h_g:

        |p_xy − c_xy| ≤ max(r_min, θ_b r),  max(z_lo − d_p, lift) ≤ p_z < z_lo − 0.05 m
    """
    if len(points) == 0 or len(c) == 0:
        return np.zeros(len(c), dtype=bool)
    radius = np.maximum(PROP_RADIUS_M, PROP_BEAM_RAD * r)
    bottom = np.maximum(low - PROP_DEPTH_M, lift)
    z = points[:, 2]  # the returns within some column's height band
    p = np.ascontiguousarray(points[(z >= bottom.min()) & (z < low.max())], dtype=np.float64)
    out: NDArray[np.bool_] = _in_columns(
        np.ascontiguousarray(c[:, :2], dtype=np.float64), radius**2, bottom, low - 0.05, p
    )
    return out


@nb.njit(cache=True)
def _in_columns(
    c: FloatArray, r2: FloatArray, bottom: FloatArray, top: FloatArray, p: FloatArray
) -> NDArray[np.bool_]:
    """(K,) whether any point p (N, 3) has bottom_k ≤ p_z < top_k and
    |p_xy − c_k|² ≤ r2_k (the first one found ends the search)."""
    out = np.zeros(len(c), dtype=np.bool_)
    for k in range(len(c)):
        for i in range(len(p)):
            z = p[i, 2]
            if z < bottom[k] or z >= top[k]:
                continue
            dx, dy = p[i, 0] - c[k, 0], p[i, 1] - c[k, 1]
            if dx * dx + dy * dy <= r2[k]:
                out[k] = True
                break
    return out


def _touches_background(
    c: FloatArray, low: FloatArray, extent: FloatArray, margin: float, test: BackgroundTest
) -> NDArray[np.bool_]:
    """(K,) whether a background cell lies beside a cluster, ±(e/2 + m) along x and y
    from its centroid.  Nothing is probed below it: the map's lookup cells are coarse
    (4 m outdoors), and a probe under a drone flying 3 m up would find the ground's;
    what stands on the ground is told by ``grounded``."""
    h = 0.5 * extent + margin
    offsets = np.zeros((len(c), 4, 3))
    offsets[:, 0, 0], offsets[:, 1, 0] = h, -h
    offsets[:, 2, 1], offsets[:, 3, 1] = h, -h
    probes = c[:, None, :] + offsets
    hit = test(probes.reshape(-1, 3)).reshape(len(c), 4)
    return np.asarray(hit.any(axis=1), dtype=bool)


@dataclass(frozen=True, slots=True)
class LifeFeatures:
    """Each track's life so far (K,), in the order of the ``Tracks`` they were asked for."""

    age: FloatArray  # since its first observation [s]
    seen_s: FloatArray  # how long it was watched: its updates' spacing, each ≤ SEEN_GAP_S [s]
    observed: NDArray[np.int64]  # frames a cluster updated it
    moved: FloatArray  # d_max: the farthest it has been from its first position [m]
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
)

# the other per-track arrays of ``TrackLives``
_LIFE = (
    "first_t",
    "last_t",
    "seen_s",
    "first_p",
    "moved",
    "extent",
    "range_m",
    "hovered",
    "hovered_free",
    "min_speed",
    "aloft",
)


class TrackLives:
    """Every track's life, kept by its identity (``update`` once a frame)."""

    def __init__(self, hover_speed: float = 4.0, hover_frames: int = 3) -> None:
        self.hover_speed = hover_speed
        self.hover_frames = hover_frames
        self._row: dict[int, int] = {}
        n = 0
        self.first_t = np.empty(n)
        self.last_t = np.empty(n)
        self.seen_s = np.empty(n)
        self.first_p = np.empty((n, 3))
        self.moved = np.empty(n)
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

    def __len__(self) -> int:
        return len(self._row)

    def update(
        self,
        t: float,
        tracks: Tracks,
        obs: Observations,
        resting: NDArray[np.int64] | None = None,
        heirs: tuple[NDArray[np.int64], NDArray[np.int64]] | None = None,
    ) -> LifeFeatures:
        """Take the frame ending at ``t``: give each heir its life (``heirs``: the new
        identities and those whose lives they take), forget tracks that ended (but the
        identities ``resting``, an heir may come), start new ones, add each updated
        track's observation; the features of ``tracks``."""
        if heirs is not None:
            self._inherit(*heirs)
        alive = set(tracks.ids.tolist())
        if resting is not None:
            alive.update(np.asarray(resting).tolist())
        self._forget(alive)
        rows = np.array([self._row_of(int(i), t) for i in tracks.ids], dtype=np.intp)
        u = obs.updated
        r = rows[u]
        first = self.observed[r] == 0
        self.first_p[r[first]] = obs.centroid[u][first]
        # watched: Σ min(t_k − t_{k−1}, SEEN_GAP_S) over its updates (not the time it was
        # out of view or missed)
        self.seen_s[r] += np.where(first, 0.0, np.minimum(t - self.last_t[r], SEEN_GAP_S))
        self.last_t[r] = t
        self.observed[r] += 1
        self.moved[r] = np.maximum(
            self.moved[r], np.linalg.norm(obs.centroid[u] - self.first_p[r], axis=1)
        )
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
        n = np.maximum(self.observed[rows], 1)
        return LifeFeatures(
            age=t - self.first_t[rows],
            seen_s=self.seen_s[rows].copy(),
            observed=self.observed[rows].copy(),
            moved=self.moved[rows].copy(),
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
        )

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
        for name in _COUNTS:
            setattr(self, name, np.append(getattr(self, name), 0))
        self.extent = np.append(self.extent, np.nan)
        self.range_m = np.append(self.range_m, np.nan)
        self.hovered = np.append(self.hovered, False)
        self.hovered_free = np.append(self.hovered_free, False)
        self.min_speed = np.append(self.min_speed, np.inf)
        self.aloft = np.append(self.aloft, 1.0)
        return row

    def _inherit(self, new: NDArray[np.int64], old: NDArray[np.int64]) -> None:
        """A copy of the life of each identity ``old`` for the new one beside it (those
        without a life, or whose heir has one already, are passed over)."""
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
