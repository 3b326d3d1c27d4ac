"""Seed 003's scan strategies: sweep, swing, slowdown, stop, re-triggering, adaptive choice."""

from __future__ import annotations

import csv
import io
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.control.plans import (
    choose_strategy,
    slowdown_plan,
    stop_plan,
    sweep,
    sweep_plan,
    swing_plan,
    swing_time_bound,
)
from dronetrack.control.strategies import MODES, ScanStrategyController, Transition
from dronetrack.errors import ConfigError
from dronetrack.geometry.mount import MountGeometry
from dronetrack.types import TrackEstimate

MOUNT = MountGeometry((0.0, 0.0, 1.0), (0.0, 0.0, 0.07), (0.0, 0.0, 0.12))  # ptu-e46
PAN_LIMITS = (math.radians(-159.0), math.radians(159.0))
TILT_LIMITS = (math.radians(-31.0), math.radians(47.0))
NONE = np.empty((0, 3))
RATE = math.radians(30.0)


def rad(deg: float) -> float:
    return math.radians(deg)


def deg(x: float) -> float:
    return math.degrees(x)


def _controller(mode: str = "swing", **kw: object) -> ScanStrategyController:
    return ScanStrategyController(MOUNT, PAN_LIMITS, TILT_LIMITS, mode, **kw)  # type: ignore[arg-type]


def _at(bearing_deg: float, range_m: float = 20.0, n: int = 5) -> np.ndarray:
    """A small cluster of foreground points centred at a bearing and range from the base."""
    b = rad(bearing_deg)
    c = np.array([range_m * math.cos(b), range_m * math.sin(b), 3.0])
    offsets = np.linspace(-0.1, 0.1, n)[:, None] * np.array([[-math.sin(b), math.cos(b), 0.5]])
    return np.asarray(c + offsets, dtype=np.float64)


def _estimate(
    t: float, tracked: bool = False, v: tuple[float, float, float] = (0.0, 0.0, 0.0)
) -> TrackEstimate:
    return TrackEstimate(t, np.zeros(3), np.asarray(v, dtype=float), tracked, 0.1)


def _run(
    c: ScanStrategyController,
    times: np.ndarray,
    detections: dict[float, np.ndarray] | None = None,
    tracked: bool = False,
) -> np.ndarray:
    """Pan commands [deg] at ``times``, with foreground points at the times given.

    The estimates say the target is still (when ``tracked``) or not tracked.
    """
    detections = detections or {}
    pans = []
    for t in times:
        pts = next((p for tt, p in detections.items() if abs(tt - t) < 1e-9), NONE)
        cmd = c.tracking(float(t), _estimate(float(t), tracked), pts)
        assert cmd is not None
        pans.append(deg(cmd.pan))
    return np.array(pans)


# -- sweep ------------------------------------------------------------------


def test_sweep_is_a_triangle_wave_between_the_limits() -> None:
    lo, hi = rad(-90), rad(90)
    t = np.arange(0.0, 24.0, 0.01)
    pans = np.degrees([sweep(e, 0.0, 1, lo, hi, RATE)[0] for e in t])
    assert pans.max() == pytest.approx(90.0)
    assert pans.min() == pytest.approx(-90.0)
    assert t[np.argmax(pans)] == pytest.approx(3.0)  # 90° at 30°/s
    assert t[np.argmin(pans)] == pytest.approx(9.0)
    # Period 2 · 180° / 30°/s = 12 s, at 30°/s throughout.
    np.testing.assert_allclose(pans[1200:], pans[:-1200], atol=1e-9)
    assert np.abs(np.diff(pans)).max() == pytest.approx(0.3)
    assert sweep(3.0, 0.0, 1, lo, hi, RATE) == pytest.approx((hi, -1))
    assert sweep(1.0, 0.0, -1, lo, hi, RATE) == pytest.approx((rad(-30), -1))


