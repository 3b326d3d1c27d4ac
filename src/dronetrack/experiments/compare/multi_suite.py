"""The ``multi`` comparison suite: the scenarios of several objects, each drone's figures,
the multi-object figures (motmetrics) and the classes, from metrics.json's drones, mot
and classes (``eval``)."""

from __future__ import annotations

from dronetrack.experiments.compare.suite import Case, MetricGroup, Suite

__all__ = ["MULTI_GROUPS", "MULTI_METRICS", "MULTI_SCENARIOS", "MULTI_SUITE"]

# The multi suite's figures, from metrics.json's drones, mot and classes (eval/).
MULTI_GROUPS = (
    MetricGroup(
        "Every drone",
        (
            "coverage_min_pct",
            "coverage_mean_pct",
            "acquire_max_s",
            "acquire_mean_s",
            "acquire_in_reach_max_s",
            "never_acquired",
            "track_acquire_max_s",
            "track_acquire_in_reach_max_s",
            "lock_on_visible_min_pct",
            "lock_on_visible_mean_pct",
            "own_track_min_pct",
            "own_track_mean_pct",
            "id_switches_max",
            "revisit_max_s",
        ),
        "Each drone's figures of metrics.json's drones, per run the minimum (_min), the "
        "maximum (_max) or the mean (_mean) over the drones: coverage against the "
        "turret's estimate; acquire_s from its first visible frame to its first locked-on "
        "one (over the drones acquired; never_acquired counts the drones visible but "
        "never locked on); track_acquire_s from its first visible frame to the first "
        "one a track matched it, whether or not the turret serves it (motmetrics; over "
        "the drones matched); _in_reach: from its first visible frame within the "
        "sensor's reach (130 m for the Avia and a Phantom 4; not known for the other "
        "pairs), as the targets count: a drone flying in from beyond reach draws single "
        "returns out there; lock_on_visible: its locked-on frames over its visible "
        "frames; own_track: the share of its visible frames in which a track matched it "
        "(motmetrics); id_switches: its identity switches; revisit_max_s: the longest "
        "time a drone in the field and within reach waited for the turret between two "
        "locked-on frames (or after the last), from its first lock, the largest over the "
        "drones (the shared turret's revisit_s is 10 s).",
    ),
    MetricGroup(
        "Multi-object figures (motmetrics, over the drones)",
        ("mota", "motp_m", "idf1", "id_switches"),
        "Each frame the drones that return points are the truth and the tracks in view "
        "that the tracker holds possible drones the hypotheses (classed drone, or not "
        "classed static or bird with p_drone ≥ 0.2), matched within the 4 m correct "
        "radius (metrics.json's mot).",
    ),
    MetricGroup(
        "Classes",
        (
            "drone_as_drone_pct",
            "bird_as_drone_pct",
            "none_as_drone_pct",
            "static_tracks",
            "static_to_class_median_s",
            "static_to_class_max_s",
            "static_late",
            "static_held_s",
        ),
        "metrics.json's classes.  A track-frame follows the truth object nearest within "
        "the correct radius, none if there is none (the static scene, clutter, or a "
        "track coasting away from what it followed); counted from 2 s of track life.  "
        "<kind>_as_drone_pct: that kind's track-frames classed drone.  static_tracks: "
        "tracks that only ever follow none (or a static object) and never move more "
        "than the radius from their birth; static_to_class: their time from birth to "
        "their first static class, over those classed; static_late: those not "
        "classed static within 3 s although they lived that long; static_held_s: how "
        "long the turret's lock was on one of them.  confusion.md has each case's matrix.",
    ),
)
MULTI_METRICS = tuple(m for g in MULTI_GROUPS for m in g.metrics)
# One line a case: the case is named after its scenario.
MULTI_SCENARIOS = (
    "outdoor-two-drones",
    "outdoor-swarm",
    "outdoor-clutter",
    "default",
    "outdoor-unscanned",
    "site-busy",
    "mid360-static",
)
MULTI_SUITE = Suite(
    name="multi",
    title="Several objects: every drone, the multi-object figures and the classes",
    methods=("pf-delta",),
    cases=tuple(Case(name, name, None) for name in MULTI_SCENARIOS),
    metrics=MULTI_METRICS,
    lockstep=False,
    acquisition=True,
    groups=MULTI_GROUPS,
    note=(
        "Each scenario as it is named, with its own turret mode (tracking; the "
        "static Mid-360 of mid360-static held still) and acquisition on, the "
        "turret shared among the drones where the scenario turns [pipeline.choose] "
        "on (outdoor-two-drones, outdoor-swarm).  A run where a figure does not "
        "exist (no drone acquired, no static track) leaves it out of the mean."
    ),
)
