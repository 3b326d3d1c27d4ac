"""The pipeline on good and bad frames: it never crashes and never returns a NaN estimate."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dronetrack.config.pipeline import (
    AcquisitionConfig,
    BackgroundConfig,
    FieldOfRegardConfig,
    PipelineConfig,
    TrackerConfig,
)
from dronetrack.config.rig import make_turret
from dronetrack.geometry.transforms import make_pose
from dronetrack.pipeline import Pipeline
from dronetrack.pipeline.factory import build_pipeline
from dronetrack.track.multi import MultiTargetTracker
from dronetrack.types import Frame

TURRET = make_turret("widowx")


def _build(cfg: PipelineConfig) -> Pipeline:
    """``cfg``'s pipeline at 10 Hz on the test turret, seeded."""
    return build_pipeline(
        cfg,
        0.1,
        TURRET.mount,
        (TURRET.pan.lower, TURRET.pan.upper),
        (TURRET.tilt.lower, TURRET.tilt.upper),
        np.random.default_rng(0),
    )


def _pipeline(scan_s: float = 0.0, particles: int = 2000) -> Pipeline:
    cfg = PipelineConfig(
        background=BackgroundConfig(
            enabled=scan_s > 0, scan_s=scan_s, resolution_m=0.5, lookup_depth=0
        ),
        tracker=TrackerConfig(
            particles=particles,
            cylinder_center_m=(30.0, 0.0, 5.0),
            cylinder_radius_m=5.0,
            cylinder_height_m=5.0,
        ),
    )
    return _build(cfg)


def _frame(stamp: float, points: np.ndarray) -> Frame:
    """A frame from a sensor at 1 m height looking along +x (sensor frame = world − (0, 0, 1))."""
    n = len(points)
    pose = make_pose(np.eye(3), [0.0, 0.0, 1.0])
    return Frame(
        stamp,
        0.1,
        points - np.array([0.0, 0.0, 1.0]),
        np.full(n, stamp + 0.05),
        np.zeros(n, np.uint8),
        np.zeros(n, np.float32),
        np.array([stamp, stamp + 0.1]),
        np.stack([pose, pose]),
    )


def _drone(g: np.random.Generator, at: tuple[float, float, float] = (30.0, 0.0, 6.0)) -> np.ndarray:
    return np.array(at) + g.normal(0.0, 0.05, (6, 3))


def test_tracks_a_drone_and_commands_the_turret() -> None:
    g = np.random.default_rng(1)
    pipe = _pipeline()
    for k in range(20):
        result = pipe.step(_frame(0.1 * k, _drone(g)))
    assert result.estimate is not None
    assert result.estimate.tracked
    np.testing.assert_allclose(result.estimate.position, [30.0, 0.0, 6.0], atol=0.2)
    assert result.command is not None
    assert result.command.stamp == pytest.approx(result.t + 0.014)
    assert result.n_points == 6


# Frame stamps 0.1 k carry rounding (0.1 · 43 + 0.1 = 4.3999…): the scan still
# takes the frames that end by scan_s, to the nearest frame.
@pytest.mark.parametrize(("scan_s", "frames"), [(1.0, 10), (4.4, 44), (0.36, 4)])
def test_background_is_scanned_then_subtracted(scan_s: float, frames: int) -> None:
    g = np.random.default_rng(2)
    wall = np.column_stack([np.full(500, 40.0), g.uniform(-10, 10, 500), g.uniform(1, 9, 500)])
    pipe = _pipeline(scan_s=scan_s)
    phases = []
    for k in range(frames):
        phases.append(pipe.step(_frame(0.1 * k, wall)).phase)
    assert phases == ["scan"] * frames
    assert not pipe.scanning
    result = pipe.step(_frame(0.1 * frames, np.vstack([wall, _drone(g)])))
    assert result.phase == "track"
    assert result.n_points == 6  # the wall is gone, the drone is left


@pytest.mark.parametrize(
    ("make", "flag"),
    [
        (lambda g: np.empty((0, 3)), "empty"),
        (lambda g: np.full((5, 3), np.nan), "nonfinite_points"),
        (lambda g: np.vstack([_drone(g), [[np.inf, 0.0, 0.0]]]), "nonfinite_points"),
    ],
)
def test_bad_points_are_counted_and_survived(make, flag: str) -> None:  # type: ignore[no-untyped-def]
    g = np.random.default_rng(3)
    pipe = _pipeline()
    for k in range(10):
        pipe.step(_frame(0.1 * k, _drone(g)))
    result = pipe.step(_frame(1.0, make(g)))
    assert flag in result.flags
    assert pipe.counts[flag] == 1
    assert result.estimate is not None
    assert np.all(np.isfinite(result.estimate.position))


