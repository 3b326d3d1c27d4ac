"""The simulator as a frame source: geometry of the returns, per-point poses, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dronetrack.config.rig import make_turret
from dronetrack.config.scenarios import SCENARIOS
from dronetrack.control.aiming import aim_angles
from dronetrack.sim.build import build_world
from dronetrack.sim.drones import make_drone
from dronetrack.sim.physics import extinction_coefficient
from dronetrack.sim.scene import make_scene
from dronetrack.sim.sensors import make_sensor
from dronetrack.sim.trajectories import Waypoint, fly_waypoints
from dronetrack.sim.world import SimWorld
from dronetrack.types import TurretCommand

TURRET = make_turret("widowx")


def _world(
    sensor: str = "avia",
    scene: str = "empty",
    target=(40.0, 5.0, 10.0),
    seed: int = 3,
    noise: bool = False,
    trajectory=None,
) -> SimWorld:
    traj = trajectory or fly_waypoints(target, [])
    pan, tilt = aim_angles(target, TURRET.mount)
    return SimWorld(
        make_sensor(sensor, noise=noise),
        make_scene(scene),
        make_drone("phantom4"),
        traj,
        TURRET,
        TURRET.mount,
        extinction_coefficient(math.inf),
        np.random.default_rng(seed),
        pan=pan,
        tilt=tilt,
    )


def test_noise_free_ground_returns_lie_on_the_ground_while_the_turret_slews() -> None:
    world = _world(target=(20.0, 0.0, 0.5))
    # Slew fast in velocity mode: every point needs the pose at its own time.
    world.command(TurretCommand(0.0, math.radians(120), math.radians(40), "velocity"))
    for _ in range(4):
        frame, truth = world.step()
    pan_path = np.unwrap([math.atan2(T[1, 0], T[0, 0]) for T in frame.poses])
    assert np.ptp(pan_path) > math.radians(10)  # the sensor turned >10° within the frame
    ground = ~truth.hit_target
    assert ground.sum() > 1000
    z = frame.world_points()[ground, 2]
    np.testing.assert_allclose(z, 0.0, atol=1e-6)
    # A single pose for the whole frame would misplace them by metres.
    mid = frame.poses[len(frame.poses) // 2]
    wrong = frame.points[ground] @ mid[:3, :3].T + mid[:3, 3]
    assert np.abs(wrong[:, 2]).max() > 0.5


def test_target_returns_lie_on_the_moving_target() -> None:
    traj = fly_waypoints((30.0, -20.0, 8.0), [Waypoint((30.0, 20.0, 8.0), 15.0, 15.0)])
    world = _world(target=(30.0, 0.0, 8.0), trajectory=traj, scene="sky")
    radius = make_drone("phantom4").radius
    n_hits = 0
    for _ in range(25):
        pan, tilt = aim_angles(traj.position(world.time)[0], world.mount)
        world.command(TurretCommand(world.time, pan, tilt))
        frame, truth = world.step()
        if truth.hit_target.any():
            pts = frame.world_points()[truth.hit_target]
            at = traj.position(frame.t[truth.hit_target])
            n_hits += len(pts)
            # Each return is on the target as it was when the pulse was fired, up to
            # half the beam footprint: a pulse whose centre just misses the target
            # still returns from it, placed along its central ray.
            ranges = np.linalg.norm(frame.points[truth.hit_target], axis=1)
            half_footprint = 0.5 * make_sensor("avia").divergence_v * ranges
            assert np.all(np.linalg.norm(pts - at, axis=1) <= radius + half_footprint + 1e-6)
    assert n_hits > 200


def test_same_seed_same_frames_other_seed_other_frames() -> None:
    def frames(seed: int) -> list[np.ndarray]:
        world = build_world(SCENARIOS["default"].model_copy(update={"seed": seed}))
        return [world.step()[0].points for _ in range(3)]

    a, b, c = frames(5), frames(5), frames(6)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert any(len(x) != len(z) or not np.array_equal(x, z) for x, z in zip(a, c, strict=True))


def test_noise_matches_the_datasheet() -> None:
    quiet = _world(scene="empty", target=(15.0, 0.0, 0.3), noise=False, seed=1)
    noisy = _world(scene="empty", target=(15.0, 0.0, 0.3), noise=True, seed=1)
    fq, tq = quiet.step()
    fn, tn = noisy.step()
    # Same pulses hit the same ground; compare ranges where both returned.
    keep_q = ~tq.hit_target
    keep_n = ~tn.hit_target
    common, iq, i_n = np.intersect1d(fq.t[keep_q], fn.t[keep_n], return_indices=True)
    assert len(common) > 2000
    rq = np.linalg.norm(fq.points[keep_q][iq], axis=1)
    rn = np.linalg.norm(fn.points[keep_n][i_n], axis=1)
    near = rq < 10  # where the ground's slope makes angular noise negligible in range
    assert np.std((rn - rq)[near]) == pytest.approx(0.02, rel=0.2)


def test_frames_carry_integration_time_and_pose_samples() -> None:
    world = _world()
    frame, truth = world.step()
    assert frame.stamp == 0.0
    assert frame.end == pytest.approx(0.1)
    assert frame.t.min() >= 0.0
    assert frame.t.max() < 0.1
    assert frame.pose_t[0] == 0.0
    assert frame.pose_t[-1] == pytest.approx(0.1)
    assert truth.n_pulses == 24_000
    assert frame.line.max() == 5


@pytest.mark.slow
def test_frame_times_do_not_drift() -> None:
    world = _world(scene="sky")
    for _ in range(1000):
        frame, _truth = world.step()
    assert frame.stamp == 999 * 0.1
    assert frame.end == 1000 * 0.1
    assert np.all((frame.t >= frame.stamp) & (frame.t < frame.end))


def test_nothing_returns_from_beyond_the_maximum_range() -> None:
    # A bright board on the VLP-16's +1° beam: seen at 60 m, but not at 110 m,
    # beyond the 100 m the sensor is rated for.
    from dataclasses import replace

    turret = make_turret("ptu-e46")
    height = turret.mount.base[2] + turret.mount.pan_to_tilt[2] + turret.mount.tilt_to_sensor[2]
    sign = replace(make_drone("sign"), body=make_drone("sign", 2.0).body)

    def returns(range_m: float) -> int:
        at = (range_m, 0.0, height + range_m * math.tan(math.radians(1.0)))
        world = SimWorld(
            make_sensor("vlp16", noise=False),
            make_scene("sky"),
            sign,
            fly_waypoints(at, []),
            turret,
            turret.mount,
            0.0,
            np.random.default_rng(0),
        )
        return sum(world.step()[1].n_target_points for _ in range(5))

    assert returns(60.0) > 0
    assert returns(110.0) == 0


def test_vlp16_revolution_sees_the_room_all_around() -> None:
    cfg = SCENARIOS["indoor-horizontal"].model_copy(
        update={"sensor": SCENARIOS["walk-line"].sensor}
    )
    world = build_world(cfg)
    frame, _ = world.step()
    az = np.degrees(np.arctan2(frame.points[:, 1], frame.points[:, 0]))
    counts, _ = np.histogram(az, bins=12, range=(-180, 180))
    assert counts.min() > 100
    # Nothing is further than the room's far corner from the sensor.
    assert np.linalg.norm(frame.points, axis=1).max() < 11.0
