"""What each track is (``classify``): the per-frame observations, a track's life, the
rules, and the classes of a simulated run's tracks against the simulator's truth."""

from __future__ import annotations

import collections
from dataclasses import replace

import numpy as np
import pytest

from dronetrack.classify.features import SEEN_GAP_S, LifeFeatures, TrackLives
from dronetrack.classify.observe import observe, view_floor
from dronetrack.classify.rules import (
    BIRD,
    DRONE,
    FAR_OBSERVED,
    STATIC,
    UNKNOWN,
    WORLD_SHARE,
    ClassRules,
    classify,
    in_open_air,
)
from dronetrack.detect.crowding import CROWD_RAD, nearest_gap
from dronetrack.errors import ConfigError
from dronetrack.sim.world import FrameTruth
from dronetrack.types import TRACK_CLASSES, Detections, Sample, StepResult, Tracks

T = 0.1


def _tracks(positions: list[list[float]], velocities: list[list[float]], ids: list[int]) -> Tracks:
    k = len(ids)
    return Tracks(
        ids=np.array(ids),
        positions=np.array(positions, dtype=float).reshape(k, 3),
        velocities=np.array(velocities, dtype=float).reshape(k, 3),
        covariances=np.tile(0.01 * np.eye(6), (k, 1, 1)),
        born=np.zeros(k),
        updated=np.ones(k, dtype=bool),
        hovered=np.zeros(k, dtype=bool),
        locked=np.zeros(k, dtype=bool),
        clusters=np.arange(k),
    )


def _found(centroids: list[list[float]], lows: list[float], extent: float = 0.4) -> Detections:
    k = len(lows)
    return Detections(
        np.array(centroids, dtype=float).reshape(k, 3),
        np.full(k, 6),
        np.tile([extent, 0.2, 0.1], (k, 1)),
        np.zeros((k, 3, 3)),
        np.zeros(k),
        np.array(lows, dtype=float),
    )


def test_observations_say_grounded_joined_and_beyond_reach() -> None:
    pos = [[20.0, 0, 10], [30.0, 0, 1.4], [200.0, 0, 10], [25.0, 5, 1.05]]
    tracks = _tracks(pos, [[0, 0, 0]] * 4, [1, 2, 3, 4])
    found = _found(pos, [9.8, 0.5, 9.8, 1.0])
    ground = np.array([0.0, 0.2, 0.0, np.nan])

    def near_wall(points: np.ndarray) -> np.ndarray:  # a wall at x ≥ 200.5
        return points[:, 0] >= 200.5

    obs = observe(
        tracks,
        found,
        np.zeros(3),
        ground,
        floor_z=1.0,
        limit_m=195.0,
        is_background=near_wall,
    )
    # in the air; bottom 0.3 m over a 0.2 m ground; in the air far out; cut by the floor
    assert obs.grounded.tolist() == [False, True, False, True]
    assert obs.beyond_reach.tolist() == [False, False, True, False]  # 200 m > 195 m
    assert obs.joined.tolist() == [False, False, True, False]  # the probe at x + 0.7 m
    np.testing.assert_allclose(obs.extent, 0.4)


def test_the_gap_to_the_nearest_cluster_is_between_their_extents() -> None:
    # clusters 0.4 m long: 3 m apart centre to centre is a 2.6 m gap; alone is +inf
    found = _found([[50.0, 0, 10], [53.0, 0, 10], [50.0, 40, 10]], [9.8] * 3)
    np.testing.assert_allclose(nearest_gap(found, np.array([0, 1, 2])), [2.6, 2.6, 39.6])
    alone = _found([[50.0, 0, 10]], [9.8])
    assert nearest_gap(alone, np.array([0])).tolist() == [np.inf]


def test_a_cluster_with_a_neighbour_within_the_gap_is_crowded() -> None:
    # a fragment of a far structure 1.6 m from the next, and a drone 30 m from anything
    pos = [[150.0, 0, 12], [152.0, 0, 12], [60.0, 20, 15]]
    tracks = _tracks(pos, [[0, 0, 0]] * 3, [1, 2, 3])
    obs = observe(tracks, _found(pos, [11.8, 11.8, 14.8]), np.zeros(3), np.zeros(3))
    assert not obs.crowded.any()  # the feature is off without a gap
    obs = observe(
        tracks, _found(pos, [11.8, 11.8, 14.8]), np.zeros(3), np.zeros(3), crowd_gap_m=2.0
    )
    assert obs.crowded.tolist() == [True, True, False]


def test_near_the_sensor_a_cluster_a_metre_away_is_another_object_not_a_fragment() -> None:
    # gap ≤ min(g_c, θ_c r): a drone 2.4 m out with a person 1 m beside it; the same
    # pair 150 m out, where the sampling leaves gaps that wide in one object
    near = [[2.4, 0, 1.5], [2.4, 1.4, 1.0]]
    far = [[150.0, 0, 12], [150.0, 1.4, 12]]
    for pos, crowded in ((near, False), (far, True)):
        tracks = _tracks(pos, [[0, 0, 0]] * 2, [1, 2])
        found = _found(pos, [p[2] - 0.2 for p in pos])
        obs = observe(tracks, found, np.zeros(3), np.zeros(3), crowd_gap_m=2.0)
        assert obs.crowded.tolist() == [crowded, crowded]
    assert CROWD_RAD * 2.4 < 1.0 < CROWD_RAD * 150.0