def test_the_controller_scans_with_the_sweep() -> None:
    c = _controller()
    assert c.home == (0.0, 0.0)
    assert c.mode == "swing"
    cmds = [c.scanning(0.1 * k) for k in range(241)]
    pans = np.degrees([cmd.pan for cmd in cmds])
    assert pans.max() == pytest.approx(90.0)
    assert pans.min() == pytest.approx(-90.0)
    np.testing.assert_allclose(pans[120:], pans[:-120], atol=1e-9)
    assert {cmd.tilt for cmd in cmds} == {0.0}
    assert all(cmd.mode == "position" for cmd in cmds)
    assert c.transitions == []


angles = st.floats(-3.0, 3.0)
durations = st.floats(0.0, 100.0)


@given(
    elapsed=durations,
    dt=st.floats(0.0, 1.0),
    start=angles,
    direction=st.sampled_from([-1, 1]),
    lo=st.floats(-2.0, 0.0),
    span=st.floats(0.01, 3.0),
    rate=st.floats(0.01, 5.0),
)
def test_a_sweep_stays_within_its_limits_at_its_rate(
    elapsed: float, dt: float, start: float, direction: int, lo: float, span: float, rate: float
) -> None:
    hi = lo + span
    pan, d = sweep(elapsed, start, direction, lo, hi, rate)
    later, _ = sweep(elapsed + dt, start, direction, lo, hi, rate)
    assert lo <= pan <= hi
    assert d in (-1, 1)
    assert abs(later - pan) <= rate * dt + 1e-9 * (1 + rate * (elapsed + dt))


@given(
    a=durations,
    b=durations,
    start=angles,
    direction=st.sampled_from([-1, 1]),
    rate=st.floats(0.05, 2.0),
)
def test_a_resumed_sweep_continues_where_it_left_off(
    a: float, b: float, start: float, direction: int, rate: float
) -> None:
    lo, hi = -1.5, 1.0
    whole = sweep(a + b, start, direction, lo, hi, rate)[0]
    resumed = sweep(b, *sweep(a, start, direction, lo, hi, rate), lo, hi, rate)[0]
    assert resumed == pytest.approx(whole, abs=1e-9 * (1 + rate * (a + b)))


@given(
    start=angles,
    direction=st.sampled_from([-1, 1]),
    rate=st.floats(0.05, 2.0),
    duration=st.floats(0.0, 20.0),
    e=st.floats(0.0, 1.0),
)
def test_a_sweep_plan_is_the_sweep(
    start: float, direction: int, rate: float, duration: float, e: float
) -> None:
    lo, hi = -1.0, 1.2
    plan = sweep_plan(start, direction, lo, hi, rate, duration)
    assert plan.duration == pytest.approx(duration, abs=1e-9)
    got = plan.at(e * duration)[0]
    assert got == pytest.approx(sweep(e * duration, start, direction, lo, hi, rate)[0], abs=1e-9)
    end = sweep(duration, start, direction, lo, hi, rate)
    after = sweep(0.1, *plan.at(plan.duration), lo, hi, rate)[0]
    assert after == pytest.approx(sweep(duration + 0.1, start, direction, lo, hi, rate)[0])
    assert plan.at(plan.duration)[0] == pytest.approx(end[0], abs=1e-9)


# -- swing, slowdown, stop ----------------------------------------------------


@pytest.mark.parametrize("n", [1, 3, 5])
def test_a_swing_plan_crosses_the_window_n_times(n: int) -> None:
    # Inside the window, moving up: on to its upper edge, then n swings of 10°.
    plan = swing_plan(rad(17), 1, rad(20), n_swings=n)
    edges = [rad(15), rad(25)] * n
    assert plan.pans == pytest.approx((rad(17), rad(25), *edges[:n]))
    assert plan.times == pytest.approx([0.0, 8 / 30] + [8 / 30 + k / 3 for k in range(1, n + 1)])
    assert plan.direction == (-1 if n % 2 else 1)
    # From outside the window: to the nearer edge first.
    below = swing_plan(rad(0), -1, rad(20), n_swings=2)
    assert below.pans == pytest.approx((0.0, rad(15), rad(25), rad(15)))
    above = swing_plan(rad(40), 1, rad(20), n_swings=1)
    assert above.pans == pytest.approx((rad(40), rad(25), rad(15)))


