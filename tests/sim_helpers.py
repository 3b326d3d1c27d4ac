"""Small simulated worlds the simulator's tests share."""

from __future__ import annotations

import numpy as np

from dronetrack.config.rig import make_turret
from dronetrack.control.aiming import aim_angles
from dronetrack.sim.clutter import ClutterSpec
from dronetrack.sim.drones import make_drone
from dronetrack.sim.scene import Scene
from dronetrack.sim.sensors import make_sensor
from dronetrack.sim.trajectories import fly_waypoints
from dronetrack.sim.world import SimWorld

__all__ = ["TURRET", "avia_world"]

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