def test_a_still_fragment_among_fragments_in_the_air_is_no_hovering_drone() -> None:
    lives = TrackLives(hover_speed=4.0, hover_frames=3)
    pos = [[150.0, 0, 12], [152.0, 0, 12], [60.0, 20, 15]]
    life = None
    for k in range(16):  # 1.5 s, all three still in the air, none on the ground
        tracks = _tracks(pos, [[0, 0, 0]] * 3, [1, 2, 3])
        found = _found(pos, [11.8, 11.8, 14.8])
        obs = observe(tracks, found, np.zeros(3), np.zeros(3), limit_m=195.0, crowd_gap_m=2.0)
        life = lives.update(k * T, tracks, obs)
    assert life is not None
    classes, p = classify(life)
    # crowded: −3, and its hover tells it from a bird only, not from the world, which
    # holds still too: unlikely (below a look's 0.2), not drone; nor static, which
    # crowded alone never makes (two drones hovering close are crowded too)
    assert classes.tolist() == [UNKNOWN, UNKNOWN, DRONE]
    assert p[0] == pytest.approx(1.0 / (1.0 + np.exp(3.0)))
    assert p[0] < 0.2
    assert p[2] > 0.95


def test_a_hover_among_fragments_is_no_hover_in_free_space_where_the_track_goes_next() -> None:
    # a track holds still 1 s beside another cluster (crowded), then follows a flier in
    # free space (a track whose gate grew while it went unseen can take one far away)
    lives = TrackLives(hover_speed=4.0, hover_frames=3)
    life = None
    for k in range(11):
        pos = [[150.0, 0, 12], [151.5, 0, 12]]
        tracks = _tracks(pos, [[0, 0, 0]] * 2, [1, 2])
        found = _found(pos, [11.8, 11.8])
        obs = observe(tracks, found, np.zeros(3), np.zeros(2), limit_m=195.0, crowd_gap_m=2.0)
        life = lives.update(k * T, tracks, obs)
    assert life is not None
    assert life.crowded[0] == 1.0
    assert life.hovered[0]
    assert not life.hovered_free[0]
    for k in range(11, 40):  # 2.9 s at 10 m/s, alone in the air
        pos = [[100.0 + (k - 11), 30, 20]]
        tracks = _tracks(pos, [[10.0, 0, 0]], [1])
        obs = observe(tracks, _found(pos, [19.8]), np.zeros(3), np.zeros(1), limit_m=195.0)
        life = lives.update(k * T, tracks, obs)
    assert life.crowded[0] < 0.5  # the world's evidence is gone from its life
    assert life.hovered[0]
    assert not life.hovered_free[0]
    classes, _ = classify(life)
    assert classes[0] != DRONE  # with the hover among fragments counted: p 0.98, a drone


def test_the_top_of_a_mast_stands_on_its_pole_and_a_drone_has_free_air_below() -> None:
    """A mast's top 125 m out and 12 m up holds still in the open air as a hovering drone
    does; the returns of its pole just below it say it is propped: static, not a drone.
    Returns beside a drone (more than max(0.5 m, 5 mrad × r) across), far below it, or
    the ground's, say nothing."""
    rng = np.random.default_rng(3)
    top, drone = np.array([125.0, 0.0, 12.0]), np.array([60.0, 20.0, 15.0])
    lives = TrackLives(hover_speed=4.0, hover_frames=3)
    life = None
    for k in range(16):  # 1.5 s, both still
        pole = np.column_stack([rng.normal(125.0, 0.1, 6), rng.normal(0.0, 0.1, 6)])
        pole = np.column_stack([pole, rng.uniform(0.0, 11.7, 6)])
        pole[0, 2] = 11.0  # one return a metre below the top
        others = np.array(
            [[60.9, 20.0, 14.5], [60.0, 20.0, 12.0], [60.0, 20.0, 0.2], [125.0, 0.0, 12.5]]
        )  # beside, 3 m below and on the ground under the drone; above the top
        tracks = _tracks([list(top), list(drone)], [[0, 0, 0]] * 2, [1, 2])
        found = _found([list(top), list(drone)], [11.8, 14.8])
        obs = observe(
            tracks,
            found,
            np.zeros(3),
            np.zeros(2),
            limit_m=195.0,
            below=np.concatenate([pole, others]),
        )
        assert obs.propped.tolist() == [True, False]
        life = lives.update(k * T, tracks, obs)
    assert life is not None
    classes, p = classify(life)
    assert classes.tolist() == [STATIC, DRONE]
    # −3 propped; its hover says nothing of a structure, which holds still too
    assert p[0] == pytest.approx(1.0 / (1.0 + np.exp(3.0)))


def test_a_pole_seen_in_a_quarter_of_the_frames_props_its_top_and_chance_returns_do_not() -> None:
    """Sparse evidence counts from a fifth of the observations (``WORLD_SHARE``): a thin
    pole the pattern samples in one frame of four (s = 0.25) props its top, which is
    then static; returns that happen to lie below a hovering drone in one frame of
    twelve (s = 0.08, below s* for any ε under 0.04 with q = 0.29) leave it a drone."""
    rng = np.random.default_rng(5)
    top, drone = np.array([100.0, 0.0, 3.5]), np.array([60.0, 20.0, 15.0])
    lives = TrackLives(hover_speed=4.0, hover_frames=3)
    life = None
    frames = 24
    for k in range(frames):
        below = [np.empty((0, 3))]
        if k % 4 == 0:  # the pole, 0.5-2.5 m below the top
            x = rng.normal(100.0, 0.05, 3)
            below.append(np.column_stack([x, np.zeros(3), [2.5, 2.0, 1.5]]))
        if k % 12 == 6:  # a return 1 m below the drone
            below.append(np.array([[60.0, 20.0, 13.8]]))
        tracks = _tracks([list(top), list(drone)], [[0, 0, 0]] * 2, [1, 2])
        found = _found([list(top), list(drone)], [3.1, 14.8])
        obs = observe(
            tracks, found, np.zeros(3), np.zeros(2), limit_m=195.0, below=np.concatenate(below)
        )
        assert obs.propped.tolist() == [k % 4 == 0, k % 12 == 6]
        life = lives.update(k * T, tracks, obs)
    assert life is not None
    np.testing.assert_allclose(life.propped, [6 / frames, 2 / frames])
    assert life.propped[1] < WORLD_SHARE <= life.propped[0]
    classes, _ = classify(life)
    assert classes.tolist() == [STATIC, DRONE]


