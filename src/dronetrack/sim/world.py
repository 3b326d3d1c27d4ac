"""The closed-loop simulator: a source of LiDAR frames plus an actuator (the turret).

Ground truth travels on a separate channel (``FrameTruth``), so whatever
consumes the frames sees only what a real sensor would give it.

The turret stands on the ground, or rides on a moving observer (a drone, seed
002).  With an observer the mount's ``base`` is the turret's offset in the
observer's body frame, and at every pose sample

    world_T_sensor(t) = world_T_body(t) · body_T_sensor(pan(t), tilt(t))
    world_T_body(t)   = [Rz(ψ(t)) | p(t)]

with p(t) the observer's trajectory and ψ(t) its yaw (roll and pitch are taken
as zero: a multirotor tilts a few degrees when it accelerates, which this leaves
out).  The sensor fires from this true pose; the frame carries the pose the
observer's odometry reports, world_T_body with p(t) + d(t), where d is a random
walk of σ m/√s per axis (zero by default).  Without an observer world_T_body is
the identity and the frames are exactly those of a turret on the ground.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.signal import lfilter

from dronetrack.config.rig import TurretSpec
from dronetrack.errors import InputError
from dronetrack.geometry.mount import MountGeometry, sensor_poses
from dronetrack.geometry.transforms import FloatArray, make_pose, rot_z
from dronetrack.sim.clutter import CLUTTER_NONE, Clutter, ClutterSpec
from dronetrack.sim.drones import DroneModel
from dronetrack.sim.lidar import LidarSimulator
from dronetrack.sim.movers import Movers
from dronetrack.sim.scene import Scene
from dronetrack.sim.sensors import SensorModel
from dronetrack.sim.targets import SimTarget
from dronetrack.sim.trajectories import Trajectory
from dronetrack.sim.turret import TurretPlant
from dronetrack.types import Frame, ObjectTruth, TurretCommand, TurretState

__all__ = ["FrameTruth", "Observer", "OdometryDrift", "SimWorld"]

HEADING_TAU_S = 1.0  # time constant of the yaw lag behind the velocity heading [s]
HEADING_MIN_SPEED = 0.5  # below this horizontal speed the yaw holds [m/s]
YAW_TABLE_DT = 0.02  # yaw table step [s]


@dataclass(frozen=True, slots=True)
class Observer:
    """The platform the turret rides on: a trajectory and a body yaw table.

    The body frame is x forward, y left, z up, at the trajectory's point, turned
    by the yaw ψ about world z; roll and pitch are zero.
    """

    trajectory: Trajectory
    yaw_t: FloatArray  # (M,) times of the yaw samples [s], increasing
    yaw: FloatArray  # (M,) yaw ψ at those times [rad]; linear between, held outside

    @classmethod
    def fixed(cls, trajectory: Trajectory, yaw: float = 0.0) -> Observer:
        """An observer whose body keeps the yaw ``yaw`` [rad]."""
        return cls(trajectory, np.array([trajectory.start]), np.array([float(yaw)]))

    @classmethod
    def heading(
        cls,
        trajectory: Trajectory,
        yaw0: float = 0.0,
        tau: float = HEADING_TAU_S,
        min_speed: float = HEADING_MIN_SPEED,
        dt: float = YAW_TABLE_DT,
    ) -> Observer:
        """An observer whose body turns to its velocity heading with a first-order lag.

        h_k = atan2(v_y, v_x) where the horizontal speed is at least ``min_speed``,
        else the last such heading (``yaw0`` before the first), unwrapped; then
        ψ_k = ψ_{k−1} + α (h_k − ψ_{k−1}),  α = 1 − exp(−dt / τ),  ψ_{−1} = yaw0.
        The table runs 5 τ past the trajectory's end, where it comes to rest.
        """
        if tau <= 0 or dt <= 0:
            raise InputError(f"heading lag and table step must be positive, got {tau}, {dt}")
        t0 = trajectory.start
        n = max(2, math.ceil((trajectory.end + 5.0 * tau - t0) / dt) + 1)
        t = t0 + dt * np.arange(n, dtype=np.float64)
        v = trajectory.velocity(t)
        moving = np.hypot(v[:, 0], v[:, 1]) >= min_speed
        last = np.maximum.accumulate(np.where(moving, np.arange(n), -1))
        raw = np.where(last >= 0, np.arctan2(v[:, 1], v[:, 0])[np.maximum(last, 0)], yaw0)
        raw = np.unwrap(np.concatenate([[yaw0], raw]))[1:]
        alpha = 1.0 - math.exp(-dt / tau)
        psi, _ = lfilter([alpha], [1.0, alpha - 1.0], raw, zi=[(1.0 - alpha) * yaw0])
        return cls(trajectory, t, np.asarray(psi, dtype=np.float64))

    def yaw_at(self, t: ArrayLike) -> FloatArray:
        """Body yaw ψ [rad] at times t, (N,)."""
        tq = np.atleast_1d(np.asarray(t, dtype=np.float64))
        psi: FloatArray = np.interp(tq, self.yaw_t, self.yaw)
        return psi

    def body_poses(self, t: ArrayLike) -> FloatArray:
        """world_T_body = [Rz(ψ(t)) | p(t)] at times t, (N, 4, 4)."""
        return make_pose(rot_z(self.yaw_at(t)), self.trajectory.position(t))


class OdometryDrift:
    """The error of the observer's reported position: a random walk, d(t) = σ W(t) per axis.

    Sampled at increasing times, each call continuing where the last ended:
    d(t_k) = d(t_{k−1}) + σ √(t_k − t_{k−1}) n_k with n_k standard normal (3,).
    ``sigma`` is in m/√s, so after t seconds each axis is off by σ √t (1σ).
    """

    def __init__(self, sigma: float, rng: np.random.Generator, t0: float = 0.0) -> None:
        if not sigma >= 0:
            raise InputError(f"odometry drift sigma must be ≥ 0, got {sigma}")
        self.sigma = float(sigma)
        self.rng = rng
        self._t = float(t0)
        self._d = np.zeros(3)

    @property
    def current(self) -> FloatArray:
        """The drift at the last time sampled, (3,)."""
        return self._d.copy()

    def sample(self, times: ArrayLike) -> FloatArray:
        """The drift at ``times`` (K,), none before the last time sampled; (K, 3)."""
        t = np.atleast_1d(np.asarray(times, dtype=np.float64))
        if self.sigma == 0.0 or len(t) == 0:
            return np.zeros((len(t), 3))
        dt = np.diff(t, prepend=self._t)
        if np.any(dt < -1e-12):
            raise InputError("odometry drift is sampled forwards in time only")
        steps = (
            self.rng.standard_normal((len(t), 3))
            * (self.sigma * np.sqrt(np.maximum(dt, 0.0)))[:, None]
        )
        d: FloatArray = self._d + np.cumsum(steps, axis=0)
        self._t, self._d = float(t[-1]), d[-1].copy()
        return d


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
    # With a moving observer: its body position at the frame end [m], (3,), the true one
    # and the one its odometry reports (the frame's poses use the reported one).
    observer_position: FloatArray | None = None
    observer_reported: FloatArray | None = None
    # With clutter ([scene.clutter]): what each point is (sim.clutter's CLUTTER_* codes:
    # none, a swaying crown or hedge, a bird, a random false alarm), (N,), and every
    # bird's position at the frame end [m], (B, 3).
    clutter: NDArray[np.int8] | None = None
    bird_positions: FloatArray | None = None
    # Every drone (the target first), bird, walker and vehicle, and the object each
    # point came from.
    objects: ObjectTruth | None = None

    @property
    def n_target_points(self) -> int:
        return int(np.count_nonzero(self.hit_target))

    @property
    def hit_clutter(self) -> NDArray[np.bool_]:
        """(N,) per point: the return came from clutter (all False without clutter)."""
        if self.clutter is None:
            return np.zeros(len(self.hit_target), dtype=bool)
        hit: NDArray[np.bool_] = self.clutter != CLUTTER_NONE
        return hit

    def target_returns(self, frame: Frame, world: FloatArray) -> int:
        """The frame's returns the ray caster marked as hitting the target (``types.Truth``)."""
        return self.n_target_points