def test_swing_oscillates_about_the_bearing_then_sweeps_on() -> None:
    c = _controller("swing")
    t = np.round(np.arange(0.0, 4.0, 0.01), 10)
    pans = _run(c, t, {0.5: _at(20.0)})
    # Sweeping up from 0° at 30°/s: at 15° when the target is seen at 20°.
    np.testing.assert_allclose(pans[t <= 0.5], 30.0 * t[t <= 0.5], atol=1e-9)
    approach_end, end = 0.5 + 1 / 3, 0.5 + 4 / 3
    swinging = (t >= approach_end) & (t <= end)
    assert pans[swinging].min() >= 15.0 - 1e-9
    assert pans[swinging].max() <= 25.0 + 1e-9
    # Exactly three swings: turning points at 25°, 15°, 25°, ending at 15° moving down.
    turns = np.flatnonzero(np.diff(np.sign(np.diff(pans[(t >= 0.5) & (t <= end)]))))
    assert len(turns) == 3
    assert c.transitions == [
        Transition(0.5, "sweep", "swing", "swing"),
        Transition(pytest.approx(end), "swing", "sweep", "swing"),  # type: ignore[arg-type]
    ]
    after = t > end + 0.01
    np.testing.assert_allclose(pans[after], 15.0 - 30.0 * (t[after] - end), atol=1e-6)
    assert c.state == "sweep"


def test_slowdown_goes_at_a_quarter_rate_for_ten_degrees() -> None:
    plan = slowdown_plan(rad(15), 1)
    assert plan.duration == pytest.approx(10.0 / 7.5)
    assert plan.at(plan.duration) == pytest.approx((rad(25), 1))
    c = _controller("slowdown")
    t = np.round(np.arange(0.0, 3.0, 0.01), 10)
    pans = _run(c, t, {0.5: _at(20.0)})
    end = 0.5 + 10.0 / 7.5
    slow = (t >= 0.5) & (t <= end)
    np.testing.assert_allclose(pans[slow], 15.0 + 7.5 * (t[slow] - 0.5), atol=1e-6)
    fast = t >= end
    np.testing.assert_allclose(pans[fast], 25.0 + 30.0 * (t[fast] - end), atol=1e-6)
    assert [(tr.from_state, tr.to_state) for tr in c.transitions] == [
        ("sweep", "slowdown"),
        ("slowdown", "sweep"),
    ]
    assert c.transitions[1].t == pytest.approx(end)


def test_a_slowdown_at_a_limit_bounces_like_the_sweep() -> None:
    plan = slowdown_plan(rad(85), 1)
    assert plan.pans == pytest.approx((rad(85), rad(90), rad(85)))
    assert plan.direction == -1


def test_stop_holds_on_the_bearing_for_five_seconds_then_resumes() -> None:
    c = _controller("stop")
    t = np.round(np.arange(0.0, 7.5, 0.05), 10)
    pans = _run(c, t, {0.5: _at(20.0)})
    held = (t >= 0.5) & (t <= 5.5)
    np.testing.assert_allclose(pans[held], 20.0, atol=1e-9)
    # Back to sweeping up from 20° at 30°/s.
    after = t >= 5.5
    np.testing.assert_allclose(pans[after], 20.0 + 30.0 * (t[after] - 5.5), atol=1e-6)
    assert c.transitions == [
        Transition(0.5, "sweep", "stop", "stop"),
        Transition(5.5, "stop", "sweep", "stop"),
    ]


def test_focus_stays_inside_the_sweep_range() -> None:
    assert stop_plan(rad(100), 1).pans == (rad(90), rad(90))
    window = swing_plan(rad(85), 1, rad(88), n_swings=2)
    assert max(window.pans) == pytest.approx(rad(90))
    assert min(window.pans) == pytest.approx(rad(80))


# -- re-triggering -------------------------------------------------------------


def test_a_bearing_jump_restarts_the_cycle_and_a_small_change_does_not() -> None:
    c = _controller("stop")
    t = np.round(np.arange(0.0, 9.0, 0.05), 10)
    pans = _run(c, t, {0.5: _at(20.0), 1.0: _at(23.0), 2.0: _at(30.0)})
    np.testing.assert_allclose(pans[(t >= 0.5) & (t < 2.0)], 20.0, atol=1e-9)
    np.testing.assert_allclose(pans[(t >= 2.0) & (t <= 7.0)], 30.0, atol=1e-9)
    assert c.transitions == [
        Transition(0.5, "sweep", "stop", "stop"),
        Transition(2.0, "stop", "stop", "stop"),
        Transition(7.0, "stop", "sweep", "stop"),
    ]