def test_a_fragment_that_wanders_over_a_mapped_crown_is_static_and_a_person_is_not() -> None:
    """Fragments of a tree's crown 150 m out, beside the map's cells in every frame,
    land up to 3 m apart: more than the 1.5 m a still object may wander there, within
    2 θ_c r (5.2 m), and it hovered in the air beside the mapped world, so static.  A
    drone that wanders as far in free air (no cell beside it), across (its heights keep
    within its size: ``test_a_pole_sampled_at_random_heights_is_taller_than_a_drone``),
    is not; nor is a person
    beside a mapped wall (grounded), who may stand and walk; nor a board carried at
    1 m/s along another wall 12 m out, in the air (2 m in 2 s, beyond 2 θ_c r)."""
    rng = np.random.default_rng(11)
    crown, drone, person = [150.0, 0.0, 8.0], [60.0, 20.0, 15.0], [30.0, -5.0, 0.9]
    board = np.array([12.0, 8.0, 1.5])
    lives = TrackLives(hover_speed=4.0, hover_frames=3)
    life = None

    def mapped(points: np.ndarray) -> np.ndarray:  # the crown's cells, and two walls
        near_crown = np.linalg.norm(points - crown, axis=1) < 4.0
        wall = (np.abs(points[:, 1] + 5.0) < 1.0) & (points[:, 0] < 40.0)
        return near_crown | wall | (np.abs(points[:, 1] - 9.0) < 0.5) & (points[:, 0] < 20.0)

    for k in range(20):
        # each frame's cluster somewhere on its object: ±1.5 m along x and z (the
        # drone's along x only)
        jitter = rng.uniform(-1.5, 1.5, (3, 2))
        pos = np.array([crown, drone, person]) + np.column_stack(
            [jitter[:, 0], np.zeros(3), jitter[:, 1] * [1.0, 0.0, 0.0]]
        )
        pos = np.vstack([pos, board - [1.0 * k * T, 0.0, 0.0]])
        velocities = [[0, 0, 0]] * 3 + [[-1.0, 0, 0]]
        tracks = _tracks(pos.tolist(), velocities, [1, 2, 3, 4])
        feet = 0.7 if k < 5 else 0.05  # the person's legs missed in the first frames
        found = _found(pos.tolist(), [pos[0, 2] - 0.2, pos[1, 2] - 0.2, feet, 1.2])
        obs = observe(tracks, found, np.zeros(3), np.zeros(4), limit_m=195.0, is_background=mapped)
        assert obs.joined.tolist() == [True, False, True, True]
        assert obs.grounded.tolist() == [False, False, k >= 5, False]
        life = lives.update(k * T, tracks, obs)
    assert life is not None
    assert np.all(life.moved[:3] > 0.01 * 150.0)  # none still by the wander bound
    assert life.moved[3] > 2 * np.radians(1.0) * 12.0
    assert life.hovered.all()  # the person too, in the air in its first frames
    classes, _ = classify(life)
    assert classes[0] == STATIC
    assert STATIC not in classes[1:].tolist()


def test_on_the_ground_a_fragment_beside_the_map_is_static_where_its_fragments_land() -> None:
    """On the ground nothing hovers, so a grounded track joined in half its observations,
    or beyond reach, whose clusters land within 2 θ_c r of the first is static without a
    hover: the base of a far structure 150 m out, its fragments up to 3 m apart (more
    than the 1.5 m a still object may wander there, within 2 θ_c r = 5.2 m), and one
    220 m out, beyond reach, with no map cell beside it, its fragments up to 5 m apart
    (2 θ_c r = 7.7 m).  Not static: the base 150 m out with no map cell beside it, one
    whose fragments land 12 m apart, and a person walking at 1.4 m/s beside a mapped
    wall 108 m out, once past 2 θ_c r (3.8 m)."""
    rng = np.random.default_rng(5)
    base, bare, wide = [150.0, 0.0, 1.0], [0.0, 150.0, 1.0], [-150.0, 0.0, 1.0]
    far = [0.0, -220.0, 1.0]
    walker = np.array([100.0, 40.0, 0.9])
    spread = [1.5, 1.5, 6.0, 2.5]  # each frame's cluster within ±spread m along the ground
    lives = TrackLives(hover_speed=4.0, hover_frames=3)
    life, walker_static = None, []

    def mapped(points: np.ndarray) -> np.ndarray:  # cells beside the base, the wide one
        # and along the wall the person walks by; none beside the bare base
        near = [np.linalg.norm(points[:, :2] - c[:2], axis=1) < 6.0 for c in (base, wide)]
        wall = (np.abs(points[:, 1] - 41.0) < 1.0) & (np.abs(points[:, 0] - 100.0) < 20.0)
        return np.asarray(near[0] | near[1] | wall)

    for k in range(40):
        jitter = rng.uniform(-1.0, 1.0, 4) * spread
        pos = np.array(
            [
                np.add(base, [jitter[0], 0.0, 0.0]),
                np.add(bare, [0.0, jitter[1], 0.0]),
                np.add(wide, [jitter[2], 0.0, 0.0]),
                np.add(walker, [1.4 * k * T, 0.0, 0.0]),
                np.add(far, [jitter[3], 0.0, 0.0]),
            ]
        )
        velocities = [[0, 0, 0]] * 3 + [[1.4, 0, 0], [0, 0, 0]]
        tracks = _tracks(pos.tolist(), velocities, [1, 2, 3, 4, 5])
        found = _found(pos.tolist(), [0.05] * 5)
        obs = observe(tracks, found, np.zeros(3), np.zeros(5), limit_m=195.0, is_background=mapped)
        assert obs.grounded.all()
        assert obs.joined.tolist() == [True, False, True, True, False]
        assert obs.beyond_reach.tolist() == [False] * 4 + [True]
        life = lives.update(k * T, tracks, obs)
        classes, _ = classify(life)
        if classes[3] == STATIC:
            walker_static.append(k * T)
    assert life is not None
    assert np.all(life.moved[:3] > 0.01 * 150.0)  # none still by the wander bound
    assert life.moved[4] > 0.01 * 220.0
    assert life.moved[0] < 2 * CROWD_RAD * 150.0 < life.moved[2]
    assert life.moved[4] < 2 * CROWD_RAD * 220.0
    assert not life.hovered.any()
    classes, _ = classify(life)
    assert classes.tolist()[:3] == [STATIC, UNKNOWN, UNKNOWN]
    assert classes[4] == STATIC
    # the person is static only while within 2 θ_c r of where it was first seen
    assert classes[3] != STATIC
    assert max(walker_static, default=0.0) <= 2 * CROWD_RAD * life.range_m[3] / 1.4