def test_frames_out_of_order_repeated_and_after_gaps() -> None:
    g = np.random.default_rng(4)
    pipe = _pipeline()
    for k in range(10):
        pipe.step(_frame(0.1 * k, _drone(g)))
    repeated = pipe.step(_frame(0.9, _drone(g)))
    assert "repeated" in repeated.flags
    assert repeated.command is None
    older = pipe.step(_frame(0.5, _drone(g)))
    assert "out_of_order" in older.flags
    # A 1 s gap: the filter predicts through it (10 periods) and carries on.
    after_gap = pipe.step(_frame(1.9, _drone(g)))
    assert "gap" in after_gap.flags
    assert (repeated.periods, older.periods, after_gap.periods) == (0, 0, 10)
    for result in (repeated, older, after_gap):
        assert result.estimate is not None
        assert np.all(np.isfinite(result.estimate.position))
    assert after_gap.estimate is not None
    np.testing.assert_allclose(after_gap.estimate.position, [30.0, 0.0, 6.0], atol=0.5)
    assert (pipe.counts["repeated"], pipe.counts["out_of_order"], pipe.counts["gap"]) == (1, 1, 1)


def test_the_filter_clock_follows_frames_at_another_rate() -> None:
    """Frames every 0.14 s against a 0.1 s filter period: no drift, no lost time."""
    g = np.random.default_rng(6)
    pipe = _pipeline()
    results = [pipe.step(_frame(0.14 * k, _drone(g))) for k in range(60)]
    periods = np.cumsum([r.periods for r in results[1:]])
    elapsed = 0.14 * np.arange(1, 60) / 0.1  # periods since the first frame
    assert np.all(np.abs(periods - elapsed) <= 0.5 + 1e-9)
    assert {r.periods for r in results[1:]} == {1, 2}
    assert sum("gap" in r.flags for r in results) == np.count_nonzero(
        [r.periods == 2 for r in results]
    )
    assert results[-1].estimate is not None
    np.testing.assert_allclose(results[-1].estimate.position, [30.0, 0.0, 6.0], atol=0.3)


@pytest.mark.parametrize("jump_to", [100.0, -50.0])
def test_a_jump_in_time_restarts_the_filter(jump_to: float) -> None:
    g = np.random.default_rng(7)
    pipe = _pipeline()
    for k in range(20):
        pipe.step(_frame(0.1 * k, _drone(g)))
    assert pipe.tracker.filter.tracked  # type: ignore[attr-defined]
    jumped = pipe.step(_frame(jump_to, _drone(g, at=(40.0, 5.0, 6.0))))
    assert "time_jump" in jumped.flags
    assert jumped.periods == 1
    assert jumped.estimate is not None
    # Restarted from the cylinder and updated once: not yet locked.
    assert not jumped.estimate.tracked
    after = pipe.step(_frame(jump_to + 0.1, _drone(g, at=(40.0, 5.0, 6.0))))
    assert after.flags == ()
    assert after.periods == 1
    assert pipe.counts["time_jump"] == 1


def test_bad_time_and_bad_poses() -> None:
    g = np.random.default_rng(5)
    pipe = _pipeline()
    pipe.step(_frame(0.0, _drone(g)))
    nan_time = replace(_frame(0.1, _drone(g)), stamp=math.nan)
    assert "bad_time" in pipe.step(nan_time).flags
    frame = _frame(0.2, _drone(g))
    bad_pose = replace(frame, pose_t=np.array([0.3, 0.3]))  # pose times must increase
    nan_pose = replace(
        _frame(0.3, _drone(g)), poses=np.full((2, 4, 4), np.nan)
    )  # a NaN pose from a broken sensor driver
    scaled = _frame(0.4, _drone(g))
    scaled = replace(scaled, poses=scaled.poses * np.array([2.0, 2.0, 2.0, 1.0])[:, None])
    for bad in (bad_pose, nan_pose, scaled):
        result = pipe.step(bad)
        assert "bad_pose" in result.flags
        assert result.n_points == 0
        assert result.estimate is not None
        assert np.all(np.isfinite(result.estimate.position))
    assert pipe.counts["bad_pose"] == 3


def _pipeline_with(acquisition: bool) -> Pipeline:
    cfg = PipelineConfig(
        background=BackgroundConfig(enabled=False),
        tracker=TrackerConfig(
            particles=2000,
            cylinder_center_m=(30.0, 0.0, 5.0),
            cylinder_radius_m=5.0,
            cylinder_height_m=5.0,
        ),
        acquisition=AcquisitionConfig(enabled=acquisition),
    )
    return _build(cfg)


