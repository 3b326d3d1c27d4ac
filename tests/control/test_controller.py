"""Turret control: tracking, holding and searching, fixed mode, scanning, limits."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.control.aiming import aim_angles
from dronetrack.control.controller import TurretController
from dronetrack.control.scan import raster, triangle
from dronetrack.geometry.mount import MountGeometry
from dronetrack.types import Candidates, TrackEstimate

MOUNT = MountGeometry((0.0, 0.0, 1.0), (0.0, 0.0, 0.05), (0.025, 0.0, 0.086))
LIMITS = ((-math.pi, math.pi), (math.radians(-68), math.radians(68)))


def _estimate(
    t: float,
    p: tuple[float, float, float],
    tracked: bool = True,
    v: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> TrackEstimate:
    return TrackEstimate(t, np.array(p), np.array(v), tracked, 0.1 if tracked else 2.0)


def _controller(**kw: object) -> TurretController:
    return TurretController(MOUNT, *LIMITS, **kw)  # type: ignore[arg-type]


def test_tracking_aims_at_the_estimate_and_leads_it() -> None:
    c = _controller()
    cmd = c.tracking(1.0, _estimate(1.0, (50.0, 10.0, 20.0)))
    assert cmd is not None
    assert (cmd.pan, cmd.tilt) == pytest.approx(aim_angles((50.0, 10.0, 20.0), MOUNT))
    lead = _controller(lead_s=0.2).tracking(1.0, _estimate(1.0, (50.0, 10.0, 20.0), v=(0, 10, 0)))
    assert lead is not None
    assert (lead.pan, lead.tilt) == pytest.approx(aim_angles((50.0, 12.0, 20.0), MOUNT))


def test_before_the_first_lock_it_looks_home() -> None:
    c = _controller(home=(60.0, 0.0, 15.0))
    cmd = c.tracking(0.0, _estimate(0.0, (5.0, 5.0, 5.0), tracked=False))
    assert cmd is not None
    assert (cmd.pan, cmd.tilt) == pytest.approx(aim_angles((60.0, 0.0, 15.0), MOUNT))


def test_a_lost_target_is_followed_then_searched_for() -> None:
    area = ((math.radians(-90), math.radians(90)), (math.radians(-40), math.radians(5)))
    c = _controller(
        search_hold_s=2.0,
        search_pan=math.radians(30),
        search_lane=math.radians(20),
        search_rate=math.radians(40),
        search_area=area,
    )
    last = (40.0, -20.0, 10.0)
    c.tracking(0.0, _estimate(0.0, last))
    pans, tilts = [], []
    for k in range(1, 400):
        t = 0.1 * k
        # The tracker's prediction drifts on at 5 m/s along y.
        predicted = (40.0, -20.0 + 5.0 * t, 10.0)
        cmd = c.tracking(t, _estimate(t, predicted, tracked=False))
        assert cmd is not None
        if t < 2.0 - 1e-9:  # following the prediction
            assert (cmd.pan, cmd.tilt) == pytest.approx(aim_angles(predicted, MOUNT))
        else:
            pans.append(cmd.pan)
            tilts.append(cmd.tilt)
    # The search reaches both ends of the field's pan range (within a frame's 4° of
    # motion, as the frames sample it) and stays inside it.
    assert min(pans) == pytest.approx(area[0][0], abs=math.radians(4.0))
    assert max(pans) == pytest.approx(area[0][1], abs=math.radians(4.0))
    assert area[0][0] <= min(pans) <= max(pans) <= area[0][1]
    assert area[1][0] <= min(tilts) <= max(tilts) <= area[1][1]
    # It moves at the search rate: 40°/s at most, 4° a 0.1 s frame.
    assert np.max(np.abs(np.diff(pans))) <= math.radians(4.0) + 1e-9
    # Found again: back to tracking at once.
    back = c.tracking(50.0, _estimate(50.0, (30.0, 5.0, 8.0)))
    assert back is not None
    assert (back.pan, back.tilt) == pytest.approx(aim_angles((30.0, 5.0, 8.0), MOUNT))


def _candidates(p: tuple[float, float, float], v: tuple[float, float, float]) -> Candidates:
    one = np.ones(1, dtype=np.int64)
    return Candidates(np.array([p]), np.array([v]), 3 * one, np.array([0.4]), one)


def test_a_confirmed_candidate_gets_the_dense_centre_before_any_lock() -> None:
    c = _controller(home=(60.0, 0.0, 15.0), lead_s=0.5)
    cand = _candidates((80.0, 40.0, 20.0), (0.0, -4.0, 0.0))
    cmd = c.tracking(0.0, _estimate(0.0, (5.0, 5.0, 5.0), tracked=False), None, cand)
    assert cmd is not None
    assert (cmd.pan, cmd.tilt) == pytest.approx(aim_angles((80.0, 38.0, 20.0), MOUNT))
    # The candidate gone: the turret stays on it for the hold, not back home.
    held = c.tracking(1.0, _estimate(1.0, (5.0, 5.0, 5.0), tracked=False), None, None)
    assert held is not None
    assert (held.pan, held.tilt) == pytest.approx((cmd.pan, cmd.tilt))


def test_before_any_lock_or_candidate_it_searches_after_the_hold() -> None:
    c = _controller(home=(60.0, 0.0, 15.0), search_hold_s=1.0)
    home = aim_angles((60.0, 0.0, 15.0), MOUNT)
    seen = [
        c.tracking(0.1 * k, _estimate(0.1 * k, (5.0, 5.0, 5.0), tracked=False)) for k in range(30)
    ]
    assert all(cmd is not None for cmd in seen)
    assert all((cmd.pan, cmd.tilt) == pytest.approx(home) for cmd in seen[:10] if cmd)
    assert any(abs(cmd.pan - home[0]) > math.radians(10) for cmd in seen[10:] if cmd)


def _cue(p: tuple[float, float, float], v: tuple[float, float, float]) -> Candidates:
    one = np.ones(1, dtype=np.int64)
    return Candidates(np.array([p]), np.array([v]), 2 * one, np.array([0.4]), one)


def test_a_cue_gets_a_look_without_lead_for_at_least_the_look_time() -> None:
    c = _controller(home=(60.0, 0.0, 15.0), lead_s=0.5, search_hold_s=0.0, cue_look_s=0.5)
    lost = _estimate(0.0, (5.0, 5.0, 5.0), tracked=False)
    cue = _cue((90.0, 40.0, 20.0), (0.0, 8.0, 0.0))
    cmd = c.tracking(0.0, lost, None, None, cue)
    assert cmd is not None
    # No lead: two hits give a poor velocity.
    assert (cmd.pan, cmd.tilt) == pytest.approx(aim_angles((90.0, 40.0, 20.0), MOUNT))
    # The cue's track dropped: the look goes on to 0.5 s ...
    for t in (0.1, 0.3, 0.4):
        held = c.tracking(t, _estimate(t, (5.0, 5.0, 5.0), tracked=False))
        assert held is not None
        assert (held.pan, held.tilt) == pytest.approx((cmd.pan, cmd.tilt))
    # ... then the search takes over (with no hold, it starts from the look's bearing).
    after = c.tracking(0.6, _estimate(0.6, (5.0, 5.0, 5.0), tracked=False))
    assert after is not None
    assert (after.pan, after.tilt) != pytest.approx((cmd.pan, cmd.tilt))


def test_a_confirmed_candidate_or_a_lock_ends_a_look() -> None:
    c = _controller(cue_look_s=1.0)
    lost = _estimate(0.0, (5.0, 5.0, 5.0), tracked=False)
    c.tracking(0.0, lost, None, None, _cue((90.0, 40.0, 20.0), (0.0, 0.0, 0.0)))
    cand = _candidates((30.0, -20.0, 10.0), (0.0, 0.0, 0.0))
    cmd = c.tracking(0.1, lost, None, cand, None)
    assert cmd is not None
    assert (cmd.pan, cmd.tilt) == pytest.approx(aim_angles((30.0, -20.0, 10.0), MOUNT))
    locked = c.tracking(0.2, _estimate(0.2, (50.0, 10.0, 20.0)))
    assert locked is not None
    assert (locked.pan, locked.tilt) == pytest.approx(aim_angles((50.0, 10.0, 20.0), MOUNT))


def test_fixed_mode_sends_home_once_and_then_nothing() -> None:
    c = _controller(mode="fixed", home=(80.0, 0.0, 20.0))
    first = c.tracking(0.0, _estimate(0.0, (10.0, 0.0, 5.0)))
    assert first is not None
    assert (first.pan, first.tilt) == pytest.approx(aim_angles((80.0, 0.0, 20.0), MOUNT))
    assert all(
        c.tracking(0.1 * k, _estimate(0.1 * k, (10.0, 5.0, 5.0))) is None for k in range(1, 20)
    )


def test_commands_stay_within_the_joint_limits() -> None:
    c = _controller()
    # Straight up: the ideal tilt (−90°) is beyond the −68° limit.
    cmd = c.tracking(0.0, _estimate(0.0, (0.5, 0.0, 50.0)))
    assert cmd is not None
    assert cmd.tilt == pytest.approx(LIMITS[1][0])


def test_scanning_raster_covers_its_area() -> None:
    pan = (math.radians(-60), math.radians(60))
    tilt = (math.radians(-25), math.radians(5))
    angles = np.array([raster(t, pan, tilt, 4.0) for t in np.linspace(0, 30, 3001)])
    assert angles[:, 0].min() == pytest.approx(pan[0], abs=1e-3)
    assert angles[:, 0].max() == pytest.approx(pan[1], abs=1e-3)
    assert angles[:, 1].min() == pytest.approx(tilt[0], abs=1e-2)
    assert angles[:, 1].max() == pytest.approx(tilt[1], abs=1e-2)
    assert triangle(0.0, 1.0, 3.0, 2.0) == 1.0
    assert triangle(1.0, 1.0, 3.0, 2.0) == 3.0


@settings(max_examples=60, deadline=None)
@given(
    t_e=st.floats(0.5, 60.0),
    pan_e=st.floats(-2.0, 2.0),
    tilt_e=st.floats(-1.0, 1.0),
    period=st.floats(1.0, 10.0),
    t=st.floats(0.0, 60.0),
)
def test_a_raster_with_an_end_passes_through_it_and_stays_in_its_box(
    t_e: float, pan_e: float, tilt_e: float, period: float, t: float
) -> None:
    pan, tilt = (math.radians(-60), math.radians(60)), (math.radians(-25), math.radians(5))
    end = raster(t_e, pan, tilt, period, (t_e, pan_e, tilt_e))
    # θ(t_e) is the end angle, clipped into the box
    assert end[0] == pytest.approx(min(max(pan_e, pan[0]), pan[1]), abs=1e-9)
    assert end[1] == pytest.approx(min(max(tilt_e, tilt[0]), tilt[1]), abs=1e-9)
    p, q = raster(t, pan, tilt, period, (t_e, pan_e, tilt_e))
    assert pan[0] - 1e-12 <= p <= pan[1] + 1e-12
    assert tilt[0] - 1e-12 <= q <= tilt[1] + 1e-12
    # the same waves, shifted in time: the pan sweeps at the rate of the unshifted raster
    h = 1e-4
    rate = abs(raster(t + h, pan, tilt, period, (t_e, pan_e, tilt_e))[0] - p) / h
    assert rate <= 2 * (pan[1] - pan[0]) / period * (1 + 1e-6)


def test_the_background_scan_ends_at_home() -> None:
    home = (60.0, 10.0, 15.0)
    c = _controller(home=home, scan_end_s=10.0)
    cmd = c.scanning(10.0)
    assert (cmd.pan, cmd.tilt) == pytest.approx(aim_angles(home, MOUNT), abs=1e-9)
    # without an end the raster falls where it falls: 2.5 periods of 4 s, the far edge
    far = _controller(home=home).scanning(10.0)
    assert far.pan == pytest.approx(math.radians(60.0))


def test_a_look_at_task_centres_the_search_on_its_point() -> None:
    c = _controller(home=(60.0, 0.0, 15.0), search_hold_s=1.0)
    lost = _estimate(0.0, (5.0, 5.0, 5.0), tracked=False)
    for k in range(5):  # searching from home (the hold)
        c.tracking(0.1 * k, lost)
    point = np.array([60.0, -50.0, 20.0])  # 40° right of home, in the search area
    assert c.look_at(0.5, point)
    cmd = c.tracking(0.5, lost)
    assert cmd is not None
    # the search starts at once, from the point: its first command is the point's aim
    assert (cmd.pan, cmd.tilt) == pytest.approx(aim_angles(point, MOUNT))
    later = [c.tracking(0.5 + 0.1 * k, lost) for k in range(1, 30)]
    pans = [cmd.pan for cmd in later if cmd is not None]
    # it searches about the point, not about home (pan 0)
    assert abs(np.mean(pans) - aim_angles(point, MOUNT)[0]) < math.radians(15)
    assert abs(np.mean(pans)) > math.radians(25)


def test_a_look_at_waits_for_the_lock_to_end_and_fixed_modes_refuse_it() -> None:
    c = _controller(search_hold_s=0.0)
    target = (50.0, 10.0, 20.0)
    point = np.array([-40.0, 80.0, 30.0])
    c.tracking(0.0, _estimate(0.0, target))
    assert c.look_at(0.1, point)
    held = c.tracking(0.1, _estimate(0.1, target))
    assert held is not None
    assert (held.pan, held.tilt) == pytest.approx(aim_angles(target, MOUNT))  # still on it
    lost = c.tracking(0.2, _estimate(0.2, target, tracked=False))
    assert lost is not None
    assert (lost.pan, lost.tilt) == pytest.approx(aim_angles(point, MOUNT))  # search there
    assert not _controller(mode="fixed").look_at(0.0, point)
    assert not _controller().look_at(0.0, np.array([np.nan, 0.0, 0.0]))
