"""The closed-loop simulator: a source of LiDAR frames plus an actuator (the turret).

Ground truth travels on a separate channel (``FrameTruth``), so whatever
consumes the frames sees only what a real sensor would give it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry import FloatArray
from dronetrack.kinematics import MountGeometry, sensor_poses
from dronetrack.sim.drones import DroneModel
from dronetrack.sim.lidar import LidarSimulator
from dronetrack.sim.scene import Scene
from dronetrack.sim.sensors import SensorModel
from dronetrack.sim.trajectories import Trajectory
from dronetrack.sim.turret import TurretPlant, TurretSpec
from dronetrack.types import Frame, TurretCommand, TurretState

__all__ = ["FrameTruth", "SimWorld"]


@dataclass(frozen=True, slots=True)
class FrameTruth:
    """What really happened during a frame."""

    t: float  # frame end [s]
    target_position: FloatArray  # (3,) at the frame end [m]
    target_velocity: FloatArray  # (3,) [m/s]
    target_attitude: FloatArray  # (3, 3) world_R_body
    hit_target: NDArray[np.bool_]  # (N,) per point of the frame
    n_pulses: int
    turret: TurretState

    @property
    def n_target_points(self) -> int:
        return int(np.count_nonzero(self.hit_target))


class SimWorld:
    """Scene + target + sensor on a turret, stepped one integration period at a time."""

    def __init__(
        self,
        sensor: SensorModel,
        scene: Scene,
        drone: DroneModel,
        trajectory: Trajectory,
        turret: TurretSpec,
        mount: MountGeometry,
        extinction: float,
        rng: np.random.Generator,
        integration_time: float = 0.1,
        pan: float = 0.0,
        tilt: float = 0.0,
        t0: float = 0.0,
    ) -> None:
        self.lidar = LidarSimulator(sensor, scene, drone, trajectory, extinction)
        self.trajectory = trajectory
        self.mount = mount
        self.integration_time = integration_time
        self.plant = TurretPlant(turret, mount, pan=pan, tilt=tilt, t0=t0)
        # Frame k spans [t0 + k T, t0 + (k + 1) T): times from the index, not a running sum.
        self._t0 = t0
        self._frames = 0
        self.rng = rng

    @property
    def time(self) -> float:
        return self.plant.time

    def place_turret(self, pan: float, tilt: float) -> None:
        """Set the turret's angles [rad] directly, at rest (to start a run already aimed)."""
        self.plant = TurretPlant(
            self.plant.spec, self.mount, pan=pan, tilt=tilt, t0=self.plant.time
        )

    def command(self, cmd: TurretCommand) -> None:
        """Send a command to the turret (it acts after the turret's latency)."""
        self.plant.command(cmd)

    def turret_state(self) -> TurretState:
        return self.plant.state()

    def target_position(self, t: float) -> FloatArray:
        """Ground-truth target position at time t, (3,)."""
        p: FloatArray = self.trajectory.position(t)[0]
        return p

    def step(self) -> tuple[Frame, FrameTruth]:
        """Integrate one frame: move the turret, fire the pattern, return frame and truth."""
        t0 = self._t0 + self._frames * self.integration_time
        t1 = self._t0 + (self._frames + 1) * self.integration_time
        self._frames += 1
        times, pan, tilt = self.plant.advance(t1)
        poses = sensor_poses(pan, tilt, self.mount)
        scan = self.lidar.scan(t0, t1, times, poses, self.rng)
        frame = Frame(
            stamp=t0,
            duration=self.integration_time,
            points=scan.points,
            t=scan.t,
            line=scan.line,
            intensity=scan.intensity,
            pose_t=times,
            poses=poses,
        )
        truth = FrameTruth(
            t=t1,
            target_position=self.trajectory.position(t1)[0],
            target_velocity=self.trajectory.velocity(t1)[0],
            target_attitude=self.lidar.target_attitude(t1),
            hit_target=scan.hit_target,
            n_pulses=scan.n_pulses,
            turret=self.plant.state(),
        )
        return frame, truth
