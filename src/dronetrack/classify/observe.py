"""One frame's observations of the tracks: what each track a cluster updated shows
this frame, the tests whose shares ``classify.features`` keeps over the track's life.

Each frame, for each track a cluster updated (``track.multi``), with c the cluster's
centroid, z_lo its lowest point, e its largest extent and r its range from the sensor:

- *grounded*: its bottom lies on the ground, or on the crop box's floor, which cuts
  off what stands on the ground:  z_lo ≤ max(g(c) + h_g, z_floor + h_f)
  (g from ``preprocess.ground``; h_g 0.5 m: a person's or a car's bottom is the
  ground, a drone in flight is metres above it; where g is not known yet, the
  observation is judged once it is, ``classify.features``);
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
- *engulfed* (a track no cluster updated, in the sensor's view): a point of a cluster
  too large to be a candidate (``Detections.oversized``) lies within ε of its
  predicted position p̂, min_i |p_i − p̂| ≤ ε: its object is part of something larger
  than a drone.  A structure's fragment seen at the rosette's sparse edge is a few
  points a frame, the size of a drone; once the turret centres it, its whole shape
  returns and its cluster is dropped as too large, so its track, classed by its few
  points, was updated no more and held the turret (``outdoor-unscanned`` seed 2: a
  sign board on a thin pole 100 m out, 1.2 m wide, hovering in free space by its
  evidence, p 0.98, returned 42-58 points a frame as one 2.5-3.0 m cluster while
  the turret held it for 1.5 s, the drone in view).  It counts as *joined*
  (``classify.features``);
- *beyond reach*: r > r_lim, the range beyond which the drone model the site guards
  returns no point to the sensor (``[pipeline.evaluation] limit_m``, measured per
  sensor and drone: 195 m for an Avia and a Phantom 4, 1.5 × its reach, where a drone
  on the axis still returns points in 80 % of frames; 50 m for a Mid-360): what
  returns there is larger or brighter than a drone;
- its speed |v| (the track's filter), and its cluster's centroid, from which its life
  keeps how far it has moved from the first one (the measurements, not the filter's
  state: a filter that follows a far object's jittering centroid gains a velocity and
  carries the state away).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.detect.candidates import engulfed as engulfed_test
from dronetrack.detect.crowding import crowded as crowded_test
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Detections, Tracks

__all__ = [
    "Observations",
    "observe",
    "view_floor",
]

BackgroundTest = Callable[[FloatArray], NDArray[np.bool_]]
VIEW_SECTORS = 72  # azimuth sectors of the view's floor, 5° each
CUT_MARGIN_RAD = math.radians(1.0)  # δ of the cut test
PROP_DEPTH_M = 1.5  # d_p of the propped test
PROP_RADIUS_M = 0.5  # r_min
BEAM_RAD = 0.005  # θ_b: the Avia's vertical beam divergence (the propped test, the height spread)


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
    # in view with no cluster, within ε of a cluster larger than a drone (False where
    # updated)
    engulfed: NDArray[np.bool_]
    low: FloatArray  # the cluster's bottom z_lo [m]
    lift: FloatArray  # g + h_g under it [m] (NaN: the ground there is not known yet)


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
    engulf_m: float | None = None,
) -> Observations:
    """This frame's observations of each track (see the module docstring); ``ground``
    (K,) is g under each track (NaN: unknown), ``sensor`` (3,) the sensor's position,
    ``crowd_gap_m`` g_c (None: the feature is off; the gap is min(g_c, θ_c r)),
    ``floor`` the view's floor (``view_floor`` of the frame's other returns; None: the
    cut test is off),
    ``below`` (N, 3) the returns the propped test probes (None: it is off),
    ``engulf_m`` ε of the engulfed test (None: it is off)."""
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
    rng = _scatter(k, idx, np.linalg.norm(c - sensor, axis=1))
    beyond = np.zeros(k, dtype=bool)
    if limit_m is not None:
        beyond[idx] = rng[idx] > limit_m
    joined = np.zeros(k, dtype=bool)
    if is_background is not None and len(idx):
        joined[idx] = _touches_background(c, low, ext, probe_margin, is_background)
    extent = _scatter(k, idx, ext)
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
    engulfed = np.zeros(k, dtype=bool)
    if engulf_m is not None:
        ask = np.flatnonzero(~updated & tracks.in_view)
        engulfed[ask] = engulfed_test(found, tracks.positions[ask], engulf_m)
    return Observations(
        updated,
        centroid,
        rng,
        speed,
        grounded,
        joined,
        beyond,
        extent,
        crowded,
        cut,
        propped,
        engulfed,
        _scatter(k, idx, low),
        _scatter(k, idx, ground[idx] + ground_margin),  # g + h_g: NaN where g is not known
    )


def _scatter(k: int, idx: NDArray[np.intp], values: FloatArray) -> FloatArray:
    """(k,) ``values`` at rows ``idx``, NaN elsewhere."""
    out = np.full(k, np.nan)
    out[idx] = values
    return out


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
    radius = np.maximum(PROP_RADIUS_M, BEAM_RAD * r)
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
