"""From echoes to returns: which echo of a pulse the sensor reports (first return,
with the detection probability), the sensor's own false alarms, the noise on a
return, and a bird and the target hiding parts of each other's footprint.  The
pulses and echoes come from ``sim/lidar.py``; this module only decides and perturbs.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.clutter import CLUTTER_FALSE_ALARM
from dronetrack.sim.patterns import Pulses

__all__ = [
    "FROM_BIRD",
    "FROM_FALSE_ALARM",
    "FROM_SCENE",
    "FROM_TARGET",
    "Scan",
    "TargetEcho",
    "beam_axes",
    "first_returns",
    "mutual_occlusion",
    "noisy_points",
    "with_false_alarms",
]

# Where a return comes from (``first_returns``).
FROM_SCENE = 0
FROM_TARGET = 1
FROM_BIRD = 2
FROM_FALSE_ALARM = 3  # the sensor's own, per pulse


@dataclass(frozen=True, slots=True)
class Scan:
    """The returns of one integration period, with their ground truth."""

    points: FloatArray  # (M, 3) sensor frame [m]
    t: FloatArray  # (M,) [s]
    line: NDArray[np.uint8]  # (M,)
    intensity: NDArray[np.float32]  # (M,) Livox reflectivity encoding
    hit_target: NDArray[np.bool_]  # (M,) ground truth: the return came from the target
    n_pulses: int
    clutter: NDArray[np.int8] | None = None  # (M,) CLUTTER_* codes, with clutter only


@dataclass(frozen=True, slots=True)
class TargetEcho:
    """Target echoes of the candidate pulses."""

    index: NDArray[np.int64]  # (C,) pulse indices
    reflectivity: FloatArray  # (C,) Σ ρ cos θ / K
    fill: FloatArray  # (C,) fraction of sub-rays on the target
    range_m: FloatArray  # (C,) mean range of the sub-rays on the target (inf if none)
    surface: FloatArray  # (C,) mean reflectivity ρ of the parts hit (for the intensity)


@nb.njit(cache=True, fastmath=True)
def noisy_points(
    dirs: FloatArray,
    origins: FloatArray,
    ranges: FloatArray,
    noise: FloatArray,
    sigma_angle: float,
    sigma_range: float,
) -> FloatArray:
    """Returns o + (R + σ_R n₂) · unit(d + σ_θ (n₀ h + n₁ v)), with the beam axes h, v of d."""
    n = dirs.shape[0]
    out = np.empty((n, 3))
    for i in range(n):
        dx, dy, dz = dirs[i, 0], dirs[i, 1], dirs[i, 2]
        # h = unit(ẑ × d), v = d × h (see beam_axes)
        norm = np.sqrt(dx * dx + dy * dy)
        if norm > 1e-9:
            hx, hy = -dy / norm, dx / norm
        else:
            hx, hy = 0.0, 1.0
        vx, vy, vz = -dz * hy, dz * hx, dx * hy - dy * hx
        a = sigma_angle * noise[i, 0]
        b = sigma_angle * noise[i, 1]
        ex, ey, ez = dx + a * hx + b * vx, dy + a * hy + b * vy, dz + b * vz
        scale = (ranges[i] + sigma_range * noise[i, 2]) / np.sqrt(ex * ex + ey * ey + ez * ez)
        out[i, 0] = origins[i, 0] + scale * ex
        out[i, 1] = origins[i, 1] + scale * ey
        out[i, 2] = origins[i, 2] + scale * ez
    return out


def beam_axes(d: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Unit horizontal and vertical axes across beams d (N, 3) in the sensor frame.

    h = unit(ẑ × d) lies in the sensor's horizontal plane; v = d × h.
    """
    h = np.column_stack([-d[:, 1], d[:, 0], np.zeros(len(d))])
    norm = np.linalg.norm(h, axis=1)
    h = np.where(
        norm[:, None] > 1e-9, h / np.maximum(norm, 1e-12)[:, None], np.array([0.0, 1.0, 0.0])
    )
    return h, np.cross(d, h)


def mutual_occlusion(
    n: int, target: TargetEcho, birds: TargetEcho
) -> tuple[FloatArray, FloatArray]:
    """The target's and the birds' echo reflectivities where they share pulses: the nearer
    one hides its fill fraction F of the farther one's footprint, ρ' = ρ (1 − F)."""
    t_range, t_fill = np.full(n, np.inf), np.zeros(n)
    t_range[target.index], t_fill[target.index] = target.range_m, target.fill
    b_range, b_fill = np.full(n, np.inf), np.zeros(n)
    b_range[birds.index], b_fill[birds.index] = birds.range_m, birds.fill
    ti, bi = target.index, birds.index
    target_rho = target.reflectivity * np.where(b_range[ti] < t_range[ti], 1.0 - b_fill[ti], 1.0)
    bird_rho = birds.reflectivity * np.where(t_range[bi] < b_range[bi], 1.0 - t_fill[bi], 1.0)
    return target_rho, bird_rho