def test_the_view_floor_is_the_lowest_elevation_in_each_azimuth_sector() -> None:
    sensor = np.array([0.0, 0.0, 1.0])
    # ground 9 m out at −7° (tan 7° × 8.14 = 1.0) ahead; a wall point behind, level
    ahead = [8.144, 0.0, 0.0]
    behind = [-10.0, 0.1, 1.0]
    floor = view_floor(np.array([ahead, [20.0, 0.0, 5.0], behind]), sensor, sectors=4)
    # sectors of 90° from −180°: behind (α = 179.4°) is sector 3, ahead (0°) sector 2
    np.testing.assert_allclose(floor[2], np.radians(-7.0), atol=1e-4)
    np.testing.assert_allclose(floor[3], 0.0, atol=1e-12)
    assert np.isnan(floor[:2]).all()
    assert np.isnan(view_floor(np.empty((0, 3)), sensor)).all()


def test_a_person_cut_off_by_the_view_floor_is_no_hovering_drone() -> None:
    """A Mid-360 1.1 m up sees nothing below 7° down: a person standing 4 m away is seen
    from 0.6 m up, legs cut off, holding still like a hovering drone.  Cut, it is not
    in the open air: unknown.  A drone hovering 2 m up beside it is seen whole."""
    sensor = np.array([0.0, 0.0, 1.136])
    bottom = sensor[2] - np.tan(np.radians(7.0)) * np.hypot(4.0, 0.5)  # 0.64 m up
    ground = np.array([[12.0, 0.0, 0.0], [12.0, 3.0, 0.0]])  # the floor, seen farther out
    floor = view_floor(ground, sensor)
    pos = [[4.0, 0.5, 1.2], [3.0, 2.0, 2.2]]
    lives = TrackLives(hover_speed=4.0, hover_frames=3)
    life = None
    for k in range(31):
        tracks = _tracks(pos, [[0, 0, 0]] * 2, [1, 2])
        found = _found(pos, [bottom + 0.005, 2.0])
        obs = observe(tracks, found, sensor, np.full(2, np.nan), floor=floor)
        assert obs.cut.tolist() == [True, False]
        life = lives.update(k * T, tracks, obs)
    assert life is not None
    classes, p = classify(life)
    assert classes.tolist() == [UNKNOWN, DRONE]
    assert p[0] == pytest.approx(0.5)
    # without the floor the person would hover in the open air
    obs = observe(tracks, found, sensor, np.full(2, np.nan))
    assert not obs.cut.any()


def test_a_track_without_a_cluster_observes_nothing() -> None:
    tracks = _tracks([[20.0, 0, 10]], [[0, 0, 0]], [1])
    tracks = Tracks(
        **{f: getattr(tracks, f) for f in tracks.__slots__ if f != "updated"},
        updated=np.zeros(1, dtype=bool),
    )
    obs = observe(tracks, _found([[20.0, 0, 10]], [9.9]), np.zeros(3), np.zeros(1), floor_z=50.0)
    assert not obs.updated[0]
    assert not obs.grounded[0]
    assert np.isnan(obs.extent[0])


def _life(seconds: float, position: np.ndarray, velocity: np.ndarray, low: float) -> LifeFeatures:
    """A track's life over ``seconds`` at ``position`` + ``velocity`` t, its bottom ``low``
    below its centre, over flat ground at z = 0."""
    lives = TrackLives(hover_speed=4.0, hover_frames=3)
    life = None
    for k in range(round(seconds / T) + 1):
        p = position + velocity * k * T
        tracks = _tracks([list(p)], [list(velocity)], [7])
        found = _found([list(p)], [p[2] - low])
        obs = observe(tracks, found, np.zeros(3), np.zeros(1), floor_z=1.0, limit_m=195.0)
        life = lives.update(k * T, tracks, obs)
    assert life is not None
    return life


def test_a_drone_hovering_in_the_air_is_a_drone_and_not_static() -> None:
    life = _life(3.0, np.array([40.0, 5.0, 20.0]), np.zeros(3), 0.1)
    assert life.hovered[0]
    assert life.moved[0] == pytest.approx(0.0)
    classes, p = classify(life)
    assert classes[0] == DRONE
    assert p[0] > 0.95


