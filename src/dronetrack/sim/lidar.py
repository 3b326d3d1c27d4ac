"""One LiDAR integration period: fire the pattern, cast the rays, decide the returns.

Per pulse, in order:

1. the pulse's direction and origin in the world, from the sensor pose at its
   firing time (the turret moves during a frame);
2. the static scene along the central ray (a beam-filling echo, F = 1);
3. the drones: pulses whose footprint can touch one are split into K sub-rays
   spread over the elliptical footprint (full divergence θ_h × θ_v; K grows
   with the footprint's area, about one ray per 2 × 2 cm, from 4 to 32), cast
   against the drone's shapes at its position at the firing time
   (``sim/echoes.py``).  The echo's beam-averaged reflectivity is Σ ρ_k cos θ_k / K
   over the sub-rays that hit it before the scene does, and its range the mean of
   their ranges.  A drone that has not entered the world yet meets no pulse;
4. first return (``sim/returns.py``): the echoes of a pulse are tried nearest
   first, each dimmed by the share of the beam nearer objects fill and detected
   with probability P_d (``physics.detection_probability``); the first detected
   one is the return, else the scene behind, which keeps the unfilled fraction of
   the beam;
5. noise: range σ_R and angular σ per axis; false alarms at a rate per pulse.

With clutter (``sim/clutter.py``) the scene is cast as the wind has moved its
crowns at the frame's middle time, birds are cast like the drones (each bird where
it is at the pulse's firing time; of several birds on one pulse the nearest stands
for them) and take their place among the echoes by range, and the clutter's random
false alarms are added.  Walkers and vehicles (``sim/movers.py``) are cast as the
birds are.

Random draws: the world's stream gives three uniforms per pulse (the target's
detection, the scene's, a false alarm) and the noise of every return, whatever is
hit; the birds' detections draw from the clutter's stream, the other drones' and
the walkers' and vehicles' each from a stream of their own, so a world without
them draws exactly what it did before they existed.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray, apply_interpolated_poses
from dronetrack.sim.clutter import CLUTTER_BIRD, CLUTTER_NONE, CLUTTER_SWAY, Clutter
from dronetrack.sim.cubemap import CubeMapIndex, build_cube_map
from dronetrack.sim.drones import DroneModel
from dronetrack.sim.echoes import FrameRays, drone_echo, group_echoes
from dronetrack.sim.movers import Movers
from dronetrack.sim.physics import detection_probability, signal_ratio
from dronetrack.sim.primitives import Primitives
from dronetrack.sim.raycast import cast_rays
from dronetrack.sim.returns import (
    FROM_BIRD,
    FROM_DRONE,
    FROM_MOVER,
    FROM_SCENE,
    FROM_TARGET,
    Scan,
    TargetEcho,
    first_returns,
    noisy_points,
    pulse_echoes,
    with_false_alarms,
)
from dronetrack.sim.scene import Scene
from dronetrack.sim.sensors import SensorModel
from dronetrack.sim.targets import SimTarget
from dronetrack.sim.trajectories import Trajectory

__all__ = ["LidarSimulator", "Scan"]

LIVOX_DIFFUSE_MAX = 150.0  # Livox reflectivity byte for 100 % diffuse
INDEX_SLACK_M = 0.5  # how far ray origins may wander before the scene is indexed again


class LidarSimulator:
    """Casts a sensor's pulses into a scene with moving targets: the target (``drone``
    on ``trajectory``, there from the start) and ``others``, each from its entry on,
    and ``movers`` (walkers and vehicles).  The others' detections draw from
    ``others_rng``, the movers' from ``movers_rng`` (each needed when there are any)."""

    def __init__(
        self,
        sensor: SensorModel,
        scene: Scene,
        drone: DroneModel,
        trajectory: Trajectory,
        extinction: float,
        clutter: Clutter | None = None,
        others: Sequence[SimTarget] = (),
        others_rng: np.random.Generator | None = None,
        movers: Movers | None = None,
        movers_rng: np.random.Generator | None = None,
    ) -> None:
        self.sensor = sensor
        self.scene = scene
        self.drone = drone
        self.trajectory = trajectory
        self.extinction = extinction
        self.clutter = clutter
        self.targets = (SimTarget(drone, trajectory), *others)
        if others and others_rng is None:
            raise ValueError("other drones need a random stream of their own")
        self._others_rng = others_rng
        if movers is not None and len(movers) and movers_rng is None:
            raise ValueError("walkers and vehicles need a random stream of their own")
        self.movers = movers
        self._movers_rng = movers_rng
        self._scene_rho = np.append(scene.prims.reflectivity, 0.0)  # index -1 → no echo
        self._index: CubeMapIndex | None = None
        # With swaying crowns the index allows for how far the wind moves each primitive.
        self._margin = None if clutter is None else clutter.sway_margin()
        self._sways = None if clutter is None else clutter.sway_mask(len(scene.prims))

    def with_objects(
        self,
        *,
        others: Sequence[SimTarget] | None = None,
        others_rng: np.random.Generator | None = None,
        movers: Movers | None = None,
        movers_rng: np.random.Generator | None = None,
    ) -> LidarSimulator:
        """This simulator with other drones (``others``, the target's company) or walkers
        and vehicles instead of its own; what is not given stays as it is."""
        if others is None:
            others, others_rng = self.targets[1:], self._others_rng
        if movers is None:
            movers, movers_rng = self.movers, self._movers_rng
        return LidarSimulator(
            self.sensor,
            self.scene,
            self.drone,
            self.trajectory,
            self.extinction,
            self.clutter,
            others,
            others_rng,
            movers,
            movers_rng,
        )

    def _signal(self, reflectivity: FloatArray, range_m: FloatArray) -> FloatArray:
        s = self.sensor
        return signal_ratio(
            reflectivity, range_m, s.rated_range_m, s.rated_reflectivity, s.gamma, self.extinction
        )

    def target_attitude(self, t: float) -> FloatArray:
        """world_R_body of the target at time t."""
        return self.targets[0].attitude(t)

    def _cast_scene(
        self, prims: Primitives, orig: FloatArray, D: FloatArray, o_mean: FloatArray, slack: float
    ) -> tuple[FloatArray, NDArray[np.int64], FloatArray]:
        """Central rays against the scene, through a cube-map index of it.

        The index holds while the rays start within its slack of its origin (a
        turret moves the sensor by centimetres); a sensor that travels further
        gets a new index.  ``prims`` are the scene's, or as the wind has moved them
        (by at most ``self._margin`` each, which the index allows for).
        """
        index = self._index
        if index is None or not index.covers(o_mean, slack):
            index = build_cube_map(
                self.scene.prims,
                o_mean,
                max(2.0 * slack, INDEX_SLACK_M),
                self.sensor.max_range_m,
                margin=self._margin,
            )
            self._index = index
        return cast_rays(prims, orig, D, self.sensor.max_range_m, index)

    def _empty_scan(self) -> Scan:
        return Scan(
            np.empty((0, 3)),
            np.empty(0),
            np.empty(0, np.uint8),
            np.empty(0, np.float32),
            np.empty(0, bool),
            0,
            None if self.clutter is None else np.empty(0, np.int8),
            np.empty(0, np.int64),
        )

    def _echoes(
        self, rays: FrameRays
    ) -> tuple[list[TargetEcho], list[int], list[FloatArray | None]]:
        """The frame's object echoes by channel: the target, the birds (the nearest bird
        of each pulse), the other drones, the walkers and vehicles (the nearest of them);
        the source code of each channel, and the uniform draws of those not on the
        world's stream (None: the target's, drawn later with the pulse's own)."""
        channels = [drone_echo(rays, self.targets[0], 0)]
        sources = [FROM_TARGET]
        draws: list[FloatArray | None] = [None]
        clutter = self.clutter
        n_birds = 0
        if clutter is not None and clutter.flock is not None:
            n_birds = len(clutter.flock)
            birds = group_echoes(rays, clutter.flock, len(self.targets))
            channels.append(birds)
            sources.append(FROM_BIRD)
            draws.append(clutter.rng.random(len(birds.index)))
        for k, target in enumerate(self.targets[1:], start=1):
            assert self._others_rng is not None
            echo = drone_echo(rays, target, k)
            channels.append(echo)
            sources.append(FROM_DRONE)
            draws.append(self._others_rng.random(len(echo.index)))
        if self.movers is not None and len(self.movers):
            assert self._movers_rng is not None
            echo = group_echoes(rays, self.movers, len(self.targets) + n_birds)
            channels.append(echo)
            sources.append(FROM_MOVER)
            draws.append(self._movers_rng.random(len(echo.index)))
        return channels, sources, draws

    def scan(
        self,
        t_start: float,
        t_end: float,
        pose_t: FloatArray,
        poses: FloatArray,
        rng: np.random.Generator,
    ) -> Scan:
        """Simulate the returns of pulses fired in [t_start, t_end) with the given sensor poses."""
        sensor = self.sensor
        pulses = sensor.pattern.pulses(t_start, t_end)
        n = len(pulses)
        if n == 0:
            return self._empty_scan()
        D, orig = apply_interpolated_poses(pose_t, poses, pulses.t, pulses.dirs, pulses.origins)
        # Every ray starts within `slack` of `o_mean`: the sensor origin's path during
        # the frame, plus the beam origins' offsets from it.
        path = poses[:, :3, 3]
        o_mean = path.mean(axis=0)
        slack = float(np.max(np.linalg.norm(path - o_mean, axis=1))) + pulses.max_origin_offset
        clutter = self.clutter
        prims = self.scene.prims
        if clutter is not None:
            prims = clutter.scene_at(prims, 0.5 * (t_start + t_end))
        t_s, hit_s, cos_s = self._cast_scene(prims, orig, D, o_mean, slack)
        rays = FrameRays(sensor, pulses, pose_t, poses, orig, D, o_mean, slack, t_s)
        channels, sources, draws = self._echoes(rays)
        # The scene keeps the share of the beam no object fills, 1 − Σ F.
        fill = np.ones(n)
        for c in channels:
            fill[c.index] -= c.fill
        fill = np.maximum(fill, 0.0)
        echoes = pulse_echoes(channels)
        # Each object's echo is dimmed by the nearer ones on its pulse: ρ' = ρ Π (1 − F).
        pd = [
            detection_probability(
                self._signal(c.reflectivity * transmitted, c.range_m), sensor.pd_width_db
            )
            for c, transmitted in zip(
                channels, echoes.per_channel(echoes.transmission), strict=True
            )
        ]
        scene_hit = np.flatnonzero(hit_s >= 0)
        pd_scene = np.zeros(n)
        pd_scene[scene_hit] = detection_probability(
            self._signal(
                self._scene_rho[hit_s[scene_hit]] * cos_s[scene_hit] * fill[scene_hit],
                t_s[scene_hit],
            ),
            sensor.pd_width_db,
        )

        # The same uniform draws every frame whatever is hit, so a run depends on its seed only.
        u = rng.random((n, 3))
        uniforms = [u[c.index, 0] if d is None else d for c, d in zip(channels, draws, strict=True)]
        keep, r, rho, source, owner = first_returns(
            u,
            echoes.pulse,
            echoes.range_m,
            echoes.sort([c.surface for c in channels]),
            echoes.sort(pd),
            echoes.sort(uniforms),
            echoes.sort(
                [np.full(len(c.index), s, np.int8) for c, s in zip(channels, sources, strict=True)]
            ),
            echoes.sort([c.owner for c in channels]),
            pd_scene,
            t_s,
            self._scene_rho[hit_s],
            sensor.min_range_m,
            sensor.max_range_m,
            sensor.false_alarm_rate,
        )

        noise = rng.standard_normal((len(keep), 3))
        points = noisy_points(
            pulses.dirs[keep],
            pulses.origins[keep],
            r,
            noise,
            sensor.angular_sigma,
            sensor.range_sigma_m,
        )
        scan = Scan(
            points=points,
            t=pulses.t[keep],
            line=pulses.line[keep],
            intensity=np.clip(LIVOX_DIFFUSE_MAX * rho, 0.0, LIVOX_DIFFUSE_MAX).astype(np.float32),
            hit_target=source == FROM_TARGET,
            n_pulses=n,
            object_index=owner,
        )
        if clutter is None:
            return scan
        assert self._sways is not None
        kind = np.full(len(keep), CLUTTER_NONE, dtype=np.int8)
        kind[(source == FROM_SCENE) & self._sways[hit_s[keep]]] = CLUTTER_SWAY
        kind[source == FROM_BIRD] = CLUTTER_BIRD
        fa, fa_range = clutter.false_alarms(
            pulses, t_end - t_start, sensor.min_range_m, sensor.max_range_m
        )
        return with_false_alarms(replace(scan, clutter=kind), keep, pulses, fa, fa_range)
