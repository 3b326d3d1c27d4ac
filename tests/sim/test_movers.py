"""Walkers and vehicles: their paths, their returns labelled with their object index and
lying on their bodies, a car absent before it drives in and still once it has parked,
and worlds without them left as they were."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.config.scenarios import SCENARIOS
from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.jobs.simulate import flight_config
from dronetrack.sim.build import build_world
from dronetrack.sim.lidar import LIVOX_DIFFUSE_MAX
from dronetrack.sim.movers import (
    VEHICLE_ACCEL_M_S2,
    VEHICLE_SIZE_M,
    WALKER_HEIGHT_M,
    Mover,
    Movers,
    vehicle,
    walker,
)
from dronetrack.sim.scene import make_scene
from dronetrack.sim.world import FrameTruth, SimWorld
from dronetrack.types import ObjectTruth
from sim_helpers import avia_world

BEHIND = (-40.0, 0.0, 30.0)  # the target, out of an Avia's view looking along +x
BEAM_V = math.radians(0.28)  # the Avia's wider beam divergence


def _world(aim: tuple[float, float, float], movers: list[Mover], seed: int = 3) -> SimWorld:
    """An Avia without noise aimed at ``aim`` over the empty field (the ground only); the
    target hovers out of view; ``movers`` added."""
    world = avia_world(make_scene("empty"), None, seed, aim, BEHIND)
    world.add_movers(Movers(movers), np.random.default_rng(seed + 50))
    return world


def _objects(truth: FrameTruth) -> ObjectTruth:
    assert truth.objects is not None
    return truth.objects


def _in_body_frame(points: FloatArray, center: FloatArray, yaw: float) -> FloatArray:
    """World points in a body's frame: p_b = Rz(yaw)ᵀ (p − c)."""
    c, s = math.cos(yaw), math.sin(yaw)
    d = points - center
    return np.column_stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], d[:, 2]])


def test_a_walkers_returns_are_its_own_lie_on_its_body_and_take_its_reflectivity() -> None:
    # One walker in a 2 × 2 m patch 20 m ahead; the Avia's beam is 0.28° tall, 10 cm there.
    person = walker((19.0, -1.0, 21.0, 1.0), (1.0, 1.6), (0.0, 2.0), np.random.default_rng(5))
    world = _world((20.0, 0.0, 0.9), [person])
    movers = world.movers
    assert movers is not None
    slack = 0.5 * BEAM_V * 22.0 + 1.6 * 0.1  # half the footprint, and a frame's walk
    for _ in range(20):
        frame, truth = world.step()
        objects = _objects(truth)
        assert objects.kinds.tolist() == ["drone", "walker"]
        mine = objects.object_index == 1
        assert mine.sum() > 50  # a person 20 m ahead on the axis fills many beams
        body = _in_body_frame(
            frame.world_points()[mine], objects.positions[1], movers.movers[0].route.yaw(truth.t)
        )
        # 0.3 deep, 0.5 across, 1.75 tall about its centre
        assert np.all(np.abs(body[:, 0]) <= 0.15 + slack)
        assert np.all(np.abs(body[:, 1]) <= 0.25 + slack)
        assert np.all(np.abs(body[:, 2]) <= 0.5 * WALKER_HEIGHT_M + slack)
        # the intensity is the reflectivity of the parts hit: trousers 0.3 to shirt 0.5
        rho = frame.intensity[mine] / LIVOX_DIFFUSE_MAX
        assert np.all((rho >= 0.3 - 1e-6) & (rho <= 0.5 + 1e-6))
        # the ground under the walker is the scene's, never labelled as the walker
        assert np.all(objects.object_index[~mine] == -1)