def test_a_drone_far_from_the_start_cylinder_is_acquired_from_detections() -> None:
    """A drone 90 m out and 40 m to the side, flying at 12 m/s, and one false return
    per frame at random: the detect stage confirms the drone on its second frame (2 of
    4), the particles are born there and the filter locks on the third or fourth;
    without acquisition the cloud, 70 m away, never reaches it in 3 s."""
    v = np.array([-12.0, 0.0, 0.0])

    def run(acquisition: bool) -> list[tuple[bool, int, int]]:
        g = np.random.default_rng(4)
        pipe = _pipeline_with(acquisition)
        out = []
        for k in range(30):
            at = np.array([90.0, 40.0, 20.0]) + v * (0.1 * k + 0.1)
            false = g.uniform([5.0, -100.0, 2.0], [200.0, 100.0, 60.0], (1, 3))
            r = pipe.step(_frame(0.1 * k, np.vstack([_drone(g, tuple(at)), false])))
            assert r.estimate is not None
            good = r.estimate.tracked and float(np.linalg.norm(r.estimate.position - at)) < 1.0
            n = -1 if r.detections is None else len(r.detections)
            c = -1 if r.candidates is None else len(r.candidates)
            out.append((good, n, c))
        return out

    with_ = run(True)
    assert [n for _, n, _ in with_] == [2] * 30  # the drone and the false return
    assert with_[0][2] == 0
    assert all(c == 1 for _, _, c in with_[1:])  # only the drone persists
    first = next(k for k, (good, _, _) in enumerate(with_) if good)
    assert first <= 3
    assert all(good for good, _, _ in with_[first:])
    without = run(False)
    assert not any(good for good, _, _ in without)
    assert all(n == c == -1 for _, n, c in without)


def test_points_beyond_the_field_of_regard_are_no_target() -> None:
    """The crop box is the field's bounding box; the field itself cuts the corners: a
    return 110 m out at 34° pan lies in the box (|y| ≤ 100 sin 45°) but beyond the
    100 m range."""
    cfg = PipelineConfig(
        background=BackgroundConfig(enabled=False),
        field_of_regard=FieldOfRegardConfig(
            pan_deg=(-45.0, 45.0), tilt_deg=(-40.0, 5.0), range_m=100
        ),
    )
    pipe = _build(cfg)
    far = np.array([[90.0, 60.0, 20.0]])
    near = np.array([[60.0, 30.0, 10.0]])
    assert pipe.step(_frame(0.0, far)).n_points == 0
    assert pipe.step(_frame(0.1, np.vstack([far, near]))).n_points == 1


@pytest.mark.parametrize(
    ("seen", "other", "taken"),
    [(20, (30.0, 80.0, 20.0), False), (20, (30.0, 20.0, 6.0), True), (8, (30.0, 80.0, 20.0), True)],
)
def test_after_a_loss_only_what_the_drone_could_reach_starts_a_track(
    seen: int, other: tuple[float, float, float], taken: bool
) -> None:
    """Tracked at (30, 0, 6), the drone vanishes; another target then persists 80 m
    away, or 20 m away.  The reach since the last fix is v_max t + g = 15 t + 1 m: 80 m
    is out of reach for the 3 s that follow, so no track starts on it; 20 m is within
    reach after 1.3 s, so the filter starts and locks on it.  A lock shorter than
    ESTABLISHED_S (8 frames seen: locked for about 0.5 s) sets no gate."""
    g = np.random.default_rng(3)
    pipe = _pipeline_with(True)
    for k in range(seen):
        r = pipe.step(_frame(0.1 * k, _drone(g)))
    assert r.estimate is not None
    assert r.estimate.tracked
    locked_on_other = []
    for k in range(seen, seen + 30):
        r = pipe.step(_frame(0.1 * k, _drone(g, other)))
        assert r.estimate is not None
        near = float(np.linalg.norm(r.estimate.position - np.array(other))) < 1.0
        locked_on_other.append(r.estimate.tracked and near)
    assert any(locked_on_other) is taken


