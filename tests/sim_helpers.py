"""Small simulated worlds the simulator's tests share."""

from __future__ import annotations

import numpy as np

from dronetrack.config.rig import make_turret
from dronetrack.config.run import ScenarioConfig
from dronetrack.control.aiming import aim_angles
from dronetrack.sim.build import build_world
from dronetrack.sim.clutter import ClutterSpec
from dronetrack.sim.drones import make_drone
from dronetrack.sim.scene import Scene
from dronetrack.sim.sensors import make_sensor
from dronetrack.sim.trajectories import fly_waypoints
from dronetrack.sim.world import SimWorld

__all__ = ["TURRET", "assert_same_frames", "avia_world"]

TURRET = make_turret("widowx")


def avia_world(
    scene: Scene,
    clutter: ClutterSpec | None,
    seed: int,
    aim: tuple[float, float, float],
    target: tuple[float, float, float],
) -> SimWorld:
    """An Avia without noise (nor its own false alarms) on a WidowX aimed at ``aim``; a
    Phantom 4, the target, hovers at ``target``."""
    pan, tilt = aim_angles(aim, TURRET.mount)
    return SimWorld(
        make_sensor("avia", noise=False),
        scene,
        make_drone("phantom4"),
        fly_waypoints(target, []),
        TURRET,
        TURRET.mount,
        0.0,
        np.random.default_rng(seed),
        pan=pan,
        tilt=tilt,
        clutter=clutter,
    )


def assert_same_frames(a: ScenarioConfig, b: ScenarioConfig, frames: int) -> None:
    """The worlds of ``a`` and ``b`` give the same points, and the same object for each,
    for their first ``frames`` frames."""
    world_a, world_b = build_world(a), build_world(b)
    for _ in range(frames):
        (fa, ta), (fb, tb) = world_a.step(), world_b.step()
        np.testing.assert_array_equal(fa.points, fb.points)
        assert ta.objects is not None
        assert tb.objects is not None
        np.testing.assert_array_equal(ta.objects.object_index, tb.objects.object_index)
