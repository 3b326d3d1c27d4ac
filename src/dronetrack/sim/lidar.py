"""One LiDAR integration period: fire the pattern, cast the rays, decide the returns.

Per pulse, in order:

1. the pulse's direction and origin in the world, from the sensor pose at its
   firing time (the turret moves during a frame);
2. the static scene along the central ray (a beam-filling echo, F = 1);
3. the target: pulses whose footprint can touch it are split into K sub-rays
   spread over the elliptical footprint (full divergence θ_h × θ_v; K grows
   with the footprint's area, about one ray per 2 × 2 cm, from 4 to 32), cast
   against the target's shapes at its position at the firing time.  The echo's
   beam-averaged reflectivity is Σ ρ_k cos θ_k / K over the sub-rays that hit it
   before the scene does, and its range the mean of their ranges; the scene
   behind keeps the unfilled fraction of the beam;
4. first return: the nearer echo is detected with probability P_d
   (``physics.detection_probability``), else the farther one is tried;
5. noise: range σ_R and angular σ per axis; false alarms at a rate per pulse.

With clutter (``sim/clutter.py``) the scene is cast as the wind has moved its
crowns at the frame's middle time, birds are cast like the target (sub-rays over
the footprint, each bird where it is at the pulse's firing time) and take their
place among the echoes by range, and the clutter's random false alarms are added.
Where a bird and the target share a pulse, the nearer one hides its fill fraction
of the farther one's footprint.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray, apply_interpolated_poses
from dronetrack.sim.birds import Flock
from dronetrack.sim.clutter import CLUTTER_BIRD, CLUTTER_NONE, CLUTTER_SWAY, Clutter
from dronetrack.sim.cubemap import CubeMapIndex, build_cube_map
from dronetrack.sim.drones import DroneModel, attitude_from_acceleration
from dronetrack.sim.patterns import Pulses
from dronetrack.sim.physics import detection_probability, signal_ratio
from dronetrack.sim.primitives import Primitives
from dronetrack.sim.raycast import cast_rays
from dronetrack.sim.returns import (
    FROM_BIRD,
    FROM_SCENE,
    FROM_TARGET,
    Scan,
    TargetEcho,
    beam_axes,
    first_returns,
    mutual_occlusion,
    noisy_points,
    with_false_alarms,
)
from dronetrack.sim.scene import Scene
from dronetrack.sim.sensors import SensorModel
from dronetrack.sim.trajectories import Trajectory

__all__ = ["LidarSimulator", "Scan", "footprint_samples"]

LIVOX_DIFFUSE_MAX = 150.0  # Livox reflectivity byte for 100 % diffuse
INDEX_SLACK_M = 0.5  # how far ray origins may wander before the scene is indexed again
SUBRAY_SPACING_M = 0.02  # footprint sampling: the thinnest target parts (arms, legs) are 1-4 cm

_NO_BIRDS = np.empty(0)


def footprint_samples(k: int) -> FloatArray:
    """K points spread evenly over the unit disc (a sunflower / Vogel spiral), (K, 2)."""
    i = np.arange(k) + 0.5
    r = np.sqrt(i / k)
    phi = i * np.pi * (3.0 - np.sqrt(5.0))  # golden angle
    return np.column_stack([r * np.cos(phi), r * np.sin(phi)])


class LidarSimulator:
    """Casts a sensor's pulses into a scene with one moving target."""

    def __init__(
        self,
        sensor: SensorModel,
        scene: Scene,
        drone: DroneModel,
        trajectory: Trajectory,
        extinction: float,
        clutter: Clutter | None = None,
    ) -> None:
        self.sensor = sensor
        self.scene = scene
        self.drone = drone
        self.trajectory = trajectory
        self.extinction = extinction
        self.clutter = clutter
        self._scene_rho = np.append(scene.prims.reflectivity, 0.0)  # index -1 → no echo
        self._index: CubeMapIndex | None = None
        # With swaying crowns the index allows for how far the wind moves each primitive.
        self._margin = None if clutter is None else clutter.sway_margin()
        self._sways = None if clutter is None else clutter.sway_mask(len(scene.prims))

    def _subray_count(self, range_m: float) -> int:
        """Sub-rays per pulse at this range: about one per (SUBRAY_SPACING_M)² of footprint.

        The elliptical footprint (π/4)(θ_h R)(θ_v R) is sampled finely enough to
        resolve the target's thinnest parts, between 4 and ``beam_samples`` rays.
        """
        s = self.sensor
        area = 0.25 * np.pi * (s.divergence_h * range_m) * (s.divergence_v * range_m)
        return int(np.clip(np.ceil(area / SUBRAY_SPACING_M**2), 4, s.beam_samples))

    def _signal(self, reflectivity: FloatArray, range_m: FloatArray) -> FloatArray:
        s = self.sensor
        return signal_ratio(
            reflectivity, range_m, s.rated_range_m, s.rated_reflectivity, s.gamma, self.extinction
        )

    def target_attitude(self, t: float) -> FloatArray:
        """world_R_body of the target at time t."""
        acc = self.trajectory.acceleration(t)[0]
        yaw = 0.0
        if self.drone.faces_sensor:
            p = self.trajectory.position(t)[0]
            yaw = float(np.arctan2(-p[1], -p[0]))
        return attitude_from_acceleration(acc, yaw)

    def _target_echo(
        self,
        pulses: Pulses,
        pose_t: FloatArray,
        poses: FloatArray,
        orig: FloatArray,
        D: FloatArray,
        o_mean: FloatArray,
        slack: float,
        scene_range: FloatArray,
    ) -> TargetEcho:
        sensor = self.sensor
        t0, t1 = float(pulses.t[0]), float(pulses.t[-1])
        tm = 0.5 * (t0 + t1)
        ends = self.trajectory.position(np.array([t0, tm, t1]))
        center = ends[1]
        # A sphere that holds the target over the whole frame, plus a margin for curvature.
        radius = self.drone.radius + np.max(np.linalg.norm(ends - center, axis=1)) * 1.2 + 0.05
        v = center - o_mean
        dist = float(np.linalg.norm(v))
        half_beam = 0.5 * max(sensor.divergence_h, sensor.divergence_v)
        if dist <= radius + slack:
            idx = np.arange(len(D))
        else:
            cone = np.arcsin(min(1.0, (radius + slack) / dist)) + half_beam
            idx = np.flatnonzero(D @ (v / dist) >= np.cos(min(cone, np.pi)))
        if len(idx) == 0:
            empty = np.empty(0)
            return TargetEcho(idx, empty, empty, empty, empty)
        # Rays in the target's body frame at each firing time: o_b = Rᵀ (o − p(t)), d_b = Rᵀ d.
        Rb = self.target_attitude(tm)
        o_b = (orig[idx] - self.trajectory.position(pulses.t[idx])) @ Rb
        d_b = D[idx] @ Rb
        # Keep the pulses whose footprint can reach the target where it is at their own
        # firing time: the central ray passes within r + |o_b| θ/2 of the body origin,
        # |o_b × d_b| ≤ r + |o_b| θ/2, in front of the sensor (−o_b · d_b > 0).
        miss = np.linalg.norm(np.cross(o_b, d_b), axis=1)
        near = (miss <= self.drone.radius + half_beam * np.linalg.norm(o_b, axis=1)) & (
            np.einsum("ij,ij->i", o_b, d_b) < 0
        )
        idx, o_b, d_b = idx[near], o_b[near], d_b[near]
        if len(idx) == 0:
            empty = np.empty(0)
            return TargetEcho(idx, empty, empty, empty, empty)
        return self._footprint_echo(
            self.drone.body,
            pulses,
            idx,
            o_b,
            d_b,
            Rb,
            pose_t,
            poses,
            float(np.linalg.norm(v)),
            scene_range,
        )

    def _footprint_echo(
        self,
        body: Primitives,
        pulses: Pulses,
        idx: NDArray[np.int64],
        o_b: FloatArray,
        d_b: FloatArray,
        Rb: FloatArray,
        pose_t: FloatArray,
        poses: FloatArray,
        range_m: float,
        scene_range: FloatArray,
    ) -> TargetEcho:
        """Echoes of the pulses ``idx`` from ``body``, whose frame the rays (o_b, d_b) are in
        (turned from the world by Rb), over the pulses' footprints at about ``range_m``."""
        sensor = self.sensor
        h_s, v_s = beam_axes(pulses.dirs[idx])
        t_idx = pulses.t[idx]
        axes_w, _ = apply_interpolated_poses(
            pose_t, poses, np.concatenate([t_idx, t_idx]), np.concatenate([h_s, v_s])
        )
        h_b, v_b = np.split(axes_w @ Rb, 2)
        # Sub-ray k: d + u_k (θ_h/2) h + v_k (θ_v/2) v
        samples = footprint_samples(self._subray_count(range_m))
        u = samples[:, 0] * 0.5 * sensor.divergence_h
        w = samples[:, 1] * 0.5 * sensor.divergence_v
        sub = (
            d_b[:, None, :]
            + u[None, :, None] * h_b[:, None, :]
            + w[None, :, None] * v_b[:, None, :]
        )
        sub /= np.linalg.norm(sub, axis=2, keepdims=True)
        k = len(samples)
        t_k, hit_k, cos_k = cast_rays(body, np.repeat(o_b, k, axis=0), sub.reshape(-1, 3))
        t_k = t_k.reshape(-1, k)
        hit_k = hit_k.reshape(-1, k)
        on = (hit_k >= 0) & (t_k < scene_range[idx][:, None])
        rho_k = np.where(on, body.reflectivity[np.maximum(hit_k, 0)], 0.0)
        count = on.sum(axis=1)
        per_hit = 1.0 / np.maximum(count, 1)
        mean_range = np.where(count > 0, np.where(on, t_k, 0.0).sum(axis=1) * per_hit, np.inf)
        return TargetEcho(
            index=idx,
            reflectivity=(rho_k * cos_k.reshape(-1, k)).sum(axis=1) / k,
            fill=count / k,
            range_m=mean_range,
            surface=rho_k.sum(axis=1) * per_hit,
        )

    def _bird_echoes(
        self,
        flock: Flock,
        pulses: Pulses,
        pose_t: FloatArray,
        poses: FloatArray,
        orig: FloatArray,
        D: FloatArray,
        o_mean: FloatArray,
        slack: float,
        scene_range: FloatArray,
    ) -> TargetEcho:
        """The birds' echoes, as the target's (``_target_echo``): the nearest bird echo of
        each pulse that meets a bird."""
        sensor = self.sensor
        n = len(D)
        t0, t1 = float(pulses.t[0]), float(pulses.t[-1])
        tm = 0.5 * (t0 + t1)
        ends = np.stack([flock.positions(t0), flock.positions(tm), flock.positions(t1)], axis=1)
        half_beam = 0.5 * max(sensor.divergence_h, sensor.divergence_v)
        best = np.full(n, np.inf)
        reflectivity, fill, surface = np.zeros(n), np.zeros(n), np.zeros(n)
        # Every ray of the frame lies within `spread` of `axis`, about the rays' mean
        # direction (a spinning head's rays all around: no axis), so a bird outside that
        # cone is skipped at once.
        axis = np.ones(len(D[::16])) @ D[::16]
        spread = np.pi
        if np.linalg.norm(axis) > 1e-3:
            axis = axis / np.linalg.norm(axis)
            spread = float(np.arccos(np.clip((D @ axis).min(), -1.0, 1.0)))
        for b in range(len(flock)):
            center = ends[b, 1]
            # A sphere that holds the bird over the whole frame (its path is straight
            # between 50 ms steps), plus a margin.
            radius = flock.radius[b] + np.max(np.linalg.norm(ends[b] - center, axis=1)) * 1.2
            radius += 0.05
            v = center - o_mean
            dist = float(np.linalg.norm(v))
            if dist - radius - slack > sensor.max_range_m:
                continue
            if dist <= radius + slack:
                idx = np.arange(n)
            else:
                cone = np.arcsin(min(1.0, (radius + slack) / dist)) + half_beam
                off_axis = np.arccos(np.clip(np.dot(v / dist, axis), -1.0, 1.0))
                if spread < np.pi and off_axis > spread + cone:
                    continue
                idx = np.flatnonzero(D @ (v / dist) >= np.cos(min(cone, np.pi)))
            if len(idx) == 0:
                continue
            # Rays in the bird's frame at each firing time: o_b = Rᵀ (o − p(t)), d_b = Rᵀ d.
            Rb = flock.attitude(b, tm)
            o_b = (orig[idx] - flock.path(b, pulses.t[idx])) @ Rb
            d_b = D[idx] @ Rb
            miss = np.linalg.norm(np.cross(o_b, d_b), axis=1)
            near = (miss <= flock.radius[b] + half_beam * np.linalg.norm(o_b, axis=1)) & (
                np.einsum("ij,ij->i", o_b, d_b) < 0
            )
            if not near.any():
                continue
            echo = self._footprint_echo(
                flock.bodies[b],
                pulses,
                idx[near],
                o_b[near],
                d_b[near],
                Rb,
                pose_t,
                poses,
                dist,
                scene_range,
            )
            closer = echo.range_m < best[echo.index]
            at = echo.index[closer]
            best[at] = echo.range_m[closer]
            reflectivity[at] = echo.reflectivity[closer]
            fill[at] = echo.fill[closer]
            surface[at] = echo.surface[closer]
        hit = np.flatnonzero(np.isfinite(best))
        return TargetEcho(hit, reflectivity[hit], fill[hit], best[hit], surface[hit])

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
            return Scan(
                np.empty((0, 3)),
                np.empty(0),
                np.empty(0, np.uint8),
                np.empty(0, np.float32),
                np.empty(0, bool),
                0,
                None if self.clutter is None else np.empty(0, np.int8),
            )
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
        echo = self._target_echo(pulses, pose_t, poses, orig, D, o_mean, slack, t_s)
        target_reflectivity = echo.reflectivity
        fill = np.ones(n)
        fill[echo.index] -= echo.fill
        u_bird = pd_bird = bird_range = bird_rho = _NO_BIRDS
        if clutter is not None and clutter.flock is not None:
            birds = self._bird_echoes(
                clutter.flock, pulses, pose_t, poses, orig, D, o_mean, slack, t_s
            )
            target_reflectivity, bird_reflectivity = mutual_occlusion(n, echo, birds)
            fill[birds.index] -= birds.fill
            fill = np.maximum(fill, 0.0)
            pd_bird, bird_range, bird_rho = np.zeros(n), np.full(n, np.inf), np.zeros(n)
            pd_bird[birds.index] = detection_probability(
                self._signal(bird_reflectivity, birds.range_m), sensor.pd_width_db
            )
            bird_range[birds.index] = birds.range_m
            bird_rho[birds.index] = birds.surface
            # u = 1 never detects; the birds' draws come from the clutter's stream.
            u_bird = np.ones(n)
            u_bird[birds.index] = clutter.rng.random(len(birds.index))
        pd_target = np.zeros(n)
        pd_target[echo.index] = detection_probability(
            self._signal(target_reflectivity, echo.range_m), sensor.pd_width_db
        )
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
        target_range = np.full(n, np.inf)
        target_range[echo.index] = echo.range_m
        target_rho = np.zeros(n)
        target_rho[echo.index] = echo.surface
        keep, r, rho, source = first_returns(
            u,
            pd_target,
            pd_scene,
            t_s,
            target_range,
            target_rho,
            self._scene_rho[hit_s],
            sensor.min_range_m,
            sensor.max_range_m,
            sensor.false_alarm_rate,
            u_bird,
            pd_bird,
            bird_range,
            bird_rho,
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
