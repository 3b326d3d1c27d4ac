"""A drone in the simulated world: its model, its path and when it enters.

The target a run is scored on is the first of a world's drones and is there from
the start; ``[[targets]]`` add others, each entering at its own time.  Before it
enters a drone is not in the world at all: no pulse meets it, and its truth is
marked not present.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.drones import DroneModel, attitude_from_acceleration
from dronetrack.sim.trajectories import Trajectory

__all__ = ["SimTarget"]


@dataclass(frozen=True, slots=True)
class SimTarget:
    """A drone flying ``trajectory``, in the world from ``enter_s`` [s] on."""

    drone: DroneModel
    trajectory: Trajectory
    enter_s: float = -math.inf

    def present(self, t: float) -> bool:
        """Whether the drone is in the world at time t."""
        return t >= self.enter_s

    def attitude(self, t: float) -> FloatArray:
        """world_R_body at time t: a multirotor's tilt from its acceleration, body x at
        yaw 0 (or towards the turret base for a target that faces the sensor)."""
        acc = self.trajectory.acceleration(t)[0]
        yaw = 0.0
        if self.drone.faces_sensor:
            p = self.trajectory.position(t)[0]
            yaw = float(np.arctan2(-p[1], -p[0]))
        return attitude_from_acceleration(acc, yaw)