def test_a_swing_restarts_on_the_new_bearing() -> None:
    c = _controller("swing")
    t = np.round(np.arange(0.0, 3.0, 0.01), 10)
    pans = _run(c, t, {0.5: _at(20.0), 0.9: _at(40.0)})
    # From 0.9 s the window is 35°-45°; reached at 30°/s from wherever the swing was.
    late = (t >= 1.6) & (t <= 0.9 + swing_time_bound())
    assert pans[late].min() >= 35.0 - 1e-9
    assert pans[late].max() <= 45.0 + 1e-9
    assert [tr.to_state for tr in c.transitions] == ["swing", "swing", "sweep"]


def test_the_same_target_triggers_again_only_once_it_has_left_the_fan() -> None:
    c = _controller("slowdown")
    t = np.round(np.arange(0.0, 8.0, 0.1), 10)
    # Seen at 20° at 0.5 s; still in the fan after the slowdown (2.0 s, pan ≈ 30°):
    # ignored.  The sweep goes on to 90° and comes back through 20° near 6.3 s.
    seen = {0.5: _at(20.0), 2.0: _at(20.5), 6.0: _at(20.5)}
    _run(c, t, seen)
    starts = [tr.t for tr in c.transitions if tr.to_state == "slowdown"]
    assert starts == [0.5, 6.0]


def test_sweep_mode_never_reacts() -> None:
    c = _controller("sweep")
    t = np.round(np.arange(0.0, 3.0, 0.1), 10)
    pans = _run(c, t, {round(x, 10): _at(20.0) for x in t})
    np.testing.assert_allclose(pans, 30.0 * t, atol=1e-9)
    assert c.transitions == []


def test_the_bearing_is_taken_from_the_turret_base() -> None:
    mount = MountGeometry((5.0, 5.0, 1.0), (0.0, 0.0, 0.07), (0.0, 0.0, 0.12))
    c = ScanStrategyController(mount, PAN_LIMITS, TILT_LIMITS, "stop")
    c.scanning(0.0)
    cmd = c.tracking(0.1, None, np.array([[5.0, 25.0, 4.0], [5.0, 25.2, 4.0]]))
    assert cmd is not None
    assert cmd.pan == pytest.approx(rad(90))
    # Non-finite points are dropped; an all-NaN foreground is no detection.
    c2 = _controller("stop")
    c2.tracking(0.0, None, np.full((3, 3), np.nan))
    assert c2.transitions == []


# -- the adaptive rule ---------------------------------------------------------

OMEGA_STOP = rad(15) / 5.0  # the fan's half width over the hold: 3°/s
OMEGA_SWING = rad(10) / swing_time_bound()  # the window the swing keeps over its length
R_GAP = 0.5 / rad(2)  # a 0.5 m target spans a 2° gap out to 14.3 m


def test_the_default_thresholds() -> None:
    assert swing_time_bound() == pytest.approx(4.0 / 3.0)  # 10° approach + 3 × 10°, at 30°/s
    assert deg(OMEGA_SWING) == pytest.approx(7.5)
    assert math.isclose(R_GAP, 14.32, abs_tol=0.01)