def test_a_still_object_on_the_ground_is_static_after_a_second() -> None:
    short = _life(0.5, np.array([40.0, 5.0, 1.5]), np.zeros(3), 0.6)
    assert classify(short)[0][0] != STATIC  # too young to tell
    life = _life(1.5, np.array([40.0, 5.0, 1.5]), np.zeros(3), 0.6)
    classes, p = classify(life)
    assert classes[0] == STATIC
    assert p[0] < 0.05


def test_a_still_object_beyond_the_drones_reach_is_static() -> None:
    life = _life(1.5, np.array([220.0, 0.0, 3.0]), np.zeros(3), 0.5)
    assert classify(life)[0][0] == STATIC


def test_beyond_reach_three_clusters_tell_a_still_object_static() -> None:
    """A far structure's few returns update its track in one frame of three or four:
    watched 1.5 s in three clusters 220 m out, beyond reach, it held still and is
    static; in two it is not yet (one displacement is no still test).  Within reach
    (150 m) so is a track as sparse whose every observation showed the world (here
    the ground); one that showed free air in one of its three needs ``min_observed``
    (5)."""
    rules = ClassRules()
    assert rules.min_observed > FAR_OBSERVED
    for x, clusters, world, static in (
        (220.0, FAR_OBSERVED, 2 / 3, True),
        (220.0, FAR_OBSERVED - 1, 1.0, False),
        (150.0, FAR_OBSERVED, 1.0, True),
        (150.0, FAR_OBSERVED - 1, 1.0, False),
        (150.0, FAR_OBSERVED, 2 / 3, False),
        (150.0, rules.min_observed, 2 / 3, True),
    ):
        life = _life(1.5, np.array([x, 0.0, 1.5]), np.zeros(3), 0.6)  # on the ground
        assert life.grounded[0] == 1.0
        sparse = replace(
            life,
            observed=np.array([clusters]),
            grounded=np.array([world]),
            world_seen=np.array([world]),
        )
        assert bool(classify(sparse, rules)[0][0] == STATIC) is static, (x, clusters, world)


def test_observations_made_before_the_ground_was_known_are_judged_once_it_is() -> None:
    """Without a clean scan, the ground under a far object may not be known at its
    first observation: its bottom 0.2 m up is then not grounded.  Once an observation
    knows the ground there (g = 0), the earlier one counts as grounded and as showing
    the world, so three clusters on the ground tell it static (``FAR_OBSERVED``).  A
    drone whose bottom is 7.8 m up stays in the air; an object whose next cluster
    moved 3 m across, past half a 5 m ground cell, is not judged by another cell's
    ground."""
    rules = ClassRules()
    ends = {}
    for name, low, step_y in (("object", 0.2, 0.0), ("drone", 7.8, 0.0), ("moving", 0.2, 3.0)):
        lives = TrackLives(ground_cell_m=5.0)
        for k, g in enumerate((np.nan, 0.0, 0.0)):
            p = [150.0, step_y * k, low + 1.0]
            tracks = _tracks([p], [[0.0, 0.0, 0.0]], [7])
            obs = observe(tracks, _found([p], [low]), np.zeros(3), np.array([g]))
            assert np.isnan(obs.lift[0]) == np.isnan(g)
            assert obs.low[0] == low
            life = lives.update(0.6 * k, tracks, obs)
            if k == 0:
                assert life.grounded[0] == 0.0
                assert life.world_seen[0] == 0.0
        ends[name] = life
    assert ends["object"].grounded[0] == 1.0
    assert ends["object"].world_seen[0] == 1.0
    assert classify(ends["object"], rules)[0][0] == STATIC
    assert ends["drone"].grounded[0] == 0.0
    assert ends["drone"].world_seen[0] == 0.0
    assert ends["moving"].grounded[0] == pytest.approx(2 / 3)
    assert classify(ends["moving"], rules)[0][0] != STATIC


def test_what_holds_still_beyond_the_drones_reach_is_static_however_its_returns_wander() -> None:
    # a far structure's few returns land anywhere on it: its track creeps at 1 m/s, 3 m
    # in 3 s, more than the still bound (2.2 m at 220 m), but it hovered
    creep = np.array([1.0, 0.0, 0.0])
    far = _life(3.0, np.array([220.0, 0.0, 8.0]), creep, 0.3)
    assert far.hovered[0]
    assert far.moved[0] > 0.01 * 220.0
    assert classify(far)[0][0] == STATIC
    near = _life(3.0, np.array([40.0, 5.0, 20.0]), creep, 0.1)  # in reach: a drone
    assert classify(near)[0][0] == DRONE


def test_a_fast_flier_that_never_hovered_grows_bird_like_with_the_time_watched() -> None:
    v = np.array([9.0, 4.0, 0.5])
    rules = ClassRules()
    at = np.array([40.0, -20.0, 25.0])
    # 2 s of steady flight is what a drone in flight does often: unknown, worth a look
    young = _life(2.0, at, v, 0.1)
    classes, p = classify(young, rules)
    assert classes[0] == UNKNOWN
    assert p[0] > rules.bird_p
    # the odds fall by exp(−T/μ): p = 1 / (1 + exp(T/μ)), a bird once T > μ ln 4
    life = _life(7.0, at, v, 0.1)
    classes, p = classify(life, rules)
    assert life.seen_s[0] == pytest.approx(7.0)
    assert p[0] == pytest.approx(1.0 / (1.0 + np.exp(7.0 / rules.steady_flight_s)))
    assert classes[0] == BIRD


