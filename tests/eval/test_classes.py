"""The class confusion matrix and the static objects' time to class (``eval.classes``),
on hand-built tracks and truth."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.eval.classes import (
    CONFUSION_KINDS,
    NONE,
    class_figures,
    followed_objects,
    static_figures,
    track_ages,
)
from dronetrack.eval.objects import ObjectsLog
from dronetrack.eval.tracks import TracksLog
from dronetrack.types import TRACK_CLASSES, ObjectTruth
from track_helpers import hand_tracks

T = 0.125  # a frame [s], exact in binary: 16 frames are 2 s
UNKNOWN, DRONE, BIRD, STATIC = (TRACK_CLASSES.index(c) for c in TRACK_CLASSES)


def _truth(positions: np.ndarray, kinds: tuple[str, ...]) -> ObjectTruth:
    k = len(kinds)
    return ObjectTruth(
        ids=np.arange(k),
        kinds=np.array(kinds),
        positions=np.asarray(positions, dtype=float).reshape(k, 3),
        velocities=np.zeros((k, 3)),
        present=np.all(np.isfinite(np.asarray(positions, dtype=float).reshape(k, 3)), axis=1),
        object_index=np.zeros(0, dtype=np.int64),
    )


def _drone(f: int) -> list[float]:
    return [40.0 + 2.0 * f, 0.0, 20.0]


def _bird(f: int) -> list[float]:
    return [60.0, 30.0 + f, 15.0]


def _scene(frames: int = 26) -> tuple[ObjectsLog, TracksLog]:
    """A drone and a bird, and three tracks, one row each per frame:

    - 1 follows the drone 0.5 m off from the first frame: unknown for its first 2 s,
      then classed drone in 9 of the next 10 frames (bird in one);
    - 2 follows the bird from frame 20 on, classed drone: younger than 2 s to the end;
    - 3 holds still 100 m from anything: unknown, then static from 2 s after its birth;
      a cluster updates it for 1.5 s, then it coasts away at 2 m a frame.
    """
    objects, tracks = ObjectsLog(), TracksLog()
    for f in range(frames):
        t = T * (f + 1)
        objects.append(t, _truth(np.array([_drone(f), _bird(f)]), ("drone", "bird")), np.zeros(3))
        drone_cls = UNKNOWN if f < 16 else BIRD if f == 21 else DRONE
        rows = [(1, np.add(_drone(f), [0.5, 0, 0]).tolist(), drone_cls, True)]
        if f >= 20:
            rows.append((2, _bird(f), DRONE, True))
        coast = max(0, f - 12)
        rows.append((3, [-100.0, 2.0 * coast, 5.0], STATIC if f >= 16 else UNKNOWN, coast == 0))
        ids, pos, cls, upd = (list(c) for c in zip(*rows, strict=True))
        tracks.append(t, hand_tracks(ids, pos, cls, upd))
    return objects, tracks


def test_a_drone_track_classed_drone_9_of_10_frames_after_2_s_is_90_pct() -> None:
    objects, tracks = _scene()
    figures = class_figures(objects, tracks, radius=4.0)
    confusion = figures["confusion"]
    # the drone's first 16 frames (unknown) are younger than 2 s and not counted
    assert confusion["drone"] == {"unknown": 0, "drone": 9, "bird": 1, "static": 0}
    assert figures["drone_as_drone_pct"] == pytest.approx(90.0)


def test_a_track_younger_than_2_s_is_not_counted() -> None:
    objects, tracks = _scene()
    figures = class_figures(objects, tracks, radius=4.0)
    assert sum(figures["confusion"]["bird"].values()) == 0  # track 2 lives 0.625 s
    assert figures["bird_as_drone_pct"] is None
    # counted from 0.5 s of life, its last two frames are, classed drone
    young = class_figures(objects, tracks, radius=4.0, min_age_s=0.5)
    assert young["confusion"]["bird"]["drone"] == 2  # frames 24 and 25: 0.5 s and 0.625 s
    assert young["bird_as_drone_pct"] == pytest.approx(100.0)


def test_a_track_following_nothing_counts_as_none() -> None:
    objects, tracks = _scene()
    figures = class_figures(objects, tracks, radius=4.0)
    assert figures["confusion"][NONE] == {"unknown": 0, "drone": 0, "bird": 0, "static": 10}
    assert figures["none_as_drone_pct"] == pytest.approx(0.0)
    assert set(figures["confusion"]) == set(CONFUSION_KINDS)
    for kind in ("walker", "vehicle", "static"):
        assert figures[f"{kind}_as_drone_pct"] is None


def test_a_still_track_on_nothing_is_timed_from_birth_to_its_static_class() -> None:
    """Track 3 is born at 0.125 s, updated to 1.625 s (still, 1.5 s seen) and classed
    static at 2.125 s; its coasting drift afterwards is no movement of its object."""
    objects, tracks = _scene()
    figures = class_figures(objects, tracks, radius=4.0)
    assert figures["static_tracks"] == 1
    assert figures["static_classed"] == 1
    assert figures["static_to_class_median_s"] == pytest.approx(2.0)
    assert figures["static_to_class_max_s"] == pytest.approx(2.0)
    assert figures["static_late"] == 0
    # judged against 1.5 s, it is late
    assert class_figures(objects, tracks, radius=4.0, static_within_s=1.5)["static_late"] == 1


def _lone_track(frames: int) -> tuple[ObjectsLog, TracksLog]:
    """A drone, and a track 80 m from it that holds still, never classed static."""
    objects, tracks = ObjectsLog(), TracksLog()
    for f in range(frames):
        t = T * (f + 1)
        objects.append(t, _truth(np.array([_drone(f)]), ("drone",)), np.zeros(3))
        tracks.append(t, hand_tracks([7], [[0.0, -80.0, 3.0 + 0.01 * f]], [UNKNOWN], [True]))
    return objects, tracks


def test_a_still_track_never_classed_static_is_late_once_it_lived_3_s() -> None:
    lived_5_s = class_figures(*_lone_track(41), radius=4.0)
    assert (lived_5_s["static_tracks"], lived_5_s["static_classed"]) == (1, 0)
    assert lived_5_s["static_late"] == 1
    assert lived_5_s["static_to_class_max_s"] is None
    assert class_figures(*_lone_track(21), radius=4.0)["static_late"] == 0  # 2.5 s


def test_classed_static_at_3_s_from_stamps_a_tenth_apart_is_within_3_s() -> None:
    """Stamps k × 0.1 s are not exact in binary: a track born at frame 134 and
    classed at frame 164 took 3.0000000000000018 s, which is 3 s, not late; one
    classed a frame later is late."""
    on_time = 164 * 0.1 - 134 * 0.1
    assert on_time > 3.0  # the rounding the figure must see past
    figures = static_figures(np.array([on_time, 165 * 0.1 - 134 * 0.1]), np.full(2, 5.0), 3.0)
    assert figures["static_late"] == 1


def test_a_track_that_moved_or_followed_an_object_is_no_static_track() -> None:
    objects, tracks = ObjectsLog(), TracksLog()
    for f in range(30):
        t = T * (f + 1)
        objects.append(t, _truth(np.array([_drone(f)]), ("drone",)), np.zeros(3))
        walking = [0.0, -80.0 + 0.5 * f, 3.0]  # updated, 14.5 m from where it was born
        touching = [_drone(f), [0.0, 50.0, 3.0]][min(f, 1)]  # on the drone at its birth
        tracks.append(t, hand_tracks([1, 2], [walking, touching], [STATIC] * 2, [True] * 2))
    assert class_figures(objects, tracks, radius=4.0)["static_tracks"] == 0


def test_the_nearest_object_within_the_radius_is_followed() -> None:
    truth = np.array([[[0.0, 0, 0], [3.0, 0, 0], [np.nan, np.nan, np.nan]]])
    positions = np.array([[1.0, 0, 0], [2.5, 0, 0], [0.0, 3.99, 0], [0.0, 4.01, 0], [9, 9, 9]])
    followed = followed_objects(np.zeros(5, dtype=np.intp), positions, truth, radius=4.0)
    # nearest first; within 4 m; an object not present is never followed
    assert followed.tolist() == [0, 1, 0, -1, -1]


def test_a_tracks_age_counts_from_its_first_row() -> None:
    t = np.array([1.0, 1.0, 1.5, 2.0, 2.0, 4.0])
    ids = np.array([5, 2, 5, 2, 9, 5])
    np.testing.assert_allclose(track_ages(t, ids), [0.0, 0.0, 0.5, 1.0, 0.0, 3.0])


def test_tracks_at_times_without_truth_are_refused() -> None:
    objects, tracks = _scene(4)
    late = TracksLog()
    late.append(9.0, hand_tracks([1], [[0.0, 0, 0]], [DRONE], [True]))
    with pytest.raises(ValueError, match="without object truth"):
        class_figures(objects, late, radius=4.0)
    with pytest.raises(ValueError, match="truth"):
        class_figures(ObjectsLog(), tracks, radius=4.0)


_KINDS = ("drone", "bird", "walker", "vehicle", "static")


@st.composite
def _worlds(draw: st.DrawFn) -> tuple[ObjectsLog, TracksLog]:
    """Up to 4 objects of any kind and up to 5 tracks, on a 20 m square, for a few
    frames; tracks come and go (a track's rows need not be in consecutive frames)."""
    frames = draw(st.integers(1, 25))
    kinds = tuple(draw(st.lists(st.sampled_from(_KINDS), min_size=0, max_size=4)))
    coord = st.floats(-10.0, 10.0, allow_nan=False)
    objects, tracks = ObjectsLog(), TracksLog()
    for f in range(frames):
        t = T * (f + 1)
        pos = np.array([[draw(coord), draw(coord), 0.0] for _ in kinds]).reshape(len(kinds), 3)
        if len(kinds):
            pos[draw(st.lists(st.booleans(), min_size=len(kinds), max_size=len(kinds)))] = np.nan
        objects.append(t, _truth(pos, kinds), np.zeros(3))
        ids = sorted(draw(st.sets(st.integers(1, 5), max_size=5)))
        tracks.append(
            t,
            hand_tracks(
                ids,
                [[draw(coord), draw(coord), 0.0] for _ in ids],
                [draw(st.integers(0, len(TRACK_CLASSES) - 1)) for _ in ids],
                [draw(st.booleans()) for _ in ids],
            ),
        )
    return objects, tracks


@given(_worlds(), st.sampled_from([0.0, 0.5, 2.0]))
@settings(max_examples=60, deadline=None)
def test_each_row_counts_the_track_frames_that_follow_that_kind(
    world: tuple[ObjectsLog, TracksLog], min_age: float
) -> None:
    """Against a frame-by-frame count: each row of the matrix sums to the track-frames
    old enough whose nearest present object within the radius is of that kind (none:
    no object within it), and every such frame is in one row."""
    objects, tracks = world
    radius = 4.0
    rows = tracks.rows
    expected = dict.fromkeys(CONFUSION_KINDS, 0)
    born: dict[int, float] = {}
    for r in rows:
        born.setdefault(int(r["id"]), float(r["t"]))
        if float(r["t"]) - born[int(r["id"])] < min_age:
            continue
        f = int(np.flatnonzero(objects.t == r["t"])[0])
        nearest, kind = np.inf, NONE
        for k, name in enumerate(objects.kinds if objects.kinds is not None else []):
            d = float(np.linalg.norm(objects.positions[f, k] - r["position"]))
            if d <= radius and d < nearest:  # NaN (not present) is neither
                nearest, kind = d, str(name)
        expected[kind] += 1
    if len(objects) == 0:
        return
    confusion = class_figures(objects, tracks, radius, min_age_s=min_age)["confusion"]
    got = {kind: sum(row.values()) for kind, row in confusion.items()}
    assert got == expected


def test_the_lock_on_a_static_track_is_timed_and_on_a_drone_not() -> None:
    """The lone still track is locked for its first 8 frames (1 s at 0.125 s a frame),
    then the drone's track for the rest: static_held_s is 1 s; none in the scene of a
    drone track and a static one that is never locked."""
    objects, tracks = ObjectsLog(), TracksLog()
    for f in range(30):
        t = T * (f + 1)
        objects.append(t, _truth(np.array([_drone(f)]), ("drone",)), np.zeros(3))
        rows = hand_tracks([1, 7], [_drone(f), [0.0, -80.0, 3.0]], [DRONE, UNKNOWN])
        tracks.append(t, replace(rows, locked=np.array([f >= 8, f < 8])))
    assert class_figures(objects, tracks, radius=4.0)["static_held_s"] == pytest.approx(1.0)
    assert class_figures(*_scene(), radius=4.0)["static_held_s"] == 0.0


def test_the_lock_is_timed_by_the_frame_period_when_frames_have_no_tracks() -> None:
    """The still track is logged (locked) in every other frame of 0.125 s only: 8 locked
    rows are 1 s, whatever the gaps between the rows."""
    objects, tracks = ObjectsLog(), TracksLog()
    for f in range(16):
        t = T * (f + 1)
        objects.append(t, _truth(np.array([_drone(f)]), ("drone",)), np.zeros(3))
        if f % 2 == 0:
            rows = hand_tracks([7], [[0.0, -80.0, 3.0]], [UNKNOWN])
            tracks.append(t, replace(rows, locked=np.array([True])))
    assert class_figures(objects, tracks, radius=4.0)["static_held_s"] == pytest.approx(1.0)