@pytest.mark.parametrize("kind", ["ekf-cv", "aekf-ca"])
def test_a_kalman_tracker_starts_on_the_drone_not_on_a_lone_false_return(kind: str) -> None:
    """Half a second of a flicker of clutter per frame (a clump of 4 returns at a random
    place, a cluster even for seed 002's detector, which needs 3 points), then a drone
    90 m out and 40 m to the side flying at 12 m/s, with the clutter going on.  Started
    by its confirmed candidates the filter waits, starts on the drone when it is
    confirmed (its third frame) and stays on it; started on its own (acquisition off)
    it starts on the first flicker."""
    v = np.array([-12.0, 0.0, 0.0])

    def run(acquisition: bool) -> tuple[list[bool], list[bool]]:
        g = np.random.default_rng(5)
        cfg = PipelineConfig(
            background=BackgroundConfig(enabled=False),
            tracker=TrackerConfig(kind=kind),  # type: ignore[arg-type]
            acquisition=AcquisitionConfig(enabled=acquisition),
        )
        pipe = _build(cfg)
        tracked, good = [], []
        for k in range(35):
            place = g.uniform([5.0, -100.0, 2.0], [200.0, 100.0, 60.0])
            false = place + g.normal(0.0, 0.1, (4, 3))
            at = np.array([90.0, 40.0, 20.0]) + v * (0.1 * k + 0.1)
            pts = false if k < 5 else np.vstack([_drone(g, tuple(at)), false])
            r = pipe.step(_frame(0.1 * k, pts))
            assert r.estimate is not None
            tracked.append(r.estimate.tracked)
            good.append(
                r.estimate.tracked and float(np.linalg.norm(r.estimate.position - at)) < 1.0
            )
        return tracked, good

    tracked, good = run(True)
    assert not any(tracked[:5])
    first = next(k for k, ok in enumerate(good) if ok)
    assert first <= 5 + 3  # confirmed on the drone's third frame, started at that frame's end
    assert all(good[first:])
    tracked_alone, good_alone = run(False)
    assert tracked_alone[0]
    assert not good_alone[0]


@pytest.mark.parametrize(("drone_speed", "moves"), [(0.0, True), (10.0, False)])
def test_a_lock_on_a_bird_gives_way_to_a_drone_that_hovers(drone_speed: float, moves: bool) -> None:
    """A bird at 8 m/s is the only target for 1.5 s, and the tracker locks on it; then a
    drone shows itself 60 m away.  Hovering, it is a multirotor (no bird can fly that
    slowly, ``detect.tentative``): the lock moves to it within half a second (confirmed
    on its 2nd frame, hovered on its 4th) and stays.  Flying at 10 m/s, it could be a
    bird as well: the lock stays where it is."""
    g = np.random.default_rng(5)
    pipe = _pipeline_with(True)
    bird0, v_bird = np.array([80.0, 40.0, 30.0]), np.array([0.0, -8.0, 0.0])
    drone0, v_drone = np.array([60.0, -30.0, 10.0]), np.array([drone_speed, 0.0, 0.0])
    on_bird, on_drone = [], []
    for k in range(45):
        t = 0.1 * k
        bird = bird0 + v_bird * t
        pts = [_drone(g, tuple(bird))]
        drone = drone0 + v_drone * max(t - 1.5, 0.0)
        if t >= 1.5:
            pts.append(_drone(g, tuple(drone)))
        r = pipe.step(_frame(t, np.vstack(pts)))
        assert r.estimate is not None
        on_bird.append(r.estimate.tracked and np.linalg.norm(r.estimate.position - bird) < 1.0)
        on_drone.append(r.estimate.tracked and np.linalg.norm(r.estimate.position - drone) < 1.0)
    assert all(on_bird[5:15])  # locked on the bird before the drone shows itself
    if moves:
        first = next(k for k in range(15, 45) if on_drone[k])
        assert first <= 15 + 6
        assert all(on_drone[first:])
    else:
        assert all(on_bird[15:])
        assert not any(on_drone)


def _ground(g: np.random.Generator) -> np.ndarray:
    """Returns from flat ground at z = 0 around the field (below the crop's 1 m floor)."""
    xy = g.uniform([5.0, -60.0], [120.0, 60.0], size=(300, 2))
    return np.column_stack([xy, g.normal(0.0, 0.02, 300)])