def test_the_time_watched_leaves_out_the_time_a_track_was_out_of_view() -> None:
    lives = TrackLives()
    v = np.array([9.0, 0.0, 0.0])
    stamps = [0.1 * k for k in range(11)] + [5.0 + 0.1 * k for k in range(6)]
    for t in stamps:  # watched 1 s, out of view 4 s, watched 0.5 s
        p = np.array([40.0, 0.0, 25.0]) + v * t
        tracks = _tracks([list(p)], [list(v)], [3])
        obs = observe(tracks, _found([list(p)], [p[2] - 0.1]), np.zeros(3), np.zeros(1))
        life = lives.update(t, tracks, obs)
    assert life.age[0] == pytest.approx(5.5)
    # Σ min(Δt, SEEN_GAP_S): the 4 s gap counts SEEN_GAP_S only
    assert life.seen_s[0] == pytest.approx(1.5 + SEEN_GAP_S)


def test_a_slow_walker_on_the_ground_is_neither_drone_nor_bird() -> None:
    life = _life(4.0, np.array([30.0, 0.0, 1.4]), np.array([1.4, 0.0, 0.0]), 0.6)
    classes, p = classify(life)
    assert classes[0] == UNKNOWN
    assert p[0] < 0.05


def test_ended_tracks_are_forgotten() -> None:
    lives = TrackLives()
    for ids in ([1, 2], [2]):
        pos = [[10.0 * i, 0, 20] for i in ids]
        tracks = _tracks(pos, [[0, 0, 0]] * len(ids), ids)
        lives.update(
            0.0,
            tracks,
            observe(tracks, _found(pos, [19.9] * len(ids)), np.zeros(3), np.zeros(len(ids))),
        )
    assert len(lives) == 1


def test_bad_rules_are_refused() -> None:
    with pytest.raises(ConfigError, match="bird_p"):
        ClassRules(bird_p=0.9, drone_p=0.8)
    with pytest.raises(ConfigError, match="still_m"):
        ClassRules(still_m=0.0)


class _Labels:
    """For each tracking frame, each track's class and what it truly is: the drone or a
    bird within 2 m of it, else something else."""

    def __init__(self) -> None:
        self.rows: list[tuple[str, str, float]] = []

    def write(self, sample: Sample, result: StepResult) -> None:
        tracks, truth = result.tracks, sample.truth
        if tracks is None or not isinstance(truth, FrameTruth):
            return
        objects = [("drone", truth.target_position)]
        if truth.bird_positions is not None:
            objects += [("bird", b) for b in truth.bird_positions]
        for k in range(len(tracks)):
            gaps = [float(np.linalg.norm(tracks.positions[k] - q)) for _, q in objects]
            label = objects[int(np.argmin(gaps))][0] if min(gaps) <= 2.0 else "other"
            age = result.t - float(tracks.born[k])
            self.rows.append((label, TRACK_CLASSES[tracks.classes[k]], age))


@pytest.mark.slow
def test_in_clutter_the_drone_is_classed_drone_and_birds_almost_never() -> None:
    """``outdoor-clutter`` seeds 0-2 (66 s each, birds at 5-15 m/s): measured 86.8 % of
    the drone's track frames after 2 s of life classed drone and 1.8 % of the birds'
    frames; the bounds leave a few frames' margin on each."""
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.jobs.simulate import run_simulation

    counts: collections.Counter[tuple[str, str]] = collections.Counter()
    for seed in (0, 1, 2):
        labels = _Labels()
        run_simulation(
            get_scenario("outdoor-clutter").model_copy(update={"seed": seed}), sinks=[labels]
        )
        counts.update((lab, cls) for lab, cls, age in labels.rows if lab != "drone" or age >= 2.0)
    drone = sum(n for (lab, _), n in counts.items() if lab == "drone")
    bird = sum(n for (lab, _), n in counts.items() if lab == "bird")
    assert counts[("drone", "drone")] / drone >= 0.85
    assert counts[("bird", "drone")] / bird <= 0.02


@pytest.mark.slow
def test_the_drone_of_default_is_classed_drone_once_its_track_is_two_seconds_old() -> None:
    """``default`` seed 0, 25 s (the first 15 s of flight after the scan): every frame of
    the drone's track after 2 s of life is classed drone (it took off hovering)."""
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.jobs.simulate import run_simulation

    labels = _Labels()
    run_simulation(get_scenario("default").model_copy(update={"duration_s": 25.0}), sinks=[labels])
    drone = [cls for lab, cls, age in labels.rows if lab == "drone" and age >= 2.0]
    assert len(drone) > 100
    assert collections.Counter(drone)["drone"] == len(drone)


def test_a_person_walking_leaves_the_open_air_and_a_drone_lifting_off_stays_in_it() -> None:
    """On the ground in every observation (a person, 1.75 m tall, walking at 1.4 m/s
    with the crop's floor cutting off below 1 m): a = 0.7ᵏ falls below 0.2 at the fifth
    observation.  A drone climbing at 2 m/s from 1.2 m, grounded at first, stays in."""
    walker = [
        in_open_air(_life(k * T, np.array([30.0, 0.0, 1.4]), np.array([1.4, 0.0, 0.0]), 0.4))[0]
        for k in range(8)
    ]
    assert walker == [True, True, True, True, False, False, False, False]  # k + 1 obs
    drone = _life(2.0, np.array([40.0, 5.0, 1.2]), np.array([0.0, 0.0, 2.0]), 0.15)
    assert in_open_air(drone)[0]
    assert drone.aloft[0] > 0.9


