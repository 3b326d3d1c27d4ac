"""Echoes of moving objects (drones, birds, walkers, vehicles) over the pulses' footprints.

Pulses whose footprint can touch an object are split into K sub-rays spread over
the elliptical footprint (full divergence θ_h × θ_v; K grows with the footprint's
area, about one ray per 2 × 2 cm, from 4 to the sensor's ``beam_samples``), cast
against the object's shapes where it is at each pulse's firing time.  The echo's
beam-averaged reflectivity is Σ ρ_k cos θ_k / K over the sub-rays that hit it
before the scene does, its fill the share of sub-rays that do, and its range the
mean of their ranges.  How echoes of one pulse hide each other, and which one the
sensor reports, is ``sim/returns.py``'s business.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray, apply_interpolated_poses
from dronetrack.sim.patterns import Pulses
from dronetrack.sim.primitives import Primitives
from dronetrack.sim.raycast import cast_rays
from dronetrack.sim.returns import TargetEcho, beam_axes
from dronetrack.sim.sensors import SensorModel
from dronetrack.sim.targets import SimTarget

__all__ = [
    "SUBRAY_SPACING_M",
    "BodyGroup",
    "FrameRays",
    "drone_echo",
    "footprint_samples",
    "group_echoes",
    "subray_count",
]

SUBRAY_SPACING_M = 0.02  # footprint sampling: the thinnest target parts (arms, legs) are 1-4 cm


def footprint_samples(k: int) -> FloatArray:
    """K points spread evenly over the unit disc (a sunflower / Vogel spiral), (K, 2)."""
    i = np.arange(k) + 0.5
    r = np.sqrt(i / k)
    phi = i * np.pi * (3.0 - np.sqrt(5.0))  # golden angle
    return np.column_stack([r * np.cos(phi), r * np.sin(phi)])


def subray_count(sensor: SensorModel, range_m: float) -> int:
    """Sub-rays per pulse at this range: about one per (SUBRAY_SPACING_M)² of footprint.

    The elliptical footprint (π/4)(θ_h R)(θ_v R) is sampled finely enough to
    resolve the target's thinnest parts, between 4 and ``beam_samples`` rays.
    """
    s = sensor
    area = 0.25 * np.pi * (s.divergence_h * range_m) * (s.divergence_v * range_m)
    return int(np.clip(np.ceil(area / SUBRAY_SPACING_M**2), 4, s.beam_samples))


@dataclass(frozen=True, slots=True)
class FrameRays:
    """One frame's pulses in the world: the sensor poses, each pulse's origin and
    direction, where the rays start (within ``slack`` of ``o_mean``) and the range of
    the scene along each central ray."""

    sensor: SensorModel
    pulses: Pulses
    pose_t: FloatArray
    poses: FloatArray
    orig: FloatArray
    D: FloatArray
    o_mean: FloatArray
    slack: float
    scene_range: FloatArray

    @property
    def half_beam(self) -> float:
        return 0.5 * max(self.sensor.divergence_h, self.sensor.divergence_v)


class BodyGroup(Protocol):
    """Bodies cast together, the nearest one's echo standing for them on a pulse: a flock
    of birds (``sim/birds.py``), walkers and vehicles (``sim/movers.py``)."""

    @property
    def bodies(self) -> Sequence[Primitives]:
        """Each body's shapes, in its own frame."""
        ...

    @property
    def radius(self) -> FloatArray:
        """(B,) a sphere about each body's origin that holds it [m]."""
        ...

    @property
    def enter_s(self) -> FloatArray:
        """(B,) when each body enters the world [s] (−inf: there from the start)."""
        ...

    def __len__(self) -> int: ...

    def positions(self, t: float) -> FloatArray:
        """(B, 3) every body's origin at time t."""
        ...

    def path(self, k: int, times: FloatArray) -> FloatArray:
        """(N, 3) body k's origin at ``times``."""
        ...

    def attitude(self, k: int, t: float) -> FloatArray:
        """(3, 3) world_R_body of body k at time t."""
        ...


def _empty(owner: int) -> TargetEcho:
    idx = np.empty(0, dtype=np.int64)
    empty = np.empty(0)
    return TargetEcho(idx, empty, empty, empty, empty, np.full(0, owner, dtype=np.int64))


