"""A class and p_drone for each track, from its life (``classify.features``), by rules
whose every constant is a physical bound or a measured figure.

p_drone is a logistic of summed evidence (log-odds, from an even prior):

    ln(p / (1 − p)) = Σ_i w_i · [feature i holds]

    hovered in free space         +4    no bird can fly below its stall speed.  The
                                        world holds still too, so it counts only where
                                        nothing says the track is part of the world
                                        (grounded, joined, propped, crowded, or cut by
                                        the view's floor, in the shares below: what is
                                        below it is not seen).  On ``outdoor-unscanned``
                                        (seeds 0-9) the fragments of an unmapped tree
                                        line 125-190 m out hovered and were crowded:
                                        p 0.73 outranked the unknown drone (0.5), the
                                        turret started on them, and the learning map
                                        never took them in (a possible drone's returns
                                        are not learnt).  The hover itself must be seen
                                        in free space too (``hovered_free``): a track
                                        that held still 5 m from the sensor, the world
                                        by its evidence (p 0.05), then took a bird's
                                        cluster 32 m away (its gate grown while
                                        unseen) and kept its hover: the bird was
                                        classed drone in 29 % of its frames
                                        (``outdoor-clutter`` seed 6).  Nor does it
                                        count where the world showed in half its
                                        observations or more, whichever kind each
                                        showed (``world_seen``): a low fragment of a
                                        structure 125-160 m out, grounded in 44 % of
                                        them and crowded in a third, each under its
                                        own half, hovered in free space for three
                                        frames and was classed drone (p 0.98), and
                                        the turret held it (``outdoor-unscanned``)
    grounded (≥ half its frames)  −4    its bottom is the ground or the crop floor
    joined (≥ a fifth)            −3    a map cell beside or below it: part of a structure
    propped (≥ a fifth)           −3    returns just below it: a mast's or a tree's top
    crowded (≥ half its frames)   −3    another cluster just beside it: a fragment of a
                                        structure the map lacks, not a drone in free space
                                        (it never makes a track static, as two drones
                                        hovering close are crowded too; but it takes
                                        their hover's evidence away: drones hovering
                                        within min(2ε, 1° × range) of each other are
                                        held unlikely)
    beyond reach (≥ half)         −6    a drone returns nothing there; so is a track
                                        that returned in more of its frames in view
                                        than the drone could at its ranges
                                        (``too_often``, ``classify.return_share``):
                                        larger or brighter than the drone, it counts
                                        as beyond reach here and in the classes below
    larger than a drone           −4    extent > ``max_extent_m``, or its clusters'
                                        heights spread over more than a drone's
                                        (``taller_than_drone``): Q of the height
                                        spread (``classify.features``), against
                                        χ²(n) for a drone, rejects it at α = 0.01
                                        (κ Q > χ²₁₋α(κ n), κ = 18/35 for the
                                        deviations' overlap, Satterthwaite's
                                        approximation).  On ``outdoor-unscanned``
                                        (seeds 0-4) the drones' tracks had Q/n ≤
                                        0.07, the tracks of a pole 85 m out sampled
                                        at heights of 1.1-4.7 m 1.1-10.7 (9 of 20
                                        rejected); on ``outdoor-clutter`` the birds'
                                        ≤ 1.4, none rejected
    moving, never hovered      −T / μ   a bird's flight: watched T seconds (``seen_s``)
                                        and never slower than a bird's stall speed, which
                                        a drone in flight does now and then.  Its fast
                                        stretches last T or more in a share exp(−T / μ)
                                        of its flight, μ = ``steady_flight_s`` (4.3 s:
                                        the simulator's drone flights,
                                        ``experiments.calibrate``), so the odds of a
                                        drone fall by that share: a steady flier reaches
                                        ``bird_p`` (0.2) after μ ln 4 = 6 s

Joined and propped count from a fifth of a track's observations (``WORLD_SHARE``), the
other tests from half.  Both show up now and then only: the pattern samples a thin
pole below a sign board, or the map cell beside a fragment, in some frames, and a
frame that misses it says little.  Between a part of the world, which shows such
evidence in a share q of its observations, and a drone in free air, which shows it by
chance in a share ε, the likelihood-ratio test over n observations, k of them showing
it, decides by the share s = k / n:

    k ln(q / ε) + (n − k) ln((1 − q) / (1 − ε)) ≥ 0
    ⟺  s ≥ s* = ln((1 − ε) / (1 − q)) / ln(q (1 − ε) / (ε (1 − q)))

With q = 0.29 (the returns below a lattice mast's top, ``classify.observe``), s* is
0.09 for ε = 0.01 and 0.18 for ε = 0.1: a fifth holds a drone that shows such
evidence by chance in up to a tenth of its frames (passing a crown, hovering beside a
mast) as not part of the world.  A majority (s ≥ ½) asks for q well above ½, which
sparse evidence never gives: on ``outdoor-unscanned`` (seeds 0-9, the scenario's own
config) it left the far structures' fragments in the open air for seconds, as
hovering drones the turret served.  A fifth, the rest of the pipeline unchanged, took
the turret's time on them from 0.75 to 0.33 s a run and the false positives from 393
to 214 a run; the drone's frames classed drone went from 99.3 to 98.6 %.

Classes, in this order:

- **static**: its clusters have not moved more than max(``still_m``, its extent, the
  height its clusters spread over, ``still_rad`` × its range) from the first (taller
  than a drone by its height spread, not more than max(``still_m``, its extent,
  ``still_rad`` × its range) across: its height is no motion), over
  ``static_after_s`` and ``min_observed`` clusters, and something says it is not in
  the open air (grounded, joined, propped, beyond reach or too large).  A small object
  holding still in the open air is a hovering drone, not a static one.  Beyond reach,
  a track that hovered is static however far its clusters wander: the drone returns
  nothing there, no bird hovers, and a far structure's few returns land anywhere on it
  (on ``site-busy``, seeds 0-9, this took the static tracks not classed within 3 s
  from 13.8 to 9.5 a run).  So is
  a track that hovered, joined in half its observations and in the air (neither
  grounded nor cut in half of them), whose clusters stayed within 2 θ_c r of the
  first (θ_c = 1°, the angular spacing of a far structure's fragments,
  ``detect.crowding``): it keeps beside what the map holds, and the fragments of a
  structure, a tree's crown or a pole, land anywhere on it, a few spacings apart.  On
  ``outdoor-unscanned`` (seeds 0-9) such fragments of trees 150-200 m out wandered up
  to 4 m (1.5° at 150 m), more than the 1.5-2 m a still object may there; with this clause the
  static tracks not classed within 3 s went from 11.1 to 4.2 a run, and on
  ``site-busy`` from 9.5 to 6.2.  Without the bound on the wander, a board carried
  towards a VLP-16 beside the map (``walk-line``) was classed static and its lock
  given up.  On the ground, where nothing hovers, the same holds without the hover,
  beside the map or beyond reach: a grounded track joined in half its observations,
  or beyond reach in half, whose clusters stayed within 2 θ_c r of the first is a
  far structure's base, a wall's foot or a parked car's side that the map lacks part
  of.  A person who walks there leaves that bound within 2 θ_c r / v (2.5 s at
  100 m, at 1.4 m/s), and one who stands there is static while standing.  On
  ``outdoor-unscanned`` and ``site-busy`` (seeds 0-9) the static tracks not classed
  within 3 s went from 3.6 to 2.6 and from 4.6 to 2.6 a run (beside the map alone:
  2.6 and 2.8); the walkers' frames classed static went from 3.2 to 3.5 %
  (``site-busy``) and stayed at 6.7 % (``mid360-static``), every drone's figure
  unchanged.
  Last, a track in the air (neither grounded nor cut in half its observations) with a
  structure's evidence, as ``in_open_air`` takes it (joined or propped in a fifth of
  its observations while within max(``still_m``, 2 θ_c r) of its first cluster), is
  static whether or not its speed said it hovered: the fragments of a sparsely
  sampled structure jump over it from frame to frame.  The turret already gave up a
  lock on such a track; on ``outdoor-unscanned`` and ``site-busy`` (seeds 0-9) the
  static tracks not classed within 3 s went from 4.7 to 3.3 and from 5.3 to 4.2 a
  run, every other figure of the ``multi`` suite unchanged.
  Beyond reach a track is static from three clusters (``FAR_OBSERVED``), not
  ``min_observed``: its range says it is no drone in every observation alike, so no
  share needs the five, only the still test, which two displacements make.  A far
  structure's few returns beyond an Avia's reach update its track in one frame of
  three or four (``site-busy``, seeds 0-9: 14 of the 21 static tracks not classed
  within 3 s had 2-4 clusters by then); with three, those tracks went from 2.1 to
  1.3 a run (seeds 10-19: 3.2 to 1.4), every drone's, bird's and walker's figure
  unchanged.  So it is within reach for a track whose every observation showed the
  world (``world_seen`` 1; grounded, joined or propped in its shares as above): a
  drone in free air shows some such evidence by chance in a share ε of its
  observations, all of three in ε³ (10⁻³ for ε = 0.1), and with ``min_observed`` it
  would be static on a share of a fifth anyway.  The tops of a tree line 150-180 m
  out, joined in each of their three or four updates in 3 s, waited for the five; on
  ``outdoor-unscanned`` the static tracks not classed within 3 s went from 0.6 to
  0.3 a run (seeds 10-29: 0.4 to 0), and on ``site-busy`` from 0.8 to 0.7; the
  drone's lock-on while visible moved on the runs whose turret took another path
  (96.3 to 96.2 % over seeds 0-9, 94.2 to 95.9 % over 10-29).
- **drone**: p_drone ≥ ``drone_p``;
- **bird**: p_drone ≤ ``bird_p``, in the air, never slower than ``v_stall``, over
  ``min_observed`` clusters;
- **unknown**: the rest (a person walking, a drone in fast flight seen too briefly).

The returns' intensity and their count in a frame are left out: in the simulator they
tell a bird by its one reflectivity and its small size, which real birds do not share
(``experiments.appearance``, docs/pipeline.md).  How often a track returns any, against
its range, is ``too_often``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.classify.features import LifeFeatures
from dronetrack.classify.spread import taller_than_drone
from dronetrack.detect.crowding import CROWD_RAD
from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TRACK_CLASSES

__all__ = [
    "FAR_OBSERVED",
    "WORLD_SHARE",
    "ClassRules",
    "classify",
    "in_open_air",
]

UNKNOWN, DRONE, BIRD, STATIC = (
    TRACK_CLASSES.index(c) for c in ("unknown", "drone", "bird", "static")
)

ALOFT_MIN = 0.2  # five grounded observations in a row bring a = 1 below it (0.7⁵ = 0.17)
W_HOVERED = 4.0
W_GROUNDED = -4.0
W_JOINED = -3.0
W_PROPPED = -3.0
W_CROWDED = -3.0
W_BEYOND_REACH = -6.0
W_TOO_LARGE = -4.0
WORLD_SHARE = 0.2  # s*: the share of observations joined or propped that counts
# Beyond reach, the clusters a track needs before it is called static: its range says
# it is no drone in every observation alike, so no share is wanted, only a still test
# (two displacements; see the module docstring)
FAR_OBSERVED = 3
BESIDE_SPACINGS = 2.0  # a fragment beside the map wanders over this many θ_c


@dataclass(frozen=True, slots=True)
class ClassRules:
    """The rules' bounds (SI units; see the module docstring).

    max_extent_m: the largest extent a drone's cluster has (a Phantom 4's 0.35 m
    diagonal plus the beam's footprint and the points' spread); still_m, still_rad: how
    far a static object's clusters wander (the pattern samples it in other places),
    at least still_m and still_rad × its range (0.01 rad: twice the Avia's 0.28°
    beam; 2 m at 200 m);
    static_after_s: how long it must hold still; steady_flight_s: μ, how long a drone
    in flight flies without slowing below a bird's stall speed (``experiments.calibrate``;
    the bird-flight evidence is −T/μ after T seconds watched); min_observed:
    the clusters a track needs before it is called static or a bird; v_stall: the
    slowest a bird flies [m/s]; drone_p, bird_p: the classes' thresholds on p_drone.
    """

    max_extent_m: float = 2.0
    still_m: float = 1.0
    still_rad: float = 0.01
    static_after_s: float = 1.0
    steady_flight_s: float = 4.3
    min_observed: int = 5
    v_stall: float = 4.0
    drone_p: float = 0.8
    bird_p: float = 0.2

    def __post_init__(self) -> None:
        for name in ("max_extent_m", "still_m", "v_stall", "steady_flight_s"):
            if not getattr(self, name) > 0:
                raise ConfigError(f"classify: {name} must be positive, got {getattr(self, name)}")
        if not self.static_after_s >= 0:
            raise ConfigError(f"classify: static_after_s must be ≥ 0, got {self.static_after_s}")
        if not 0.0 <= self.bird_p < self.drone_p <= 1.0:
            raise ConfigError(
                f"classify: need 0 ≤ bird_p < drone_p ≤ 1, got {self.bird_p}, {self.drone_p}"
            )


def _fragment_spread(life: LifeFeatures) -> FloatArray:
    """(K,) how far a structure's fragments land from the first one at each track's
    range: 2 θ_c r [m] (``BESIDE_SPACINGS`` of the fragments' angular spacing θ_c; 0
    where the range is not known)."""
    out: FloatArray = BESIDE_SPACINGS * CROWD_RAD * np.nan_to_num(life.range_m, nan=0.0)
    return out


def in_open_air(life: LifeFeatures, rules: ClassRules | None = None) -> NDArray[np.bool_]:
    """(K,) whether each track's life says it may be in the open air now.

    - Not grounded in nearly all of its recent observations (``aloft`` ≥ ``ALOFT_MIN``):
      a person walking is on the ground in every one, a drone flying low over the
      crop's floor in some.
    - Not part of a structure by its evidence: joined or propped in ``WORLD_SHARE`` of
      its observations, once it has ``min_observed`` of them (one frame's evidence is
      no share), while it stayed within max(``still_m``, 2 θ_c r) of its first cluster,
      where a structure's fragments land (``beside`` in ``classify``).

    The turret gives up a lock on what is not in the open air (``pipeline.selection``).
    On ``outdoor-unscanned`` (seeds 0-9) a lamp post's track, its evidence a
    structure's (p 0.002) before it had held still long enough to be static, held the
    lock for 1.2 s (seed 1); with the structure's evidence, the turret's time on static
    objects went from 0.44 to 0.22 s a run, the longest 1.0 s.  What flew further is
    no structure whatever its evidence: a drone that flew 112 m in and stopped 28 m
    from the sensor was joined in a fifth of its observations as the map learnt cells
    beside it before its hover was seen (``outdoor-incoming`` seed 4, tracked by
    ekf-dogru); without the bound its lock was given up and lost."""
    rules = rules if rules is not None else ClassRules()
    worldly = (life.observed >= rules.min_observed) & _structure_evidence(life, rules)
    out: NDArray[np.bool_] = (life.aloft >= ALOFT_MIN) & ~worldly
    return out


def _structure_evidence(life: LifeFeatures, rules: ClassRules) -> NDArray[np.bool_]:
    """(K,) joined or propped in ``WORLD_SHARE`` of its observations while it stayed
    where a structure's fragments land: d_max ≤ max(still_m, 2 θ_c r)."""
    stayed = life.moved <= np.maximum(rules.still_m, _fragment_spread(life))
    evidence = (life.joined >= WORLD_SHARE) | (life.propped >= WORLD_SHARE)
    out: NDArray[np.bool_] = evidence & stayed
    return out