def test_a_structures_evidence_takes_a_track_out_of_the_open_air_once_it_is_a_share() -> None:
    """Joined or propped in a fifth of its observations (``WORLD_SHARE``), once it has
    ``min_observed`` (5) of them, a track that stayed where it was first seen is part
    of a structure, not in the open air; under a fifth, or with fewer observations,
    the evidence is no share yet; and what flew in from afar is no structure (moved
    beyond 2 θ_c r: 3.5 m at 100 m)."""
    four = _life(0.3, np.array([100.0, 0.0, 3.5]), np.zeros(3), 0.1)
    five = _life(0.4, np.array([100.0, 0.0, 3.5]), np.zeros(3), 0.1)
    assert (int(four.observed[0]), int(five.observed[0])) == (4, 5)
    share = np.array([WORLD_SHARE])
    below = np.array([np.nextafter(WORLD_SHARE, 0.0)])
    assert in_open_air(five)[0]
    assert not in_open_air(replace(five, propped=share))[0]
    assert not in_open_air(replace(five, joined=share))[0]
    assert in_open_air(replace(five, propped=below, joined=below))[0]
    assert in_open_air(replace(four, propped=np.ones(1), joined=np.ones(1)))[0]
    assert not in_open_air(replace(five, joined=share, moved=np.array([3.4])))[0]
    assert in_open_air(replace(five, joined=share, moved=np.array([3.6])))[0]


def test_a_part_of_a_structure_in_the_air_is_static_where_its_fragments_land() -> None:
    """A sign board's fragments 100 m out, propped or joined in a fifth of the frames
    (``WORLD_SHARE``), land 2.5 m apart: beyond the 1 m a still object may wander
    there, within 2 θ_c r (3.5 m).  The selection already holds such a track out of
    the open air (``in_open_air``); it is static once it is old enough, whether or not
    its speed said it hovered.  Past 2 θ_c r it flew (a drone that stopped beside a
    mast); on the ground or cut by the view's floor it may be a person who walks."""
    base = _life(1.5, np.array([100.0, 0.0, 6.0]), np.zeros(3), 0.1)
    share = np.array([WORLD_SHARE])
    board = replace(base, moved=np.array([2.5]), hovered=np.zeros(1, dtype=bool))
    assert classify(board)[0][0] != STATIC  # free air: no evidence of a structure
    for evidence in ({"propped": share}, {"joined": share}):
        assert not in_open_air(replace(board, **evidence))[0]
        assert classify(replace(board, **evidence))[0][0] == STATIC
        assert classify(replace(board, moved=np.array([3.6]), **evidence))[0][0] != STATIC
        young = _life(0.8, np.array([100.0, 0.0, 6.0]), np.zeros(3), 0.1)
        assert classify(replace(young, moved=np.array([2.5]), **evidence))[0][0] != STATIC
        for person in ({"grounded": np.ones(1)}, {"cut": np.ones(1)}):
            assert classify(replace(board, **evidence, **person))[0][0] != STATIC


def test_an_heir_takes_the_life_of_the_track_at_rest_and_others_are_forgotten() -> None:
    """A still object on the ground, watched 1.5 s, is static; its track ends for room
    and rests (``track.rest``), and a birth on it is its heir: static from its first
    frame.  Without the inheritance it is too young to tell; a track that ended and
    does not rest is forgotten."""
    p = [40.0, 5.0, 1.5]

    def frame(lives: TrackLives, t: float, ident: int, **kw: object) -> LifeFeatures:
        tracks = _tracks([p], [[0, 0, 0]], [ident])
        obs = observe(tracks, _found([p], [p[2] - 0.6]), np.zeros(3), np.zeros(1), floor_z=1.0)
        return lives.update(t, tracks, obs, **kw)  # type: ignore[arg-type]

    outcomes = []
    for inherit in (True, False):
        lives = TrackLives(hover_speed=4.0, hover_frames=3)
        for k in range(16):
            life = frame(lives, k * T, 7)
        assert classify(life)[0][0] == STATIC
        rest = np.array([7])
        heirs = (np.array([12]), rest) if inherit else None
        heir = frame(lives, 1.8, 12, resting=rest, heirs=heirs)
        outcomes.append(int(classify(heir)[0][0]))
        assert heir.observed[0] == (17 if inherit else 1)
    assert outcomes[0] == STATIC
    assert outcomes[1] != STATIC
    lives = TrackLives()
    frame(lives, 0.0, 7)
    frame(lives, 0.1, 8, resting=np.array([7]))
    assert len(lives) == 2
    frame(lives, 0.2, 8)
    assert len(lives) == 1


def test_an_heir_counts_how_far_it_moved_from_its_own_first_cluster() -> None:
    """A fragment of a tree line 150 m out whose track crept 6 m along it (past the
    2 θ_c r = 5.2 m a fragment lands within) ends for room; the birth at its last fix
    is its heir, whose clusters land within 0.5 m of each other: its d_max is 0.5 m,
    not the chain's 6.5 m, while the rest of its life (its observations, its age) is
    the resting track's."""

    def frame(lives: TrackLives, t: float, ident: int, y: float, **kw: object) -> LifeFeatures:
        p = [150.0, y, 12.0]
        tracks = _tracks([p], [[0, 0, 0]], [ident])
        obs = observe(tracks, _found([p], [p[2] - 0.5]), np.zeros(3), np.zeros(1), floor_z=0.0)
        return lives.update(t, tracks, obs, **kw)  # type: ignore[arg-type]

    for inherit in (True, False):
        lives = TrackLives()
        for k in range(13):
            life = frame(lives, k * T, 7, 0.5 * k)
        assert life.moved[0] == pytest.approx(6.0)
        rest = np.array([7])
        heirs = (np.array([12]), rest) if inherit else None
        frame(lives, 1.5, 12, 6.0, resting=rest, heirs=heirs)
        heir = frame(lives, 1.6, 12, 6.5)
        assert heir.moved[0] == pytest.approx(0.5)
        assert heir.observed[0] == (15 if inherit else 2)
        assert heir.age[0] == pytest.approx(1.6 if inherit else 0.1)