def drone_echo(rays: FrameRays, target: SimTarget, owner: int) -> TargetEcho:
    """The echoes of ``target`` on the frame's pulses fired while it is in the world,
    each marked as coming from object ``owner``."""
    pulses, D = rays.pulses, rays.D
    if len(pulses) == 0 or pulses.t[-1] < target.enter_s:
        return _empty(owner)
    trajectory, drone = target.trajectory, target.drone
    t0, t1 = float(pulses.t[0]), float(pulses.t[-1])
    tm = 0.5 * (t0 + t1)
    ends = trajectory.position(np.array([t0, tm, t1]))
    center = ends[1]
    # A sphere that holds the target over the whole frame, plus a margin for curvature.
    radius = drone.radius + np.max(np.linalg.norm(ends - center, axis=1)) * 1.2 + 0.05
    v = center - rays.o_mean
    dist = float(np.linalg.norm(v))
    half_beam = rays.half_beam
    if dist <= radius + rays.slack:
        idx = np.arange(len(D))
    else:
        cone = np.arcsin(min(1.0, (radius + rays.slack) / dist)) + half_beam
        idx = np.flatnonzero(D @ (v / dist) >= np.cos(min(cone, np.pi)))
    if np.isfinite(target.enter_s):
        idx = idx[pulses.t[idx] >= target.enter_s]
    if len(idx) == 0:
        return _empty(owner)
    # Rays in the target's body frame at each firing time: o_b = Rᵀ (o − p(t)), d_b = Rᵀ d.
    Rb = target.attitude(tm)
    o_b = (rays.orig[idx] - trajectory.position(pulses.t[idx])) @ Rb
    d_b = D[idx] @ Rb
    # Keep the pulses whose footprint can reach the target where it is at their own
    # firing time: the central ray passes within r + |o_b| θ/2 of the body origin,
    # |o_b × d_b| ≤ r + |o_b| θ/2, in front of the sensor (−o_b · d_b > 0).
    miss = np.linalg.norm(np.cross(o_b, d_b), axis=1)
    near = (miss <= drone.radius + half_beam * np.linalg.norm(o_b, axis=1)) & (
        np.einsum("ij,ij->i", o_b, d_b) < 0
    )
    idx, o_b, d_b = idx[near], o_b[near], d_b[near]
    if len(idx) == 0:
        return _empty(owner)
    echo = _footprint_echo(rays, drone.body, idx, o_b, d_b, Rb, float(np.linalg.norm(v)))
    return TargetEcho(
        echo.index,
        echo.reflectivity,
        echo.fill,
        echo.range_m,
        echo.surface,
        np.full(len(echo.index), owner, dtype=np.int64),
    )


def _footprint_echo(
    rays: FrameRays,
    body: Primitives,
    idx: NDArray[np.int64],
    o_b: FloatArray,
    d_b: FloatArray,
    Rb: FloatArray,
    range_m: float,
) -> TargetEcho:
    """Echoes of the pulses ``idx`` from ``body``, whose frame the rays (o_b, d_b) are in
    (turned from the world by Rb), over the pulses' footprints at about ``range_m``;
    no owner yet (the caller's)."""
    sensor, pulses = rays.sensor, rays.pulses
    h_s, v_s = beam_axes(pulses.dirs[idx])
    t_idx = pulses.t[idx]
    axes_w, _ = apply_interpolated_poses(
        rays.pose_t, rays.poses, np.concatenate([t_idx, t_idx]), np.concatenate([h_s, v_s])
    )
    h_b, v_b = np.split(axes_w @ Rb, 2)
    # Sub-ray k: d + u_k (θ_h/2) h + v_k (θ_v/2) v
    samples = footprint_samples(subray_count(sensor, range_m))
    u = samples[:, 0] * 0.5 * sensor.divergence_h
    w = samples[:, 1] * 0.5 * sensor.divergence_v
    sub = d_b[:, None, :] + u[None, :, None] * h_b[:, None, :] + w[None, :, None] * v_b[:, None, :]
    sub /= np.linalg.norm(sub, axis=2, keepdims=True)
    k = len(samples)
    t_k, hit_k, cos_k = cast_rays(body, np.repeat(o_b, k, axis=0), sub.reshape(-1, 3))
    t_k = t_k.reshape(-1, k)
    hit_k = hit_k.reshape(-1, k)
    on = (hit_k >= 0) & (t_k < rays.scene_range[idx][:, None])
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
        owner=np.empty(0, dtype=np.int64),
    )