def test_a_lock_on_a_static_object_is_given_up_for_the_drone() -> None:
    """An object the background does not hold stands on the ground 40 m out (a crate or
    a bush, 1.6 × 1 × 1.2 m, its bottom cut by the crop's 1 m floor) and is alone in
    view: the tracker locks on it.  Once its track has been on the ground in nearly all
    its recent observations, or classed static (still for 1 s, grounded), for 0.5 s the
    lock is given up and the object is never offered
    again; a drone that then hovers 30 m up, 50 m away, is locked on and held.  Without
    the track layer's classes the lock stays on the crate."""
    car = (40.0, 10.0, 1.6)
    drone = (50.0, -20.0, 30.0)

    def run(classes: bool) -> tuple[list[bool], list[bool], list[str]]:
        g = np.random.default_rng(9)
        pipe = _pipeline_with(True)
        if not classes:
            pipe.classifier = None
        on_car, on_drone, car_class = [], [], []
        for k in range(60):
            t = 0.1 * k
            car_pts = np.array(car) + g.uniform([-0.8, -0.5, -0.6], [0.8, 0.5, 0.6], (12, 3))
            pts = [car_pts, _ground(g)]
            if t >= 3.0:
                pts.append(_drone(g, drone))
            r = pipe.step(_frame(t, np.vstack(pts)))
            assert r.estimate is not None
            est = r.estimate
            on_car.append(est.tracked and np.linalg.norm(est.position - car) < 2.5)
            on_drone.append(est.tracked and np.linalg.norm(est.position - drone) < 1.0)
            near = (
                [
                    r.tracks.class_names[k]
                    for k in range(len(r.tracks))
                    if r.tracks is not None and np.linalg.norm(r.tracks.positions[k] - car) < 2.5
                ]
                if r.tracks is not None
                else []
            )
            car_class.append(near[0] if near else "")
        return on_car, on_drone, car_class

    on_car, on_drone, car_class = run(True)
    assert any(on_car[:10])  # the car alone in view is locked first
    static_from = car_class.index("static")
    assert static_from <= 10 + 20  # classed static within 2 s of its track's birth
    # given up once on the ground in nearly all its recent observations for 0.5 s, or
    # classed static for 0.5 s, whichever comes first
    assert not any(on_car[static_from + 6 :])  # held 0.5 s at most after its class
    first = next(k for k in range(30, 60) if on_drone[k])
    assert first <= 30 + 6
    assert all(on_drone[first:])
    on_car_alone, on_drone_alone, _ = run(False)
    assert all(on_car_alone[10:])
    assert not any(on_drone_alone)


def test_a_track_coasting_down_keeps_on_the_ground_the_classes_learn() -> None:
    """An object 40 m out descends at 5 m/s and is lost 1.5 m up; its track coasts on
    in view for its coasting time.  The classes learn the ground (z = 0) from the
    returns the crop drops, and the track keeps on or above it; without the classes
    there is no ground, and it sinks on below."""

    def lowest(classes: bool) -> float:
        g = np.random.default_rng(2)
        pipe = _pipeline_with(True)
        if not classes:
            pipe.classifier = None
        low = np.inf
        for k in range(40):
            at = (40.0, 5.0, 6.0 - 5.0 * (0.1 * k + 0.05))
            pts = [_ground(g)] + ([_drone(g, at)] if at[2] > 1.5 else [])
            r = pipe.step(_frame(0.1 * k, np.vstack(pts)))
            if r.tracks is not None and len(r.tracks):
                low = min(low, float(r.tracks.positions[:, 2].min()))
        return low

    assert -0.1 < lowest(classes=True) < 1.5
    assert lowest(classes=False) < -5.0


class _NoHeirs(MultiTargetTracker):
    """A track layer whose births are never heirs."""

    @property
    def heirs(self) -> tuple[np.ndarray, np.ndarray]:
        return np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64)


def test_a_crate_whose_track_ended_for_room_is_static_again_at_its_next_birth() -> None:
    """Three crates stand on the ground, and the track layer holds two tracks: at the
    cap the static ones end first (``track.multi``), and each crate's clusters give
    birth again.  A birth on a crate whose track ended for room is its heir
    (``track.rest``) and takes its life, so it is static from its first frame; without
    the inheritance every such birth starts again from nothing, unknown for a second."""
    crates = [(40.0, 10.0, 1.6), (50.0, -15.0, 1.6), (60.0, 25.0, 1.6)]

    def classes(inherit: bool) -> list[str]:
        g = np.random.default_rng(5)
        pipe = _pipeline_with(True)
        assert pipe.acquisition is not None
        assert pipe.acquisition.objects is not None
        kind = MultiTargetTracker if inherit else _NoHeirs
        layer = kind(replace(pipe.acquisition.objects.settings, max_tracks=2))
        pipe.acquisition = replace(pipe.acquisition, objects=layer)
        out: list[str] = []
        for k in range(80):
            pts = [
                np.array(c) + g.uniform([-0.8, -0.5, -0.6], [0.8, 0.5, 0.6], (12, 3))
                for c in crates
            ]
            r = pipe.step(_frame(0.1 * k, np.vstack([*pts, _ground(g)])))
            if k >= 30 and r.tracks is not None:
                out += list(r.tracks.class_names)
        return out

    heirs, none = classes(True), classes(False)
    assert len(heirs) > 50
    assert len(none) > 50
    share = heirs.count("static") / len(heirs)
    assert share > 0.9
    assert none.count("static") / len(none) < share - 0.2