def test_a_hover_counts_for_a_drone_only_where_the_world_showed_in_under_half_its_frames() -> None:
    """A low fragment of a structure 125 m out shows a different kind of the world's
    evidence from frame to frame: grounded in 4 of 10 observations and crowded in 3
    others, each under its own share of half, the world's in 7 of 10 together
    (``world_seen``: one observation counts once).  It held still in free space for three
    frames (``hovered_free``), but that hover counts for a drone no more.  With the
    world's evidence in 4 of 10 observations (a drone passing a mast and crossing
    another) the hover counts."""
    kinds = ["ground", "crowd"] * 3 + ["ground"] + ["free"] * 3
    lives = TrackLives(hover_speed=4.0, hover_frames=3)
    for k, kind in enumerate(kinds):
        pos = [[125.0, 0.0, 2.0], [125.0, 1.5, 2.0]]
        tracks = _tracks(pos, [[0, 0, 0]] * 2, [1, 2])
        # the fragment's bottom on the ground (z 0) or 1.5 m over it; its neighbour
        # beside it (1.5 m) or 40 m off
        low = 0.05 if kind == "ground" else 1.5
        if kind != "crowd":
            pos[1] = [125.0, 40.0, 2.0]
        obs = observe(tracks, _found(pos, [low, 1.5]), np.zeros(3), np.zeros(2), crowd_gap_m=2.0)
        life = lives.update(k * T, tracks, obs)
    assert (life.grounded[0], life.crowded[0], life.world_seen[0]) == (0.4, 0.3, 0.7)
    assert life.hovered_free[0]
    fragment = replace(
        life, **{name: getattr(life, name)[:1] for name in life.__dataclass_fields__}
    )
    assert classify(fragment)[0][0] != DRONE
    passing = replace(
        fragment, grounded=np.array([0.2]), crowded=np.array([0.2]), world_seen=np.array([0.4])
    )
    assert classify(passing)[0][0] == DRONE


def test_a_track_in_view_without_a_cluster_is_engulfed_where_an_oversized_cluster_holds_it() -> (
    None
):
    """Three tracks no cluster updated: one within ε (0.5 m) of a point of a cluster too
    large for a candidate, one 0.6 m from it, one on it but out of view; a fourth on it
    that a cluster updated.  Only the first is engulfed; with the test off, none is."""
    pos = [[100.0, 0, 3.2], [100.0, 0.0, 4.9], [100.0, 0, 3.0], [100.0, 0, 2.0]]
    tracks = _tracks(pos, [[0, 0, 0]] * 4, [1, 2, 3, 4])
    tracks = replace(
        tracks,
        updated=np.array([False, False, False, True]),
        clusters=np.array([-1, -1, -1, 0]),
        in_view=np.array([True, True, False, True]),
    )
    board = np.column_stack([np.full(15, 100.0), np.zeros(15), 1.5 + 0.2 * np.arange(15)])
    found = replace(_found([pos[3]], [1.8]), oversized=board)  # the board's top: z = 4.3
    obs = observe(tracks, found, np.zeros(3), np.zeros(4), engulf_m=0.5)
    assert obs.engulfed.tolist() == [True, False, False, False]
    off = observe(tracks, found, np.zeros(3), np.zeros(4))
    assert not off.engulfed.any()


def test_a_hover_in_free_space_engulfed_by_a_structure_is_the_structures_part() -> None:
    """A sign board's fragment 100 m out, seen as a few points at the rosette's edge,
    hovers in free space: a drone (p 0.98).  Once the turret centres it, the board and
    its pole return as one cluster larger than a drone; each frame it holds the track
    is an observation, a joined one.  One of nine is no share yet; two of ten are a
    fifth, the world's: no drone, out of the open air, and static once it is a second
    old."""
    lives = TrackLives(hover_speed=4.0, hover_frames=3)
    p = [100.0, 0.0, 3.5]
    board = np.column_stack([np.full(15, 100.0), np.zeros(15), 1.0 + 0.2 * np.arange(15)])
    for k in range(8):  # 0.7 s of a hover in free space
        tracks = _tracks([p], [[0, 0, 0]], [5])
        obs = observe(tracks, _found([p], [3.3]), np.zeros(3), np.zeros(1), floor_z=0.0)
        life = lives.update(k * T, tracks, obs)
    assert classify(life)[0][0] == DRONE
    assert in_open_air(life)[0]
    seen = []
    for k in range(8, 11):
        tracks = replace(
            _tracks([p], [[0, 0, 0]], [5]), updated=np.zeros(1, dtype=bool), clusters=np.array([-1])
        )
        found = replace(Detections.empty(), oversized=board)
        obs = observe(tracks, found, np.zeros(3), np.zeros(1), floor_z=0.0, engulf_m=0.5)
        assert obs.engulfed[0]
        life = lives.update(k * T, tracks, obs)
        cls, p_drone = classify(life)
        seen.append((TRACK_CLASSES[int(cls[0])], float(p_drone[0]), bool(in_open_air(life)[0])))
    assert [int(life.observed[0]), float(life.joined[0])] == [11, pytest.approx(3 / 11)]
    assert seen[0][0] == "drone"
    assert seen[0][2]
    assert seen[1][1] < 0.1
    assert not seen[1][2]
    assert seen[2][0] == "static"