def group_echoes(rays: FrameRays, group: BodyGroup, first_owner: int) -> TargetEcho:
    """A group's echoes, as a drone's (``drone_echo``): the nearest echo of the group's
    bodies on each pulse that meets one, marked as coming from object
    ``first_owner + b`` for body b; a body meets the pulses fired from its entry on."""
    sensor, pulses, D = rays.sensor, rays.pulses, rays.D
    n = len(D)
    t0, t1 = float(pulses.t[0]), float(pulses.t[-1])
    tm = 0.5 * (t0 + t1)
    ends = np.stack([group.positions(t0), group.positions(tm), group.positions(t1)], axis=1)
    half_beam = rays.half_beam
    best = np.full(n, np.inf)
    reflectivity, fill, surface = np.zeros(n), np.zeros(n), np.zeros(n)
    owner = np.full(n, -1, dtype=np.int64)
    # Every ray of the frame lies within `spread` of `axis`, about the rays' mean
    # direction (a spinning head's rays all around: no axis), so a body outside that
    # cone is skipped at once.
    axis = np.ones(len(D[::16])) @ D[::16]
    spread = np.pi
    if np.linalg.norm(axis) > 1e-3:
        axis = axis / np.linalg.norm(axis)
        spread = float(np.arccos(np.clip((D @ axis).min(), -1.0, 1.0)))
    for b in range(len(group)):
        if t1 < group.enter_s[b]:
            continue
        center = ends[b, 1]
        # A sphere that holds the body over the whole frame (a bird's path is straight
        # between 50 ms steps, a walker's or a car's nearly so), plus a margin.
        radius = group.radius[b] + np.max(np.linalg.norm(ends[b] - center, axis=1)) * 1.2
        radius += 0.05
        v = center - rays.o_mean
        dist = float(np.linalg.norm(v))
        if dist - radius - rays.slack > sensor.max_range_m:
            continue
        if dist <= radius + rays.slack:
            idx = np.arange(n)
        else:
            cone = np.arcsin(min(1.0, (radius + rays.slack) / dist)) + half_beam
            off_axis = np.arccos(np.clip(np.dot(v / dist, axis), -1.0, 1.0))
            if spread < np.pi and off_axis > spread + cone:
                continue
            idx = np.flatnonzero(D @ (v / dist) >= np.cos(min(cone, np.pi)))
        if np.isfinite(group.enter_s[b]):
            idx = idx[pulses.t[idx] >= group.enter_s[b]]
        if len(idx) == 0:
            continue
        # Rays in the body's frame at each firing time: o_b = Rᵀ (o − p(t)), d_b = Rᵀ d.
        Rb = group.attitude(b, tm)
        o_b = (rays.orig[idx] - group.path(b, pulses.t[idx])) @ Rb
        d_b = D[idx] @ Rb
        miss = np.linalg.norm(np.cross(o_b, d_b), axis=1)
        near = (miss <= group.radius[b] + half_beam * np.linalg.norm(o_b, axis=1)) & (
            np.einsum("ij,ij->i", o_b, d_b) < 0
        )
        if not near.any():
            continue
        echo = _footprint_echo(rays, group.bodies[b], idx[near], o_b[near], d_b[near], Rb, dist)
        closer = echo.range_m < best[echo.index]
        at = echo.index[closer]
        best[at] = echo.range_m[closer]
        reflectivity[at] = echo.reflectivity[closer]
        fill[at] = echo.fill[closer]
        surface[at] = echo.surface[closer]
        owner[at] = first_owner + b
    hit = np.flatnonzero(np.isfinite(best))
    return TargetEcho(hit, reflectivity[hit], fill[hit], best[hit], surface[hit], owner[hit])