@pytest.mark.parametrize(
    ("range_m", "speed", "expected"),
    [
        (10.0, 10.0 * OMEGA_STOP * (1 - 1e-9), "stop"),
        (10.0, 10.0 * OMEGA_STOP * (1 + 1e-9), "swing"),
        (10.0, 10.0 * OMEGA_SWING * (1 - 1e-9), "swing"),
        (10.0, 10.0 * OMEGA_SWING * (1 + 1e-9), "slowdown"),
        (R_GAP, 0.0, "stop"),
        (R_GAP * (1 + 1e-9), 0.0, "swing"),
        (80.0, 80.0 * OMEGA_SWING * (1 - 1e-9), "swing"),
        (80.0, 80.0 * OMEGA_SWING * (1 + 1e-9), "slowdown"),
        (5.0, -1.0, "slowdown"),  # the sign does not matter: 1 m/s at 5 m is 11.5°/s,
        (5.0, -0.5, "swing"),  # 0.5 m/s is 5.7°/s,
        (5.0, -0.2, "stop"),  # and 0.2 m/s 2.3°/s
        (30.0, None, "swing"),
        (30.0, math.nan, "swing"),
        (0.0, 0.1, "slowdown"),
        (math.inf, 100.0, "swing"),
    ],
)
def test_choose_strategy_boundaries(range_m: float, speed: float | None, expected: str) -> None:
    assert choose_strategy(range_m, speed) == expected


def test_choose_strategy_follows_its_parameters() -> None:
    # A bigger target spans the gaps farther out; a shorter hold tolerates faster drift.
    assert choose_strategy(25.0, 0.0) == "swing"
    assert choose_strategy(25.0, 0.0, target_size_m=1.0) == "stop"
    assert choose_strategy(10.0, 0.8) == "swing"
    assert choose_strategy(10.0, 0.8, stop_hold_s=2.0) == "stop"
    assert choose_strategy(10.0, 2.0, swing_duration_s=0.5) == "swing"


RANK = {"stop": 0, "swing": 1, "slowdown": 2}


@given(
    range_m=st.floats(0.1, 500.0),
    s1=st.floats(0.0, 50.0),
    s2=st.floats(0.0, 50.0),
)
def test_faster_targets_never_get_a_calmer_strategy(range_m: float, s1: float, s2: float) -> None:
    lo, hi = sorted((s1, s2))
    a, b = choose_strategy(range_m, lo), choose_strategy(range_m, hi)
    assert RANK[a] <= RANK[b]
    omega = hi / range_m
    assert (b == "slowdown") == (omega > OMEGA_SWING)
    assert (b == "stop") == (range_m <= R_GAP and omega <= OMEGA_STOP)


def _adaptive_first(range_m: float, v: tuple[float, float, float], tracked: bool = True) -> str:
    c = _controller("adaptive")
    c.tracking(0.5, _estimate(0.5, tracked, v), _at(0.0, range_m))
    return c.transitions[-1].to_state


def test_adaptive_uses_the_tracker_velocity_across_the_line_of_sight() -> None:
    assert _adaptive_first(10.0, (0.0, 0.0, 0.0)) == "stop"
    assert _adaptive_first(50.0, (0.0, 0.0, 0.0)) == "swing"
    assert _adaptive_first(20.0, (0.0, 5.0, 0.0)) == "slowdown"  # 14°/s across
    assert _adaptive_first(20.0, (5.0, 0.0, 3.0)) == "swing"  # radial and vertical only
    assert _adaptive_first(10.0, (0.0, 5.0, 0.0), tracked=False) == "swing"  # unknown


def test_adaptive_falls_back_on_consecutive_centroids() -> None:
    c = _controller("adaptive")
    c.tracking(0.5, _estimate(0.5), _at(0.0, 10.0))  # no speed yet: swing
    # 0.1 s later 2 m across (11°, a re-trigger): 20 m/s at 10 m, 115°/s.
    c.tracking(0.6, _estimate(0.6), _at(math.degrees(math.atan2(2.0, 10.0)), math.hypot(10, 2)))
    assert [tr.to_state for tr in c.transitions] == ["swing", "slowdown"]
    # A previous centroid older than speed_gap_s gives no speed.
    c2 = _controller("adaptive", speed_gap_s=0.05)
    c2.tracking(0.5, _estimate(0.5), _at(0.0, 10.0))
    c2.tracking(0.6, _estimate(0.6), _at(math.degrees(math.atan2(2.0, 10.0)), math.hypot(10, 2)))
    assert [tr.to_state for tr in c2.transitions] == ["swing", "swing"]


