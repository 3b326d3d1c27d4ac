"""Which track the turret serves (``control.choose``): threat, hysteresis, revisits and
looks that find nothing."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from dronetrack.control.choose import (
    ChooseSettings,
    TargetChooser,
    drone_instead,
    threat,
    worth_a_look,
)
from dronetrack.errors import ConfigError
from dronetrack.types import TRACK_CLASSES, Tracks

DRONE, BIRD = TRACK_CLASSES.index("drone"), TRACK_CLASSES.index("bird")
UNKNOWN = TRACK_CLASSES.index("unknown")


def _tracks(
    t: float,
    positions: list[list[float]],
    classes: list[int],
    p: list[float],
    seen: list[float] | None = None,
    away: list[float] | None = None,
) -> Tracks:
    """Tracks last updated at ``seen`` (default: now), out of the sensor's view for
    ``away`` of the time since (default: none of it)."""
    k = len(positions)
    last = np.full(k, t) if seen is None else np.array(seen, dtype=float)
    out = np.zeros(k) if away is None else np.array(away, dtype=float)
    return Tracks(
        ids=np.arange(1, k + 1),
        positions=np.array(positions, dtype=float),
        velocities=np.zeros((k, 3)),
        covariances=np.tile(np.eye(6), (k, 1, 1)),
        born=np.zeros(k),
        updated=np.ones(k, dtype=bool),
        hovered=np.zeros(k, dtype=bool),
        locked=np.zeros(k, dtype=bool),
        classes=np.array(classes),
        p_drone=np.array(p),
        last_seen=last,
        missed_s=t - last - out,
    )


def test_threat_grows_with_p_drone_closeness_and_closing_speed() -> None:
    q = np.zeros(3)
    pos = np.array([[100.0, 0, 20], [50.0, 0, 20], [100.0, 0, 20], [100.0, 0, 20]])
    vel = np.array([[0.0, 0, 0], [0.0, 0, 0], [-15.0, 0, 0], [15.0, 0, 0]])
    p = np.array([0.9, 0.9, 0.9, 0.9])
    th = threat(pos, vel, p, q, d_ref=100.0, v_ref=15.0)
    d = np.linalg.norm(pos[0])
    assert th[0] == pytest.approx(0.9 * 100 / (100 + d))
    assert th[1] > th[0]  # closer
    assert th[2] == pytest.approx(th[0] * (1 + 15 * 100 / d / 15))  # closing at 15·cos
    assert th[3] == pytest.approx(th[0])  # leaving counts as not closing
    assert threat(pos[:1], vel[:1], np.array([0.45]), q, 100.0, 15.0)[0] == pytest.approx(th[0] / 2)


def test_one_drone_leaves_the_choice_to_the_acquisition() -> None:
    chooser = TargetChooser()
    tracks = _tracks(1.0, [[60, 0, 20], [40, 10, 5]], [DRONE, BIRD], [0.98, 0.1])
    assert chooser.choose(1.0, tracks, locked=1) is None


def test_two_drones_share_the_turret_every_revisit_period() -> None:
    chooser = TargetChooser(ChooseSettings(revisit_s=5.0, hold_s=1.0, look_s=1.5))
    served = []
    for k in range(200):  # 20 s at 10 Hz; the held track is the one served
        t = 0.1 * k
        tracks = _tracks(t, [[60, -40, 20], [60, 40, 20]], [DRONE, DRONE], [0.98, 0.98])
        locked = served[-1] if served else 1
        served.append(chooser.choose(t, tracks, locked))
    changes = [k for k in range(1, 200) if served[k] != served[k - 1]]
    assert served[0] == 1  # the held drone is kept at first (equal threat)
    assert len(changes) >= 3  # turns to the other and back, time after time
    gaps = np.diff([0, *changes]) * 0.1
    # each is due look_s before the revisit period, so a look that lands within look_s
    # lands within it
    assert np.all(gaps <= 5.0 - 1.5 + 0.1 + 1e-9)
    assert np.all(gaps[1:] >= 1.0 - 1e-9)  # and holds the turret at least hold_s


def test_a_much_greater_threat_takes_the_turret_after_the_hold() -> None:
    chooser = TargetChooser(ChooseSettings(hysteresis=1.5, hold_s=1.0, revisit_s=100.0))
    both = [DRONE, DRONE]
    even = [[100, -30, 20], [100, 30, 20]]
    assert chooser.choose(0.0, _tracks(0.0, even, both, [0.98, 0.98]), 1) == 1
    # track 2 closes in: three times the threat at 20 m, but only after the hold
    near = [[100, -30, 20], [20, 0, 10]]
    assert chooser.choose(0.5, _tracks(0.5, near, both, [0.98, 0.98]), 1) == 1
    assert chooser.choose(1.0, _tracks(1.0, near, both, [0.98, 0.98]), 1) == 2
    # a threat a few per cent greater does not take it: track 2 (97.6 m out) is served
    # first, track 1 (102.5 m) gets its first look, and keeps the turret
    chooser2 = TargetChooser(ChooseSettings(hysteresis=1.5, hold_s=0.0, revisit_s=100.0))
    close = [[100, -10, 20], [95, 10, 20]]
    assert chooser2.choose(0.0, _tracks(0.0, close, both, [0.98, 0.98]), 2) == 2
    assert chooser2.choose(0.1, _tracks(0.1, close, both, [0.98, 0.98]), 2) == 1
    for k in range(2, 22):
        assert chooser2.choose(0.1 * k, _tracks(0.1 * k, close, both, [0.98, 0.98]), 1) == 1


def test_a_look_that_finds_nothing_gives_way_and_is_not_repeated() -> None:
    chooser = TargetChooser(ChooseSettings(hysteresis=1.5, hold_s=0.0, look_s=1.0, revisit_s=100.0))
    far_near = [[140, 0, 20], [20, 0, 10]]
    served = [chooser.choose(0.0, _tracks(0.0, far_near, [DRONE, DRONE], [0.98, 0.98]), 1)]
    assert served[0] == 2  # the near one, not held
    for k in range(1, 15):  # the tracker never finds track 2 (held stays 1)
        t = 0.1 * k
        served.append(
            chooser.choose(t, _tracks(t, far_near, [DRONE, DRONE], [0.98, 0.98], [t, 0.0]), 1)
        )
    assert served[9] == 2
    assert served[10] == 1  # given up after look_s: back to the held one
    assert served[-1] is None  # and not chosen again while it is not seen anew


def test_stale_and_bird_tracks_are_no_candidates() -> None:
    chooser = TargetChooser(ChooseSettings(fresh_s=1.0))
    tracks = _tracks(
        5.0,
        [[60, 0, 20], [60, 40, 20], [60, -40, 20]],
        [DRONE, DRONE, BIRD],
        [0.98, 0.98, 0.1],
        [5.0, 3.0, 5.0],
    )
    assert chooser.choose(5.0, tracks, locked=1) is None  # the other drone is 2 s unseen


def test_a_drone_out_of_view_stays_a_candidate_and_is_looked_at_again() -> None:
    """Track 2 was last held at 1 s and has been out of the sensor's view since (the
    turret served track 1): it is not missed, so it is looked at again look_s before
    revisit_s is up (so that the look lands within it)."""
    chooser = TargetChooser(ChooseSettings(revisit_s=5.0, hold_s=1.0, fresh_s=1.0))
    pos, both = [[60, -40, 20], [60, 40, 20]], [DRONE, DRONE]
    assert chooser.choose(0.0, _tracks(0.0, pos, both, [0.98, 0.98]), 1) == 1
    chooser.choose(1.0, _tracks(1.0, pos, both, [0.98, 0.98]), 2)  # track 2 served, held
    served = None
    for k in range(2, 80):
        t = 0.1 * k + 1.0
        tracks = _tracks(t, pos, both, [0.98, 0.98], [t, 1.0], [0.0, t - 1.0])
        served = chooser.choose(t, tracks, 1)
        if served == 2:
            break
    assert served == 2
    assert t == pytest.approx(1.0 + 5.0 - ChooseSettings().look_s, abs=0.15)
    # missed in view for 2 s (> fresh_s): no candidate, the choice is the acquisition's
    missed = _tracks(9.0, pos, both, [0.98, 0.98], [9.0, 7.0], [0.0, 0.0])
    assert TargetChooser().choose(9.0, missed, 1) is None


def test_a_new_track_worth_a_look_is_served_after_the_hold() -> None:
    """A track the classes cannot tell yet (unknown, p 0.5) appears while a drone is
    held: it is looked at once the hold is over, not after revisit_s; a track classed bird
    (p 0.12) is not."""
    chooser = TargetChooser(ChooseSettings(revisit_s=100.0, hold_s=1.0, hysteresis=1.5))
    pos = [[60, -40, 20], [60, 40, 20]]
    assert chooser.choose(0.0, _tracks(0.0, pos, [DRONE, UNKNOWN], [0.98, 0.5]), 1) == 1
    assert chooser.choose(0.9, _tracks(0.9, pos, [DRONE, UNKNOWN], [0.98, 0.5]), 1) == 1
    assert chooser.choose(1.0, _tracks(1.0, pos, [DRONE, UNKNOWN], [0.98, 0.5]), 1) == 2
    birds = TargetChooser(ChooseSettings(revisit_s=100.0, hold_s=1.0))
    for k in range(30):
        tracks = _tracks(0.1 * k, pos, [DRONE, BIRD], [0.98, 0.12])
        assert birds.choose(0.1 * k, tracks, 1) is None


def test_new_tracks_that_cannot_be_found_get_one_look_each_then_the_held_one_is_kept() -> None:
    """Two new tracks the tracker never finds (the held track stays 1): each gets its
    first look once, each look is given up after look_s, and the turret is back on the
    held track for good, rather than taking turns between the two."""
    s = ChooseSettings(revisit_s=100.0, hold_s=1.0, look_s=1.5)
    chooser = TargetChooser(s)
    pos, cls = [[60, 0, 20], [60, 40, 20], [60, -40, 20]], [DRONE, UNKNOWN, UNKNOWN]
    served = []
    for k in range(150):
        t = 0.1 * k
        seen = [t, 0.0, 0.0]  # tracks 2 and 3 last seen at 0, out of view since
        served.append(chooser.choose(t, _tracks(t, pos, cls, [0.98, 0.5, 0.5], seen, [0, t, t]), 1))
    looks = [i for i in (2, 3) if i in served]
    assert looks == [2, 3]
    turns = sum(1 for a, b in itertools.pairwise(served) if a != b)
    assert turns <= 4  # 1 → a look → the other look → back (→ no choice)
    assert set(served[-30:]) <= {1, None}


def test_worth_a_look_is_a_drone_or_a_servable_track_not_told_yet() -> None:
    tracks = _tracks(
        0.0,
        [[60, 0, 20]] * 5,
        [DRONE, UNKNOWN, BIRD, UNKNOWN, TRACK_CLASSES.index("static")],
        [0.98, 0.5, 0.12, 0.05, 0.5],
    )
    assert worth_a_look(tracks, 0.2).tolist() == [True, True, False, False, False]
    assert worth_a_look(tracks, 0.1).tolist() == [True, True, True, False, False]
    assert worth_a_look(tracks, 1.0).tolist() == [True, False, False, False, False]


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ConfigError, match="min_p"):
        ChooseSettings(min_p=1.5)
    with pytest.raises(ConfigError, match="revisit_s"):
        ChooseSettings(revisit_s=0.0)
    with pytest.raises(ConfigError, match="hysteresis"):
        ChooseSettings(hysteresis=0.5)


def test_a_lock_on_no_drone_turns_to_a_drone_track() -> None:
    """Held: an unknown object 190 m out (p 0.12); a drone-class track 60 m out is a
    candidate: threat 0.98·100/160 = 0.61 against 0.12·100/290 = 0.04, so it is chosen."""
    tracks = _tracks(0.0, [[190.0, 0, 10], [60.0, 0, 15]], [UNKNOWN, DRONE], [0.12, 0.98])
    owner = np.array([1, -1])  # candidate 0 is the drone's cluster, candidate 1 no track's
    assert drone_instead(owner, tracks, 0, ChooseSettings()) == 0
    assert drone_instead(owner, tracks, -1, ChooseSettings()) == 0  # no track at the lock


def test_a_lock_on_a_drone_or_a_greater_threat_stays() -> None:
    """A held drone-class track is kept whatever else is seen; a held unknown track
    near the protected point outweighs a drone-class track far out (hysteresis 1.5)."""
    s = ChooseSettings()
    tracks = _tracks(0.0, [[60.0, 0, 15], [190.0, 0, 10]], [DRONE, DRONE], [0.98, 0.98])
    assert drone_instead(np.array([1]), tracks, 0, s) == -1
    tracks = _tracks(0.0, [[60.0, 0, 15], [190.0, 0, 10]], [UNKNOWN, DRONE], [0.5, 0.98])
    # 0.98·100/290 = 0.34 is not 1.5 × 0.5·100/160 = 0.47
    assert drone_instead(np.array([1]), tracks, 0, s) == -1
    birds = _tracks(0.0, [[190.0, 0, 10], [60.0, 0, 15]], [UNKNOWN, BIRD], [0.12, 0.1])
    assert drone_instead(np.array([1]), birds, 0, s) == -1  # no drone among the candidates
    assert drone_instead(np.array([0]), tracks, 0, s) == -1  # the held track is no other


def test_the_books_keep_only_the_tracks_alive() -> None:
    """A live rig runs for hours and identities are never reused: what the chooser
    keeps of ended tracks is dropped."""
    chooser = TargetChooser(ChooseSettings(hold_s=0.0))
    pos = [[60, -40, 20], [60, 40, 20]]
    for k in range(50):
        t = 0.1 * k
        tracks = _tracks(t, pos, [DRONE, DRONE], [0.98, 0.98])
        tracks = replace(tracks, ids=np.array([2 * k + 1, 2 * k + 2]))
        chooser.choose(t, tracks, 2 * k + 1)
    assert set(chooser.first_seen) <= {99, 100}
    assert set(chooser.held_at) <= {99, 100}
    assert chooser.looked <= {99, 100}


def test_a_look_is_not_cut_short_by_a_greater_threat() -> None:
    """A look at a track out of view (served, not held) goes on for look_s even though
    the held drone is far more threatening: a threat that took the turret back after
    the hold would end every look at a less likely drone before the turret got there.
    Once given up, the threat decides again."""
    s = ChooseSettings(revisit_s=100.0, hold_s=0.5, look_s=1.5, hysteresis=1.5)
    chooser = TargetChooser(s)
    pos = [[40, 0, 10], [120, 60, 20]]  # track 1 near, track 2 far: 1 is 3x the threat
    cls, p = [DRONE, UNKNOWN], [0.98, 0.5]
    served = []
    for k in range(30):
        t = 0.1 * k
        served.append(chooser.choose(t, _tracks(t, pos, cls, p, [t, 0.0], [0.0, t]), 1))
    assert served[0] == 1  # the held one first (fair: within hysteresis of none)
    first = served.index(2)  # the new track's first look, after the hold
    assert first == 5
    assert set(served[first : first + 15]) == {2}  # held for the whole look_s
    assert served[first + 15] == 1  # then given up


def test_a_look_turns_to_a_new_track_found_in_its_gate() -> None:
    """While the turret looks for a track out of view, a new track born within its gate
    (the Mahalanobis distance on its grown position covariance, d² ≤ χ²₃(0.99)) is the
    object looked for, found: it is served at once, without waiting out the hold.  One
    outside the gate waits for the hold like any new track."""
    s = ChooseSettings(revisit_s=100.0, hold_s=1.0, look_s=1.5)

    def frame(t: float, third: list[float], sigma: float) -> Tracks:
        tracks = _tracks(
            t, [[40, 0, 10], [100, 50, 20], third], [DRONE, UNKNOWN, UNKNOWN], [0.98, 0.5, 0.5]
        )
        cov = tracks.covariances.copy()
        cov[1, :3, :3] = np.eye(3) * sigma**2  # track 2 coasted: σ grew
        return replace(tracks, covariances=cov)

    two = ([[40, 0, 10], [100, 50, 20]], [DRONE, UNKNOWN], [0.98, 0.5])
    # 22 m from track 2's prediction, σ 10 m: d² = 5.0; 125 m away: d² = 157; a track
    # with a singular covariance (no spread) has no gate
    cases = (([120.0, 40.0, 20.0], 10.0, True), ([40.0, -60.0, 20.0], 10.0, False))
    for third, sigma, found in (*cases, ([120.0, 40.0, 20.0], 0.0, False)):
        chooser = TargetChooser(s)
        chooser.choose(0.0, _tracks(0.0, *two), 1)
        assert chooser.choose(1.0, _tracks(1.0, *two), 1) == 2  # its first look
        served = chooser.choose(1.2, frame(1.2, third, sigma), 1)
        assert served == (3 if found else 2)
