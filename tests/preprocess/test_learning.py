"""The background that keeps learning (preprocess/learning.py)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import InputError
from dronetrack.preprocess.learning import (
    N_CELLS,
    LearningBackground,
    LearningSettings,
    learnt_now,
    look_cells,
    looked_at,
    window_update,
)

PERIOD = 0.1
NO_BALLS = (np.empty((0, 3)), np.empty(0))


def _rays(rng: np.random.Generator, n: int = 3000) -> np.ndarray:
    """Unit directions in a cone ±0.3 rad across and ±0.2 rad up around +x."""
    az, el = rng.uniform(-0.3, 0.3, n), rng.uniform(-0.2, 0.2, n)
    return np.column_stack([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])


def _scene(rng: np.random.Generator, car: bool, wall_m: float = 30.0) -> np.ndarray:
    """A static sensor at the origin looking along +x at a wall ``wall_m`` away; with
    ``car``, a 2 m wide, 1.5 m tall box 10 m out in front of it."""
    d = _rays(rng)
    r = wall_m / d[:, 0]
    if car:
        at = 10.0 / d[:, 0]
        inside = (np.abs(d[:, 1] * at) < 1.0) & (np.abs(d[:, 2] * at) < 0.75)
        r = np.where(inside, at, r)
    return d * r[:, None]


def _run(
    model: LearningBackground,
    seconds: float,
    car: object,
    rng: np.random.Generator,
    protect: tuple[np.ndarray, np.ndarray] = NO_BALLS,
) -> list[tuple[float, bool]]:
    """Feed ``seconds`` of frames (the car present where ``car(t)``; candidates: what is
    nearer than the wall, as if the wall were in the scanned map); per frame, (t, whether
    the car's centre is background)."""
    out = []
    pose = np.eye(4)
    for i in range(round(seconds / PERIOD)):
        t = i * PERIOD
        pts = _scene(rng, bool(car(t)))  # type: ignore[operator]
        model.observe(t, pts, pts, pose, pts[pts[:, 0] < 20.0], *protect)
        out.append((t, bool(model.is_background(np.array([[10.2, 0.1, 0.1]]))[0])))
    return out


def _first(series: list[tuple[float, bool]], value: bool, after: float) -> float:
    return next(t for t, v in series if t >= after and v == value)


def test_a_parked_car_is_learnt_after_the_look_time_and_fades_when_it_leaves() -> None:
    s = LearningSettings(memory_s=20.0, share=0.5, min_occupied_s=5.0)
    model = LearningBackground(s, PERIOD)
    series = _run(model, 60.0, lambda t: 10.0 <= t < 40.0, np.random.default_rng(0))
    learnt, faded = _first(series, True, 0.0), _first(series, False, 40.0)
    w = model.window_s
    # Learnt once occupied for min_occupied_s (L_min windows), within a window of that.
    assert 10.0 + s.min_occupied_s - w <= learnt <= 10.0 + s.min_occupied_s + 2 * w
    # Looked through (the wall behind returns) with no hit for L_min windows: gone.
    assert 40.0 + s.min_occupied_s - w <= faded <= 40.0 + s.min_occupied_s + 2 * w
    assert not any(v for t, v in series if t < 10.0 + s.min_occupied_s - w)


def test_a_car_that_stops_briefly_is_not_learnt() -> None:
    model = LearningBackground(LearningSettings(min_occupied_s=5.0), PERIOD)
    series = _run(model, 30.0, lambda t: 10.0 <= t < 13.0, np.random.default_rng(1))
    assert not any(v for _, v in series)


def test_what_a_track_holds_is_never_learnt() -> None:
    """The same car, inside a protected ball for the whole run, never enters the map;
    without the ball it does (the test can fail)."""
    rng = np.random.default_rng(2)
    ball = (np.array([[10.5, 0.0, 0.0]]), np.array([2.0]))
    held = LearningBackground(LearningSettings(), PERIOD)
    assert not any(v for _, v in _run(held, 30.0, lambda t: True, rng, ball))
    assert held.voxels == 0
    free = LearningBackground(LearningSettings(), PERIOD)
    assert any(v for _, v in _run(free, 30.0, lambda t: True, rng))


def test_voxels_nothing_hits_are_forgotten_after_the_memory() -> None:
    """One stray return makes a voxel with a history, gone T later: memory is bounded by
    what the last T seconds saw."""
    s = LearningSettings(memory_s=4.0, min_occupied_s=1.0)
    model = LearningBackground(s, PERIOD)
    pose = np.eye(4)
    stray = np.array([[50.0, 3.0, 2.0]])
    model.observe(0.0, stray, stray, pose, stray, *NO_BALLS)
    model.observe(0.6, stray[:0], stray[:0], pose, stray[:0], *NO_BALLS)
    assert model.voxels == 1
    for i in range(1, 70):
        model.observe(0.6 + i * PERIOD, stray[:0], stray[:0], pose, stray[:0], *NO_BALLS)
    assert model.voxels == 0
    assert len(model) == 0


def test_a_hovering_object_in_the_open_sky_fades_where_the_sensor_samples() -> None:
    """A kite 8 m up in a direction that returns nothing once it leaves: its voxel is
    looked at when that direction is one the sensor samples (it returned before), not
    when it is not."""
    pose = np.eye(4)
    kite = np.array([[20.0, 0.2, 8.2]])
    s = LearningSettings(memory_s=10.0, min_occupied_s=2.0)
    model = LearningBackground(s, PERIOD)
    t = 0.0
    for _ in range(40):  # 4 s: learnt
        model.observe(t, kite, kite, pose, kite, *NO_BALLS)
        t += PERIOD
    assert model.is_background(kite)[0]
    for _ in range(40):  # it has gone; the direction is covered (it returned there)
        model.observe(t, kite[:0], kite[:0], pose, kite[:0], *NO_BALLS)
        t += PERIOD
    assert not model.is_background(kite)[0]


def test_masks_shift_where_the_window_looked_and_keep_the_memory() -> None:
    looks = np.array([0b1011] * 3, dtype=np.uint64)
    hits = np.array([0b0001] * 3, dtype=np.uint64)
    looked = np.array([True, False, False])
    hit = np.array([False, True, False])
    new_l, new_h = window_update(looks, hits, looked, hit, 64)
    assert new_l.tolist() == [0b10111, 0b10111, 0b1011]  # a hit is a look; out of view: kept
    assert new_h.tolist() == [0b00010, 0b00011, 0b0001]
    new_l, new_h = window_update(looks, hits, looked, hit, 4)
    assert new_l.tolist() == [0b0111, 0b0111, 0b1011]  # only the last 4 looks kept
    assert new_h.tolist() == [0b0010, 0b0011, 0b0001]


def test_enter_and_leave_rules() -> None:
    full = np.uint64(2**64 - 1)
    rows = [
        # (was learnt, looks, hits) -> learnt after
        (False, full, np.uint64(2**32 - 1), True),  # 64 looks, 32 hits: share 0.5
        (False, full, np.uint64(2**31 - 1), False),  # 31 of 64: below the share
        (False, np.uint64(2**15 - 1), np.uint64(2**15 - 1), False),  # 15 hits < L_min 16
        (True, full, np.uint64((2**20 - 1) << 4), True),  # 20 of 64 ≥ s/2; hit recently
        (True, full, np.uint64((2**40 - 1) << 16), False),  # last 16 windows clear
        (True, full, np.uint64((2**15 - 1) << 1), False),  # 15 of 64 < s/2 · 64
    ]
    was = np.array([r[0] for r in rows])
    looks = np.array([r[1] for r in rows], dtype=np.uint64)
    hits = np.array([r[2] for r in rows], dtype=np.uint64)
    got = learnt_now(was, looks, hits, share=0.5, min_looks=16)
    assert got.tolist() == [r[3] for r in rows]


def test_a_look_needs_the_beam_to_reach_the_voxel() -> None:
    rel = np.array([[30.0, 0.0, 0.0], [10.0, 10.0, 0.0]])
    farthest = look_cells(rel)
    assert farthest.shape == (N_CELLS,)
    assert np.count_nonzero(farthest >= 0) == 2
    assert np.isclose(farthest.max(), 30.0)
    covered = np.zeros(N_CELLS, dtype=bool)
    centres = np.array(
        [
            [10.5, 0.0, 0.0],  # in front of the 30 m return: passed through
            [29.6, 0.0, 0.0],  # at it, within the margin
            [40.0, 0.0, 0.0],  # behind it: hidden
            [0.0, -20.0, 0.0],  # nothing returned that way, not sampled
        ]
    )
    got = looked_at(centres, np.zeros(3), np.eye(3), farthest, covered, 1.0)
    assert got.tolist() == [True, True, False, False]
    covered[:] = True  # the sensor samples every direction: the empty one is open sky
    got = looked_at(centres, np.zeros(3), np.eye(3), farthest, covered, 1.0)
    assert got.tolist() == [True, True, False, True]


@settings(max_examples=40, deadline=None)
@given(
    st.lists(st.tuples(st.booleans(), st.booleans()), min_size=1, max_size=80),
    st.integers(1, 64),
)
def test_masks_hold_no_hit_without_a_look_and_no_more_than_the_memory(
    steps: list[tuple[bool, bool]], windows: int
) -> None:
    looks = np.zeros(1, dtype=np.uint64)
    hits = np.zeros(1, dtype=np.uint64)
    for looked, hit in steps:
        looks, hits = window_update(looks, hits, np.array([looked]), np.array([hit]), windows)
        assert int(hits[0]) & ~int(looks[0]) == 0
        assert int(looks[0]) < 2**windows
        assert int(np.bitwise_count(looks)[0]) <= windows


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"memory_s": -1.0}, "learning time"),
        ({"memory_s": 0.0}, "learning time"),
        ({"share": 0.0}, "share"),
        ({"share": 1.5}, "share"),
        ({"min_occupied_s": -1.0}, "minimum occupied time"),
        ({"memory_s": 4.0, "min_occupied_s": 5.0}, "minimum occupied time"),
    ],
)
def test_bad_settings_name_the_problem(kwargs: dict[str, float], words: str) -> None:
    with pytest.raises(InputError, match=words):
        LearningSettings(**kwargs)


def test_what_is_learnt_is_kept_while_out_of_view() -> None:
    """The turret turns away from a learnt car for longer than the memory: the car stays
    in the map (nothing looked through it), and is still there when the turret is back."""
    rng = np.random.default_rng(5)
    s = LearningSettings(memory_s=10.0, min_occupied_s=2.0)
    model = LearningBackground(s, PERIOD)
    series = _run(model, 6.0, lambda t: True, rng)
    assert series[-1][1]
    pose = np.eye(4)
    pose[:2, :2] = [[0.0, -1.0], [1.0, 0.0]]  # turned 90° left
    ahead = np.array([[30.0, 0.0, 0.0]])  # in the sensor frame: a wall ahead
    world = ahead @ pose[:3, :3].T
    for i in range(300):  # 30 s, three memories
        model.observe(6.0 + i * PERIOD, world, ahead, pose, world[:0], *NO_BALLS)
    assert model.is_background(np.array([[10.2, 0.1, 0.1]]))[0]