def test_a_vehicle_enters_drives_in_parks_and_stays_still() -> None:
    # 14.1 m from (40, −10) to (30, 0) at 5 m/s, 2 m/s²: L / v + v / a = 5.33 s, so to
    # park at 6 s it enters at 0.67 s.
    car = vehicle([(40.0, -10.0), (30.0, 0.0)], 5.0, 6.0)
    length = math.hypot(10.0, 10.0)
    assert car.enter_s == pytest.approx(6.0 - (length / 5.0 + 5.0 / VEHICLE_ACCEL_M_S2))
    world = _world((32.0, -3.0, 0.75), [car])
    parked: list[FloatArray] = []
    for _ in range(90):  # 9 s
        frame, truth = world.step()
        objects = _objects(truth)
        mine = objects.object_index == 1
        if truth.t < car.enter_s:
            assert not objects.present[1]
            assert np.all(np.isnan(objects.positions[1]))
            assert not mine.any()
            continue
        assert objects.present[1]
        assert objects.kinds[1] == "vehicle"
        if truth.t >= 6.0:
            # Parked on its last point, at rest, facing the way it drove in (135°).
            np.testing.assert_allclose(objects.positions[1], [30.0, 0.0, 0.75], atol=1e-9)
            np.testing.assert_array_equal(objects.velocities[1], 0.0)
            assert car.route.yaw(truth.t) == pytest.approx(math.radians(135.0))
            body = _in_body_frame(frame.world_points()[mine], objects.positions[1], 0.75 * math.pi)
            half = 0.5 * np.array(VEHICLE_SIZE_M) + 0.5 * BEAM_V * 35.0
            assert mine.sum() > 100
            assert np.all(np.abs(body) <= half)
            parked.append(frame.world_points()[mine])
            rho = frame.intensity[mine] / LIVOX_DIFFUSE_MAX
            assert np.all((rho >= 0.05 - 1e-6) & (rho <= 0.4 + 1e-6))  # tyres to paint
    assert len(parked) == 31  # the frames ending at 6.0, 6.1, ..., 9.0 s
    # Still: without noise its returns stay within its box frame after frame.
    everything = np.concatenate(parked)
    assert np.ptp(everything, axis=0).max() <= max(VEHICLE_SIZE_M) + 0.2


@settings(max_examples=25, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    lo=st.floats(0.2, 2.0),
    spread=st.floats(0.0, 1.0),
    pause_hi=st.floats(0.0, 8.0),
    width=st.floats(2.0, 40.0),
)
def test_a_walk_keeps_to_its_area_its_speeds_and_its_pauses(
    seed: int, lo: float, spread: float, pause_hi: float, width: float
) -> None:
    hi = lo + spread
    area = (-5.0, 10.0, -5.0 + width, 10.0 + 0.5 * width)
    person = walker(area, (lo, hi), (0.5 * pause_hi, pause_hi), np.random.default_rng(seed))
    t = np.linspace(0.0, 120.0, 2401)
    p = person.route.position(t)
    v = person.route.velocity(t)
    lo_xy, hi_xy = np.array(area[:2]) - 1e-9, np.array(area[2:]) + 1e-9
    assert np.all(p[:, :2] >= lo_xy)
    assert np.all(p[:, :2] <= hi_xy)
    np.testing.assert_allclose(p[:, 2], 0.5 * WALKER_HEIGHT_M)
    assert np.linalg.norm(v, axis=1).max() <= hi + 1e-9
    path = person.route.drawn
    assert path.end > 120.0
    speed = np.linalg.norm(path.v, axis=1)
    accel = np.linalg.norm(path.a, axis=1)
    cruising = (accel == 0) & (speed > 0)
    assert np.all((speed[cruising] >= lo - 1e-9) & (speed[cruising] <= hi + 1e-9))
    # Pauses at the waypoints (segments at rest after the first) last [p_lo, p_hi].
    pauses = np.diff(path.knots)[1:][(accel[1:] == 0) & (speed[1:] == 0)]
    assert np.all((pauses >= 0.5 * pause_hi - 1e-9) & (pauses <= pause_hi + 1e-9))
    # It faces the way it walks.
    for k in np.flatnonzero(np.linalg.norm(v[:, :2], axis=1) > 0.1)[::50]:
        yaw = person.route.yaw(float(t[k]))
        heading = np.array([math.cos(yaw), math.sin(yaw)])
        np.testing.assert_allclose(heading, v[k, :2] / np.linalg.norm(v[k, :2]), atol=1e-9)


