"""Every object's truth and the figures scored against it (``eval.objects``): each
drone's own figures and motmetrics' multi-object figures."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from dronetrack.eval.objects import ObjectsLog, drone_figures, mot_figures
from dronetrack.eval.tracks import TracksLog
from dronetrack.types import TRACK_CLASSES, ObjectTruth
from track_helpers import hand_tracks

T = 0.1
DRONE, BIRD = TRACK_CLASSES.index("drone"), TRACK_CLASSES.index("bird")


def _truth(positions: np.ndarray, returns: list[int], kinds: tuple[str, ...]) -> ObjectTruth:
    index = np.concatenate([np.full(n, k) for k, n in enumerate(returns)] or [np.empty(0)])
    k = len(kinds)
    return ObjectTruth(
        ids=np.arange(k),
        kinds=np.array(kinds),
        positions=positions,
        velocities=np.zeros((k, 3)),
        present=np.ones(k, dtype=bool),
        object_index=index.astype(np.int64),
    )


def _scene(
    frames: int, switch_at: int | None = None, bird_track: bool = False
) -> tuple[ObjectsLog, TracksLog]:
    """Two drones 20 m apart, each followed by a track 0.5 m off; from ``switch_at`` on
    the two tracks trade drones (identity switches); optionally a bird-class track."""
    objects, tracks = ObjectsLog(), TracksLog()
    for f in range(frames):
        t = T * (f + 1)
        drones = np.array([[30.0 + f, 0.0, 10.0], [30.0 + f, 20.0, 10.0]])
        objects.append(t, _truth(drones, [5, 5], ("drone", "drone")), np.zeros(3))
        ids = [1, 2] if switch_at is None or f < switch_at else [2, 1]
        est = drones + np.array([0.5, 0.0, 0.0])
        extra_ids, extra_pos, extra_cls = [], [], []
        if bird_track:
            extra_ids, extra_pos, extra_cls = [9], [[80.0, -40.0, 30.0]], [BIRD]
        tracks.append(
            t,
            hand_tracks(
                ids + extra_ids,
                np.vstack([est, *extra_pos]) if extra_pos else est,
                [DRONE, DRONE, *extra_cls],
            ),
        )
    return objects, tracks


def test_two_drones_each_followed_by_its_track_score_perfectly() -> None:
    objects, tracks = _scene(20, bird_track=True)
    mot = mot_figures(objects, tracks, radius=4.0)
    assert mot["mota"] == pytest.approx(1.0)
    assert mot["idf1"] == pytest.approx(1.0)
    assert mot["motp_m"] == pytest.approx(0.5)
    assert mot["id_switches"] == 0
    assert mot["false_positives"] == 0  # the bird-class track is no drone hypothesis
    assert [d["own_track_pct"] for d in mot["drones"]] == [100.0, 100.0]
    assert [d["track_ids"] for d in mot["drones"]] == [1, 1]


def test_tracks_that_trade_drones_switch_identity_once_each() -> None:
    objects, tracks = _scene(20, switch_at=10)
    mot = mot_figures(objects, tracks, radius=4.0)
    assert mot["id_switches"] == 2
    assert [d["id_switches"] for d in mot["drones"]] == [1, 1]
    assert [d["track_ids"] for d in mot["drones"]] == [2, 2]
    assert mot["idf1"] == pytest.approx(0.5)


def test_a_drone_without_returns_is_not_expected_and_a_track_far_off_is_a_false_positive() -> None:
    objects, tracks = ObjectsLog(), TracksLog()
    for f in range(4):
        drone = np.array([[40.0, 0.0, 10.0]])
        objects.append(T * (f + 1), _truth(drone, [0 if f < 2 else 3], ("drone",)), np.zeros(3))
        tracks.append(T * (f + 1), hand_tracks([1], np.array([[40.0, 10.0, 10.0]]), [DRONE]))
    mot = mot_figures(objects, tracks, radius=4.0)
    assert mot["false_positives"] == 4  # 10 m off: never within the 4 m radius
    assert mot["misses"] == 2  # the two frames it returned points
    assert mot["drones"][0]["own_track_pct"] == 0.0


def test_a_track_out_of_view_is_no_hypothesis() -> None:
    """A drone out of the sensor's view returns nothing and is no truth; its track,
    kept while the turret serves another, is no hypothesis either: no false positive
    while it is out of view, a match again once it is back in view."""
    objects, tracks = ObjectsLog(), TracksLog()
    for f in range(6):
        back = f >= 4
        drone = np.array([[40.0, 0.0, 10.0]])
        objects.append(T * (f + 1), _truth(drone, [3 if back else 0], ("drone",)), np.zeros(3))
        drifted = np.array([[40.0, 2.0 if back else 9.0, 10.0]])  # its prediction, off
        tracks.append(T * (f + 1), hand_tracks([1], drifted, [DRONE], in_view=[back]))
    mot = mot_figures(objects, tracks, radius=4.0)
    assert mot["false_positives"] == 0
    assert mot["misses"] == 0
    assert mot["drones"][0]["own_track_pct"] == 100.0


def test_a_track_with_evidence_against_a_drone_is_no_hypothesis() -> None:
    """Beside the drone's track, two tracks of no class: one the classes cannot tell
    (p_drone 0.5) is a false positive, one with evidence against a drone (0.1: on the
    ground, part of a structure, beyond reach) is not; nor is a bird, whatever its p."""
    objects, tracks = ObjectsLog(), TracksLog()
    unknown = TRACK_CLASSES.index("unknown")
    for f in range(5):
        drone = np.array([[40.0, 0.0, 10.0]])
        objects.append(T * (f + 1), _truth(drone, [3], ("drone",)), np.zeros(3))
        where = [[40.0, 0.0, 10.0], [80.0, 30.0, 5.0], [90.0, -30.0, 2.0], [60.0, 5.0, 20.0]]
        these = hand_tracks([1, 2, 3, 4], where, [DRONE, unknown, unknown, BIRD])
        these = replace(these, p_drone=np.array([0.98, 0.5, 0.1, 0.5]))
        tracks.append(T * (f + 1), these)
    mot = mot_figures(objects, tracks, radius=4.0)
    assert mot["matches"] == 5
    assert mot["false_positives"] == 5  # track 2's, one a frame


def test_each_drones_figures_score_the_turrets_estimate_against_it() -> None:
    objects, _ = _scene(30)
    t = T * np.arange(1, 31)
    # the turret holds drone 1 (at y = 20) from frame 10 on
    est = np.array([[30.0 + f, 20.0, 10.0] for f in range(30)])
    tracked = np.arange(30) >= 10
    drones = drone_figures(objects, t, est, tracked, radius=4.0)
    assert [d["id"] for d in drones] == [0, 1]
    assert drones[0]["lock_on_visible_pct"] == 0.0
    assert drones[0]["acquire_s"] is None
    assert drones[1]["lock_on_visible_pct"] == pytest.approx(100.0 * 20 / 30)
    assert drones[1]["acquire_s"] == pytest.approx(1.0)
    assert drones[1]["visible_frames"] == 30
    assert drones[0]["revisit_max_s"] is None  # never locked on
    assert drones[1]["revisit_max_s"] == 0.0  # held from its first lock on


@pytest.mark.slow
def test_drone_0s_own_figures_are_the_runs_single_target_figures() -> None:
    """A simulated run: the figures of drone 0 in ``drones`` are computed as the run's
    own (coverage, acquisition, lock-on) are, against the same truth."""
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.jobs.simulate import run_simulation

    run = run_simulation(get_scenario("default").model_copy(update={"duration_s": 14.0}))
    metrics = run.metrics()
    own = metrics["drones"][0]
    for key in ("coverage_pct", "max_tracking_distance_m", "acquire_s", "lock_on_visible_pct"):
        assert own[key] == pytest.approx(metrics[key]), key
    assert 0.0 <= metrics["mot"]["mota"] <= 1.0
    assert metrics["mot"]["frames"] == metrics["frames"]


def test_a_drone_is_acquired_as_a_track_from_its_first_visible_frame_to_its_first_match() -> None:
    """Visible from frame 2; a track 10 m off until frame 4, on it from frame 5: acquired
    as a track 3 frames (0.3 s) after it came into view; never, without the match."""
    objects, tracks, far = ObjectsLog(), TracksLog(), TracksLog()
    for f in range(8):
        drone = np.array([[40.0, 0.0, 10.0]])
        objects.append(T * (f + 1), _truth(drone, [0 if f < 2 else 3], ("drone",)), np.zeros(3))
        off = 10.0 if f < 5 else 0.5
        tracks.append(T * (f + 1), hand_tracks([1], np.array([[40.0, off, 10.0]]), [DRONE]))
        far.append(T * (f + 1), hand_tracks([1], np.array([[40.0, 10.0, 10.0]]), [DRONE]))
    (drone,) = mot_figures(objects, tracks, radius=4.0)["drones"]
    assert drone["track_acquire_s"] == pytest.approx(0.3)
    assert mot_figures(objects, far, radius=4.0)["drones"][0]["track_acquire_s"] is None


def test_a_drone_flying_in_from_beyond_reach_is_acquired_from_its_first_frame_within_it() -> None:
    """A drone flying in at 10 m/s from 150 m at the sensor's height, visible all along
    (a single return a frame out there), crosses the 130 m reach at frame 20 (t 2.1 s);
    a track matches it from frame 23 and the turret locks on from frame 25: acquired
    0.3 s and 0.5 s after it came within reach, 2.3 s and 2.5 s after it came into
    view.  A track on it from frame 15, beyond reach, has it when it comes within
    reach: 0 s, not −0.5 s.  Without the reach, the figures within it are left out."""
    objects, tracks, early = ObjectsLog(), TracksLog(), TracksLog()
    frames = 30
    positions = np.array([[150.0 - 1.0 * f, 0.0, 0.0] for f in range(frames)])
    for f in range(frames):
        drone = positions[f : f + 1]
        objects.append(T * (f + 1), _truth(drone, [1], ("drone",)), np.zeros(3))
        off = 10.0 if f < 23 else 0.5
        tracks.append(T * (f + 1), hand_tracks([1], drone + np.array([0.0, off, 0.0]), [DRONE]))
        off = 10.0 if f < 15 else 0.5
        early.append(T * (f + 1), hand_tracks([1], drone + np.array([0.0, off, 0.0]), [DRONE]))
    t = T * np.arange(1, frames + 1)
    tracked = np.arange(frames) >= 25
    (own,) = drone_figures(objects, t, positions, tracked, radius=4.0, reach_m=130.0)
    (scored,) = mot_figures(objects, tracks, radius=4.0, reach_m=130.0)["drones"]
    assert own["acquire_s"] == pytest.approx(2.5)
    assert own["acquire_in_reach_s"] == pytest.approx(0.5)
    assert scored["track_acquire_s"] == pytest.approx(2.3)
    assert scored["track_acquire_in_reach_s"] == pytest.approx(0.3)
    (scored,) = mot_figures(objects, early, radius=4.0, reach_m=130.0)["drones"]
    assert scored["track_acquire_s"] == pytest.approx(1.5)
    assert scored["track_acquire_in_reach_s"] == 0.0
    (own,) = drone_figures(objects, t, positions, tracked, radius=4.0)
    (scored,) = mot_figures(objects, tracks, radius=4.0)["drones"]
    assert "acquire_in_reach_s" not in own
    assert "track_acquire_in_reach_s" not in scored