def test_centroid_speed_uses_the_longest_baseline() -> None:
    # 0°, then 4° (no re-trigger), then 6° (re-trigger) at 10 m over 1 s: 6°/s, a swing.
    # The last frame alone, 2° in 0.1 s, would read 20°/s and slow down.
    c = _controller("adaptive")
    for t, b in ((0.0, 0.0), (0.9, 4.0), (1.0, 6.0)):
        c.tracking(t, _estimate(t), _at(b, 10.0))
    assert [(tr.t, tr.to_state) for tr in c.transitions] == [(0.0, "swing"), (1.0, "swing")]


# -- the log and the limits ------------------------------------------------------


def test_transitions_write_as_csv_rows() -> None:
    c = _controller("adaptive")
    _run(c, np.round(np.arange(0.0, 8.0, 0.1), 10), {0.5: _at(20.0, 10.0)}, tracked=True)
    assert [(tr.from_state, tr.to_state, tr.strategy) for tr in c.transitions] == [
        ("sweep", "stop", "adaptive"),
        ("stop", "sweep", "adaptive"),
    ]
    out = io.StringIO()
    writer = csv.writer(out)
    writer.writerow(Transition._fields)
    writer.writerows(c.transitions)
    rows = list(csv.reader(io.StringIO(out.getvalue())))
    assert rows[0] == ["t", "from_state", "to_state", "strategy"]
    assert rows[1] == ["0.5", "sweep", "stop", "adaptive"]
    assert float(rows[2][0]) == pytest.approx(5.5)


events = st.lists(
    st.tuples(
        st.floats(0.0, 2.0),  # time to the next frame
        st.booleans(),  # foreground?
        st.floats(-180.0, 180.0),  # its bearing [deg]
        st.floats(1.0, 150.0),  # its range
        st.floats(-20.0, 20.0),  # tracked velocity across [m/s]
    ),
    max_size=40,
)


@given(
    mode=st.sampled_from(MODES),
    sweep_deg=st.tuples(st.floats(-200.0, 0.0), st.floats(1.0, 200.0)),
    tilt=st.floats(-1.5, 1.5),
    seq=events,
)
def test_commands_always_stay_within_the_limits(
    mode: str,
    sweep_deg: tuple[float, float],
    tilt: float,
    seq: list[tuple[float, bool, float, float, float]],
) -> None:
    c = _controller(mode, sweep_limits=(rad(sweep_deg[0]), rad(sweep_deg[1])), tilt=tilt)
    lo, hi = c.sweep_limits
    assert PAN_LIMITS[0] <= lo < hi <= PAN_LIMITS[1]
    t = 0.0
    cmds = [c.scanning(t)]
    for dt, seen, bearing, range_m, v in seq:
        t += dt
        b = rad(bearing)
        velocity = (-v * math.sin(b), v * math.cos(b), 0.0)
        pts = _at(bearing, range_m) if seen else NONE
        cmd = c.tracking(t, _estimate(t, v != 0.0, velocity), pts)
        assert cmd is not None
        cmds.append(cmd)
    for cmd in cmds:
        assert lo - 1e-12 <= cmd.pan <= hi + 1e-12
        assert TILT_LIMITS[0] <= cmd.tilt <= TILT_LIMITS[1]
        assert cmd.tilt == min(max(tilt, TILT_LIMITS[0]), TILT_LIMITS[1])
    times = [tr.t for tr in c.transitions]
    assert times == sorted(times)
    for before, after in zip(c.transitions, c.transitions[1:], strict=False):
        assert after.from_state == before.to_state
    if mode == "sweep":
        assert c.transitions == []


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"mode": "dance"}, "unknown scan strategy"),
        ({"sweep_rate": 0.0}, "sweep_rate"),
        ({"swing_rate": -1.0}, "swing_rate"),
        ({"sweep_limits": (rad(170), rad(180))}, "no range"),
        ({"slowdown_factor": 0.0}, "slowdown_factor"),
        ({"stop_hold_s": -1.0}, "stop_hold_s"),
        ({"swing_count": -1}, "swing_count"),
        ({"beam_gap": 0.0}, "beam_gap"),
    ],
)
def test_bad_settings_are_refused(kw: dict[str, object], message: str) -> None:
    mode = kw.pop("mode", "swing")
    with pytest.raises(ConfigError, match=message):
        _controller(str(mode), **kw)