def test_a_walk_is_the_same_however_far_ahead_it_is_asked_for() -> None:
    """The walk is drawn on as the clock asks for it, from the walker's own stream: asked
    for 100 s at once or a frame at a time, it is the same walk."""
    area, speed, pause = (0.0, 0.0, 20.0, 20.0), (1.0, 1.6), (0.0, 5.0)
    at_once = walker(area, speed, pause, np.random.default_rng(9))
    stepwise = walker(area, speed, pause, np.random.default_rng(9))
    t = np.arange(0.0, 100.0, 0.1)
    far = at_once.route.position(t)
    near = np.concatenate([stepwise.route.position(ti) for ti in t])
    np.testing.assert_allclose(far, near)
    another = walker(area, speed, pause, np.random.default_rng(10))
    assert not np.allclose(another.route.position(t), far)


def test_a_vehicle_needs_a_path_and_movers_come_once_before_the_first_frame() -> None:
    with pytest.raises(InputError, match="at least two points"):
        vehicle([(0.0, 0.0)], 5.0, 3.0)
    world = _world((20.0, 0.0, 1.0), [vehicle([(40.0, 0.0), (30.0, 0.0)], 5.0, 3.0)])
    with pytest.raises(InputError, match="once, before its frames"):
        world.add_movers(Movers([]), np.random.default_rng(0))


def test_walkers_and_vehicles_out_of_view_leave_the_frames_as_they_were() -> None:
    """Walkers and vehicles draw from a stream of their own: where none is ever seen, the
    frames are those of a world without them."""
    aim = (60.0, 0.0, 8.0)
    plain = avia_world(make_scene("outdoor"), None, 4, aim, (60.0, 2.0, 8.0))
    busy = avia_world(make_scene("outdoor"), None, 4, aim, (60.0, 2.0, 8.0))
    behind = walker((-30.0, -5.0, -20.0, 5.0), (1.0, 1.6), (0.0, 1.0), np.random.default_rng(1))
    busy.add_movers(
        Movers([behind, vehicle([(-40, 10), (-30, 10)], 5, 1)]), np.random.default_rng(2)
    )
    for _ in range(5):
        (fa, _), (fb, tb) = plain.step(), busy.step()
        np.testing.assert_array_equal(fa.points, fb.points)
        np.testing.assert_array_equal(fa.intensity, fb.intensity)
        assert _objects(tb).kinds.tolist() == ["drone", "walker", "vehicle"]
        assert _objects(tb).returns()[1:].sum() == 0


def test_walkers_and_vehicles_come_after_the_drones_and_birds_in_the_truth() -> None:
    cfg = SCENARIOS["outdoor-clutter"].model_copy(
        update={
            "walkers": SCENARIOS["site-busy"].walkers,
            "vehicles": SCENARIOS["site-busy"].vehicles,
        }
    )
    world = build_world(cfg)
    _, truth = world.step()
    objects = _objects(truth)
    birds = cfg.scene.clutter.birds if cfg.scene.clutter is not None else 0
    assert objects.kinds.tolist() == ["drone"] + ["bird"] * birds + ["walker"] * 4 + ["vehicle"]
    np.testing.assert_array_equal(objects.ids, np.arange(len(objects)))


def test_walkers_and_vehicles_leave_the_drones_flights_alone() -> None:
    """They draw from a stream spawned after the drones': the target flies the same path
    with them as without."""
    busy = SCENARIOS["site-busy"]
    alone = busy.model_copy(update={"walkers": (), "vehicles": ()})
    t = np.linspace(0.0, 40.0, 81)
    np.testing.assert_array_equal(
        build_world(busy).trajectory.position(t), build_world(alone).trajectory.position(t)
    )


def test_a_vehicle_parks_arrive_s_after_the_background_scan() -> None:
    cfg = SCENARIOS["site-busy"]
    world = build_world(flight_config(cfg))
    movers = world.movers
    assert movers is not None
    scan_s = cfg.pipeline.background.scan_s
    park = scan_s + cfg.vehicles[0].arrive_s
    car = movers.movers[-1]
    x, y = cfg.vehicles[0].path_m[-1]
    for t in (park, park + 5.0, scan_s + cfg.duration_s):
        np.testing.assert_allclose(car.route.position(t)[0], [x, y, 0.75], atol=1e-9)
        np.testing.assert_array_equal(car.route.velocity(t)[0], 0.0)
    assert np.linalg.norm(car.route.velocity(park - 1.0)[0]) > 0
