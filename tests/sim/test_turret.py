"""The turret plant: limits, latency, resolution, modes; and aiming through the mount."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.config.rig import make_turret
from dronetrack.control.aiming import aim_angles
from dronetrack.errors import ConfigError, InputError
from dronetrack.geometry.mount import MountGeometry, sensor_poses
from dronetrack.sim.turret import TurretPlant
from dronetrack.types import TurretCommand

WIDOWX = make_turret("widowx")


def _move(plant: TurretPlant, pan: float, tilt: float, until: float, mode: str = "position"):
    plant.command(TurretCommand(plant.time, pan, tilt, mode))  # type: ignore[arg-type]
    return plant.advance(until)


def test_rate_and_acceleration_limits_hold() -> None:
    from dataclasses import replace

    # Without quantisation the pointing is the integrated angle itself.
    exact = replace(WIDOWX, pan=replace(WIDOWX.pan, resolution=0.0))
    plant = TurretPlant(exact)
    t, pan, _ = _move(plant, math.radians(150), math.radians(-60), 2.0)
    dt = t[1] - t[0]
    rate = np.diff(pan) / dt
    accel = np.diff(rate) / dt
    assert np.max(np.abs(rate)) <= WIDOWX.pan.rate * (1 + 1e-9)
    assert np.max(np.abs(accel)) <= WIDOWX.pan.accel * (1 + 1e-6)
    # It reaches the goal at the limits and stays: a trapezoid of 150° at 180°/s and
    # 360°/s² takes 150/180 + 180/360 = 1.33 s after the latency.
    assert pan[-1] == pytest.approx(math.radians(150), abs=1e-9)
    reached = t[np.argmax(np.abs(pan - math.radians(150)) < 1e-4)]
    assert reached == pytest.approx(150 / 180 + 180 / 360 + WIDOWX.pan.latency, abs=0.03)
    # With the preset's 0.088° resolution the reported angle sits on the encoder grid.
    plant = TurretPlant(WIDOWX)
    _, _, tilt = _move(plant, math.radians(150), math.radians(-60), 2.0)
    q = WIDOWX.tilt.resolution
    np.testing.assert_allclose(tilt / q, np.round(tilt / q), atol=1e-9)
    assert tilt[-1] == pytest.approx(math.radians(-60), abs=q)


def test_time_only_runs_forward() -> None:
    plant = TurretPlant(WIDOWX)
    plant.advance(0.1)
    with pytest.raises(InputError, match="forward"):
        plant.advance(0.1)


def test_latency_delays_the_response() -> None:
    plant = TurretPlant(WIDOWX)
    t, pan, _ = _move(plant, 0.5, 0.0, 0.1)
    moving = t[np.flatnonzero(pan != 0.0)[0]]
    # From rest at α_max the pointing leaves zero at ½ α τ² = q/2, i.e. τ = √(q/α),
    # after the command latency.
    q, accel = WIDOWX.pan.resolution, WIDOWX.pan.accel
    assert moving == pytest.approx(WIDOWX.pan.latency + math.sqrt(q / accel), abs=2e-3)


def test_position_resolution_and_joint_limits() -> None:
    plant = TurretPlant(WIDOWX)
    _move(plant, math.radians(10.03), math.radians(200.0), 3.0)
    state = plant.state()
    q = WIDOWX.pan.resolution
    assert state.pan / q == pytest.approx(round(state.pan / q), abs=1e-9)
    # Tilt is clipped to its ±68° limit.
    assert state.tilt == pytest.approx(WIDOWX.tilt.upper, abs=q)


def test_velocity_mode_runs_at_the_commanded_rate() -> None:
    plant = TurretPlant(WIDOWX)
    t, pan, _ = _move(plant, math.radians(30), 0.0, 1.0, mode="velocity")
    late = t > 0.5
    rate = np.polyfit(t[late], pan[late], 1)[0]
    assert rate == pytest.approx(math.radians(30), rel=0.01)
    with pytest.raises(ConfigError, match="mode"):
        plant.command(TurretCommand(1.0, 0.0, 0.0, "spin"))  # type: ignore[arg-type]


def test_time_based_profile_makes_every_move_last_its_profile_time() -> None:
    from dataclasses import replace

    shipped = replace(WIDOWX, profile_time_s=1.0)
    q = shipped.pan.resolution
    for goal in (0.1, 1.0):
        plant = TurretPlant(shipped)
        t, pan, _ = _move(plant, goal, 0.0, 1.5)
        at = {s: pan[np.argmin(np.abs(t - shipped.pan.latency - s))] for s in (0.5, 0.9, 1.0)}
        # A triangular move: half way at half time, 2 (0.1)² = 2 % short at 90 %, there at 100 %.
        assert at[0.5] == pytest.approx(goal / 2, abs=q)
        assert at[0.9] == pytest.approx(goal * 0.98, abs=q)
        assert at[1.0] == pytest.approx(goal, abs=q)


def test_each_axis_has_its_own_latency() -> None:
    from dataclasses import replace

    slow_tilt = replace(WIDOWX, tilt=replace(WIDOWX.tilt, latency=0.05))
    plant = TurretPlant(slow_tilt)
    t, pan, tilt = _move(plant, 0.5, 0.5, 0.2)
    first = {name: t[np.flatnonzero(a != 0.0)[0]] for name, a in (("pan", pan), ("tilt", tilt))}
    rise = math.sqrt(WIDOWX.pan.resolution / WIDOWX.pan.accel)
    assert first["pan"] == pytest.approx(0.020 + rise, abs=2e-3)
    assert first["tilt"] == pytest.approx(0.050 + rise, abs=2e-3)


def test_unknown_turret() -> None:
    with pytest.raises(ConfigError, match="unknown turret"):
        make_turret("ptu-x")


@given(
    st.floats(-200, 200),
    st.floats(-200, 200),
    st.floats(-20, 80),
    st.tuples(st.floats(-0.1, 0.1), st.floats(-0.1, 0.1), st.floats(0, 0.2)),
    st.tuples(st.floats(-0.1, 0.1), st.floats(-0.1, 0.1), st.floats(-0.1, 0.2)),
)
def test_aiming_puts_the_target_on_the_optical_axis(
    x: float, y: float, z: float, pan_to_tilt: tuple, tilt_to_sensor: tuple
) -> None:
    mount = MountGeometry((0.0, 0.0, 1.0), pan_to_tilt, tilt_to_sensor)
    target = np.array([x, y, z])
    if np.linalg.norm(target[:2]) < 2.0:
        return
    pan, tilt = aim_angles(target, mount)
    T = sensor_poses(pan, tilt, mount)
    to_target = target - T[:3, 3]
    axis = T[:3, 0]
    miss = np.linalg.norm(np.cross(axis, to_target))
    assert miss < 1e-8 * max(1.0, np.linalg.norm(to_target))
    assert axis @ to_target > 0


def test_aiming_reduces_to_seed_000_eq_10_at_the_pivot() -> None:
    mount = MountGeometry((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    pan, tilt = aim_angles((30.0, 40.0, 50.0), mount)
    assert pan == pytest.approx(math.atan2(40, 30))
    assert tilt == pytest.approx(-math.atan2(50, 50))


def test_one_axis_command_moves_that_axis_alone_after_its_latency() -> None:
    # A goal for the pan axis alone moves it exactly as a two-axis command whose
    # tilt goal is where the tilt already is; the tilt never moves.
    alone, both = TurretPlant(WIDOWX, tilt=0.3), TurretPlant(WIDOWX, tilt=0.3)
    alone.command_axis("pan", 0.0, 0.8)
    both.command(TurretCommand(0.0, 0.8, 0.3))
    t, pan, tilt = alone.advance(1.0)
    _, pan_both, _ = both.advance(1.0)
    np.testing.assert_array_equal(pan, pan_both)
    assert np.all(tilt == alone.state().tilt)
    # nothing moves before the latency
    assert np.all(pan[t < WIDOWX.pan.latency] == 0.0)
    assert pan[-1] == pytest.approx(0.8, abs=WIDOWX.pan.resolution)
    # the advance's path is kept
    assert alone.last_path is not None
    for kept, path in zip(alone.last_path, (t, pan, tilt), strict=True):
        np.testing.assert_array_equal(kept, path)


def test_one_axis_command_needs_an_axis_and_a_finite_angle() -> None:
    plant = TurretPlant(WIDOWX)
    with pytest.raises(ConfigError, match="'pan' or 'tilt'"):
        plant.command_axis("roll", 0.0, 0.1)
    with pytest.raises(ConfigError, match="finite"):
        plant.command_axis("tilt", 0.0, math.nan)


@given(
    shift=st.floats(-50.0, 50.0),
    cut=st.floats(0.001, 0.6),
    profile=st.sampled_from(["widowx", "ptu-e46"]),
)
def test_a_rebased_plant_moves_as_before_on_its_new_clock(
    shift: float, cut: float, profile: str
) -> None:
    """A goal in hand and one still queued: rebasing the plant's clock by Δ at any moment
    of the move changes nothing but the times, as if the clock had always read t + Δ."""
    spec = make_turret(profile)
    ref, moved = TurretPlant(spec), TurretPlant(spec)
    for plant in (ref, moved):
        plant.command_axis("pan", 0.0, 0.6)
        plant.command_axis("tilt", 0.05, -0.3)  # still queued at small cuts
        plant.advance(cut)
    moved.rebase(cut + shift)
    assert moved.time == cut + shift
    t_ref, pan_ref, tilt_ref = ref.advance(cut + 1.0)
    t_mov, pan_mov, tilt_mov = moved.advance(cut + shift + 1.0)
    np.testing.assert_allclose(t_mov - shift, t_ref, atol=1e-9)
    np.testing.assert_allclose(pan_mov, pan_ref, atol=1e-9)
    np.testing.assert_allclose(tilt_mov, tilt_ref, atol=1e-9)


def test_a_plant_is_at_rest_once_its_goal_is_reached_and_none_is_queued() -> None:
    plant = TurretPlant(make_turret("widowx"))
    assert plant.at_rest
    plant.command_axis("pan", 0.0, 0.3)
    assert not plant.at_rest  # queued
    plant.advance(0.1)
    assert not plant.at_rest  # moving
    plant.advance(2.0)
    assert plant.at_rest