def classify(
    life: LifeFeatures, rules: ClassRules | None = None
) -> tuple[NDArray[np.int64], FloatArray]:
    """Each track's class (index into ``TRACK_CLASSES``) and p_drone (K,)."""
    rules = rules if rules is not None else ClassRules()
    grounded = life.grounded >= 0.5
    joined = life.joined >= WORLD_SHARE
    propped = life.propped >= WORLD_SHARE
    crowded = life.crowded >= 0.5
    cut = life.cut >= 0.5
    # beyond the drone's reach, or returning more often than it could at its ranges
    beyond = (life.beyond_reach >= 0.5) | life.too_often
    extent = np.nan_to_num(life.extent, nan=0.0)
    range_m = np.nan_to_num(life.range_m, nan=0.0)
    taller = taller_than_drone(life.spread_q, life.spread_n)
    large = (extent > rules.max_extent_m) | taller
    # d_max ≤ max(still_m, extent, h, θ_still r): a far object's few returns land
    # anywhere on it (its clusters' extent, or the height they spread over) and its
    # beam footprint; taller than a drone, across: its height is no motion
    spread = np.nan_to_num(life.spread_m, nan=0.0)
    footprint = np.maximum(rules.still_m, np.maximum(extent, rules.still_rad * range_m))
    still = (life.moved <= np.maximum(footprint, spread)) | (taller & (life.moved_xy <= footprint))
    seen = life.observed >= rules.min_observed
    flying = ~still & ~life.hovered & seen
    # the world's evidence in most of its observations, whichever kind each showed
    of_the_world = life.world_seen >= 0.5
    free = ~(grounded | cut | joined | propped | crowded | of_the_world)
    logit = (
        W_HOVERED * (life.hovered_free & free)
        + W_GROUNDED * grounded
        + W_JOINED * joined
        + W_PROPPED * propped
        + W_CROWDED * crowded
        + W_BEYOND_REACH * beyond
        + W_TOO_LARGE * large
        - np.where(flying, life.seen_s / rules.steady_flight_s, 0.0)  # −T/μ
    )
    p = 1.0 / (1.0 + np.exp(-logit))
    classes = np.full(len(p), UNKNOWN, dtype=np.int64)
    classes[p >= rules.drone_p] = DRONE
    bird = (p <= rules.bird_p) & ~grounded & (life.min_speed >= rules.v_stall) & ~still & seen
    classes[bird] = BIRD
    # beyond the drone's reach, what holds still is the world, however far its few
    # returns wander over it; beside what the map holds, in the air, within a few of
    # the fragments' angular spacings: d_max ≤ 2 θ_c r
    # (in the air, it must have hovered: a drone stopped beside the map is still for a
    # while too; on the ground, where nothing hovers, its ground is the evidence, and
    # beyond reach too, within the same spread)
    landed = life.moved <= _fragment_spread(life)
    beside = (life.joined >= 0.5) & ~cut & landed
    # a structure's part in the air by its evidence, as ``in_open_air`` holds it
    worldly = _structure_evidence(life, rules) & ~grounded & ~cut
    aloft_parked = (beyond | (beside & ~grounded)) & life.hovered
    parked = still | aloft_parked | (grounded & (beside | (beyond & landed))) | worldly
    # its range, or the world's evidence in every one of its observations, says it is
    # no drone in free air: no share needs ``min_observed``
    sure = (beyond | (life.world_seen >= 1.0)) & (life.observed >= FAR_OBSERVED)
    static = (
        parked
        & (seen | sure)
        & (life.age >= rules.static_after_s)
        & (grounded | joined | propped | beyond | large)
    )
    classes[static] = STATIC
    return classes, p