class SimWorld:
    """Scene + targets + sensor on a turret, stepped one integration period at a time.

    The target (``drone`` on ``trajectory``) is there from the start; ``add_targets``
    adds other drones, each entering at its own time.

    With an ``observer`` the turret rides on it (``mount.base`` in its body frame)
    and ``odometry_sigma`` [m/√s] makes the reported poses drift from the true
    ones; the drift draws from a child of ``rng``, so the returns are the same
    with and without it.  ``clutter`` adds swaying crowns, false alarms and birds
    (``sim/clutter.py``), drawn from a child of ``rng`` spawned after the drift's, so
    a world without clutter draws exactly what it did before clutter existed.
    """

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
        observer: Observer | None = None,
        odometry_sigma: float = 0.0,
        clutter: ClutterSpec | None = None,
    ) -> None:
        self.trajectory = trajectory
        self.mount = mount
        self.integration_time = integration_time
        self.plant = TurretPlant(turret, mount, pan=pan, tilt=tilt, t0=t0)
        # Frame k spans [t0 + k T, t0 + (k + 1) T): times from the index, not a running sum.
        self._t0 = t0
        self._frames = 0
        self.rng = rng
        self.observer = observer
        self.odometry: OdometryDrift | None = None
        if observer is not None and odometry_sigma > 0:
            self.odometry = OdometryDrift(odometry_sigma, rng.spawn(1)[0], t0)
        self.clutter: Clutter | None = None
        if clutter is not None:
            self.clutter = Clutter(clutter, scene, rng.spawn(1)[0], t0, self._line_of_sight)
        self.lidar = LidarSimulator(sensor, scene, drone, trajectory, extinction, self.clutter)

    @property
    def targets(self) -> tuple[SimTarget, ...]:
        """Every drone of the world: the target, then the others in the order added."""
        return self.lidar.targets

    def add_targets(self, others: list[SimTarget], rng: np.random.Generator) -> None:
        """Add drones besides the target, before the first frame; their detections draw
        from ``rng`` (a stream of their own, so the world's draws stay as they are)."""
        if self._frames:
            raise InputError("drones are added to a world before its first frame")
        self.lidar = self.lidar.with_objects(others=(*self.targets[1:], *others), others_rng=rng)

    def add_movers(self, movers: Movers, rng: np.random.Generator) -> None:
        """Add walkers and vehicles, before the first frame (once); their detections draw
        from ``rng`` (a stream of their own, so the world's draws stay as they are)."""
        if self._frames or self.movers is not None:
            raise InputError("walkers and vehicles are added to a world once, before its frames")
        self.lidar = self.lidar.with_objects(movers=movers, movers_rng=rng)

    @property
    def movers(self) -> Movers | None:
        """The world's walkers and vehicles, if any."""
        return self.lidar.movers

    def object_truth(self, t: float, object_index: NDArray[np.int64]) -> ObjectTruth:
        """Every drone's, bird's, walker's and vehicle's state at time t, and
        ``object_index`` per point."""
        drones = self.targets
        present = np.array([d.present(t) for d in drones])
        positions = np.full((len(drones), 3), np.nan)
        velocities = np.full((len(drones), 3), np.nan)
        for k in np.flatnonzero(present):
            positions[k] = drones[k].trajectory.position(t)[0]
            velocities[k] = drones[k].trajectory.velocity(t)[0]
        kinds = ["drone"] * len(drones)
        flock = None if self.clutter is None else self.clutter.flock
        if flock is not None:
            b = len(flock)
            positions = np.concatenate([positions, flock.positions(t)])
            velocities = np.concatenate([velocities, flock.velocities(t)])
            present = np.concatenate([present, np.ones(b, dtype=bool)])
            kinds += ["bird"] * b
        movers = self.lidar.movers
        if movers is not None and len(movers):
            here = movers.present(t)
            nan = np.where(here[:, None], 0.0, np.nan)
            positions = np.concatenate([positions, movers.positions(t) + nan])
            velocities = np.concatenate([velocities, movers.velocities(t) + nan])
            present = np.concatenate([present, here])
            kinds += movers.kinds
        return ObjectTruth(
            ids=np.arange(len(kinds), dtype=np.int64),
            kinds=np.array(kinds),
            positions=positions,
            velocities=velocities,
            present=present,
            object_index=object_index,
        )

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

    def observer_position(self, t: float) -> FloatArray:
        """Ground-truth position of the observer's body at time t, (3,); the origin without one."""
        if self.observer is None:
            return np.zeros(3)
        p: FloatArray = self.observer.trajectory.position(t)[0]
        return p

    def _line_of_sight(self, t: float) -> tuple[FloatArray, FloatArray]:
        """The turret base's and the target's true positions at time t, (3,) each."""
        base = np.append(self.mount.base_vec, 1.0)
        if self.observer is not None:
            base = self.observer.body_poses(t)[0] @ base
        return base[:3].copy(), self.target_position(t)

    def _poses(
        self, times: FloatArray, pan: FloatArray, tilt: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray | None, FloatArray | None]:
        """True and reported world_T_sensor at the pose times, and the observer's true and
        reported body positions at the last of them."""
        poses = sensor_poses(pan, tilt, self.mount)
        if self.observer is None:
            return poses, poses, None, None
        body = self.observer.body_poses(times)
        true = body @ poses
        position = body[-1, :3, 3].copy()
        if self.odometry is None:
            return true, true, position, position
        body[:, :3, 3] += self.odometry.sample(times)
        return true, body @ poses, position, body[-1, :3, 3].copy()

    def warm_up(self) -> None:
        """Run every numba kernel of a frame once, so none compiles inside a timed loop.

        A throwaway turret and LiDAR, on this world's scene, sensor, drone and flight,
        turn towards the target's starting point for a few milliseconds and scan; the
        random stream is a fresh one.  The world itself (its turret, time and ``rng``)
        is untouched, so a run is the same with or without a warm-up.
        """
        t0 = self.time
        plant = TurretPlant(self.plant.spec, self.mount, pan=0.0, tilt=0.0, t0=t0)
        aim = self.trajectory.position(t0)[0] - np.asarray(self.mount.base, dtype=np.float64)
        plant.command(TurretCommand(t0, math.atan2(aim[1], aim[0]), 0.0))
        period = min(self.integration_time, 0.005)
        times, pan, tilt = plant.advance(t0 + period)
        poses = sensor_poses(pan, tilt, self.mount)
        if self.observer is not None:  # without odometry drift, which has a stream of its own
            poses = self.observer.body_poses(times) @ poses
        lidar = LidarSimulator(
            self.lidar.sensor,
            self.lidar.scene,
            self.lidar.drone,
            self.trajectory,
            self.lidar.extinction,
        )
        lidar.scan(t0, t0 + period, times, poses, np.random.default_rng(0))

    def step(self) -> tuple[Frame, FrameTruth]:
        """Integrate one frame: move the turret, fire the pattern, return frame and truth."""
        t0 = self._t0 + self._frames * self.integration_time
        t1 = self._t0 + (self._frames + 1) * self.integration_time
        self._frames += 1
        times, pan, tilt = self.plant.advance(t1)
        poses, reported, observer, observer_reported = self._poses(times, pan, tilt)
        scan = self.lidar.scan(t0, t1, times, poses, self.rng)
        frame = Frame(
            stamp=t0,
            duration=self.integration_time,
            points=scan.points,
            t=scan.t,
            line=scan.line,
            intensity=scan.intensity,
            pose_t=times,
            poses=reported,
        )
        assert scan.object_index is not None
        bird_positions = None if self.clutter is None else self.clutter.bird_positions(t1)
        objects = self.object_truth(t1, scan.object_index)  # the target is object 0
        truth = FrameTruth(
            t=t1,
            target_position=objects.positions[0].copy(),
            target_velocity=objects.velocities[0].copy(),
            target_attitude=self.lidar.target_attitude(t1),
            hit_target=scan.hit_target,
            n_pulses=scan.n_pulses,
            turret=self.plant.state(),
            observer_position=observer,
            observer_reported=observer_reported,
            clutter=scan.clutter,
            bird_positions=bird_positions,
            objects=objects,
        )
        return frame, truth