def with_false_alarms(
    scan: Scan,
    keep: NDArray[np.int64],
    pulses: Pulses,
    fa: NDArray[np.int64],
    fa_range: FloatArray,
) -> Scan:
    """The scan with the clutter's false alarms on pulses ``fa`` at ``fa_range`` added, each
    after its pulse's own return (reflectivity 0, no noise)."""
    if len(fa) == 0:
        return scan
    assert scan.clutter is not None
    # p = o + R d in the sensor frame.
    fa_points = pulses.origins[fa] + fa_range[:, None] * pulses.dirs[fa]
    order = np.argsort(np.concatenate([keep, fa]), kind="stable")
    m = len(fa)
    return replace(
        scan,
        points=np.concatenate([scan.points, fa_points])[order],
        t=np.concatenate([scan.t, pulses.t[fa]])[order],
        line=np.concatenate([scan.line, pulses.line[fa]])[order],
        intensity=np.concatenate([scan.intensity, np.zeros(m, np.float32)])[order],
        hit_target=np.concatenate([scan.hit_target, np.zeros(m, bool)])[order],
        clutter=np.concatenate([scan.clutter, np.full(m, CLUTTER_FALSE_ALARM, np.int8)])[order],
    )


@nb.njit(cache=True)
def first_returns(
    u: FloatArray,
    pd_target: FloatArray,
    pd_scene: FloatArray,
    scene_range: FloatArray,
    target_range: FloatArray,
    target_rho: FloatArray,
    scene_rho: FloatArray,
    r_min: float,
    r_max: float,
    p_fa: float,
    u_bird: FloatArray,
    pd_bird: FloatArray,
    bird_range: FloatArray,
    bird_rho: FloatArray,
) -> tuple[NDArray[np.int64], FloatArray, FloatArray, NDArray[np.int8]]:
    """Which pulses return, from what range and reflectivity, and from what (FROM_*).

    Per pulse with uniforms u = (u₀, u₁, u₂): the target echoes if u₀ < P_d,target,
    else the scene if u₁ < P_d,scene; a return counts within [r_min, r_max].  A pulse
    without one is a false alarm if u₂ < p_fa, at range r_min + (r_max − r_min) u₂ / p_fa
    (given u₂ < p_fa, u₂ / p_fa is uniform on [0, 1)) and reflectivity 0.  With birds
    (``u_bird`` not empty) a bird echoes if u_bird < P_d,bird, tried before the target if
    it is nearer, after it otherwise, and always before the scene behind both.
    """
    n = u.shape[0]
    has_birds = u_bird.shape[0] > 0
    keep = np.empty(n, dtype=np.int64)
    r = np.empty(n)
    rho = np.empty(n)
    source = np.empty(n, dtype=np.int8)
    m = 0
    for i in range(n):
        bird_first = has_birds and bird_range[i] < target_range[i]
        hit_bird = bird_first and u_bird[i] < pd_bird[i]
        hit_target = not hit_bird and u[i, 0] < pd_target[i]
        if has_birds and not bird_first and not hit_target:
            hit_bird = u_bird[i] < pd_bird[i]
        hit_scene = not hit_target and not hit_bird and u[i, 1] < pd_scene[i]
        if hit_target:
            rng_i, rho_i, src = target_range[i], target_rho[i], FROM_TARGET
        elif hit_bird:
            rng_i, rho_i, src = bird_range[i], bird_rho[i], FROM_BIRD
        else:
            rng_i, rho_i, src = scene_range[i], scene_rho[i], FROM_SCENE
        if (hit_target or hit_bird or hit_scene) and r_min <= rng_i <= r_max:
            keep[m] = i
            r[m] = rng_i
            rho[m] = rho_i
            source[m] = src
            m += 1
        elif u[i, 2] < p_fa:
            keep[m] = i
            r[m] = r_min + (r_max - r_min) * (u[i, 2] / p_fa)
            rho[m] = 0.0
            source[m] = FROM_FALSE_ALARM
            m += 1
    return keep[:m], r[:m], rho[:m], source[:m]
