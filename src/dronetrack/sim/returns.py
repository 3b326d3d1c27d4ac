"""From echoes to returns: which echo of a pulse the sensor reports (first return,
with the detection probability), the sensor's own false alarms, the noise on a
return, and the objects on one pulse (drones, birds, walkers, vehicles) hiding parts of each other's
footprint.  The pulses and echoes come from ``sim/lidar.py`` and ``sim/echoes.py``;
this module only decides and perturbs.

The echoes of one pulse are taken nearest first.  Each object's echo is dimmed by
the share of the beam the nearer objects on the pulse fill, ρ' = ρ Π (1 − F_nearer),
and the scene behind keeps what none of them fills, 1 − Σ F.  The sensor reports the
first echo, in range order, that it detects (each with its own probability and its
own uniform draw), the scene if it detects none of them, else perhaps a false alarm.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TypeVar

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.clutter import CLUTTER_FALSE_ALARM
from dronetrack.sim.patterns import Pulses

__all__ = [
    "FROM_BIRD",
    "FROM_DRONE",
    "FROM_FALSE_ALARM",
    "FROM_MOVER",
    "FROM_SCENE",
    "FROM_TARGET",
    "PulseEchoes",
    "Scan",
    "TargetEcho",
    "beam_axes",
    "first_returns",
    "noisy_points",
    "pulse_echoes",
    "with_false_alarms",
]

Value = TypeVar("Value", bound=np.generic)

# Where a return comes from (``first_returns``).
FROM_SCENE = 0
FROM_TARGET = 1  # the target a run is scored on (object 0)
FROM_BIRD = 2
FROM_FALSE_ALARM = 3  # the sensor's own, per pulse
FROM_DRONE = 4  # another drone ([[targets]])
FROM_MOVER = 5  # a walker or a vehicle ([[walkers]], [[vehicles]])


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
    # (M,) the object each return came from (drones 0..D−1, then the birds, the walkers
    # and the vehicles), −1 none
    object_index: NDArray[np.int64] | None = None


@dataclass(frozen=True, slots=True)
class TargetEcho:
    """Echoes of an object (or of the nearest of several) on the candidate pulses."""

    index: NDArray[np.int64]  # (C,) pulse indices, increasing
    reflectivity: FloatArray  # (C,) Σ ρ cos θ / K
    fill: FloatArray  # (C,) fraction of sub-rays on the target
    range_m: FloatArray  # (C,) mean range of the sub-rays on the target (inf if none)
    surface: FloatArray  # (C,) mean reflectivity ρ of the parts hit (for the intensity)
    owner: NDArray[np.int64]  # (C,) the object each echo came from


@dataclass(frozen=True, slots=True)
class PulseEchoes:
    """Every object echo of a frame's pulses, sorted by pulse, then range, then channel
    (the order the channels were given in).

    ``order`` maps them back: sorted echo e is echo ``order[e]`` of the channels'
    concatenation.  ``transmission`` is each echo's share of the beam that the nearer
    echoes of its pulse leave, Π (1 − F) over the echoes strictly nearer.
    """

    pulse: NDArray[np.int64]  # (E,) sorted
    order: NDArray[np.int64]  # (E,)
    range_m: FloatArray  # (E,) sorted
    transmission: FloatArray  # (E,) sorted
    sizes: tuple[int, ...]  # echoes per channel

    def per_channel(self, sorted_values: FloatArray) -> list[FloatArray]:
        """Values of the sorted echoes, back in channel order and split by channel."""
        values = np.empty_like(sorted_values)
        values[self.order] = sorted_values
        return np.split(values, np.cumsum(self.sizes)[:-1])

    def sort(self, per_channel: Sequence[NDArray[Value]]) -> NDArray[Value]:
        """Per-channel values, concatenated and sorted as the echoes are."""
        joined: NDArray[Value] = np.concatenate(per_channel)[self.order]
        return joined


@nb.njit(cache=True)
def _transmission(pulse: NDArray[np.int64], ranges: FloatArray, fill: FloatArray) -> FloatArray:
    """Π (1 − F_f) over the echoes f of the same pulse strictly nearer than echo e, per
    echo e of echoes sorted by pulse and range (1 with none)."""
    out = np.ones(ranges.shape[0])
    first = 0  # the first echo of the current pulse
    for e in range(ranges.shape[0]):
        if pulse[e] != pulse[first]:
            first = e
        p = 1.0
        for f in range(first, e):
            if ranges[f] < ranges[e]:
                p *= 1.0 - fill[f]
        out[e] = p
    return out


def pulse_echoes(channels: list[TargetEcho]) -> PulseEchoes:
    """The echoes of ``channels`` (the target first, by priority on equal ranges),
    sorted nearest first on each pulse, with their transmission."""
    pulse = np.concatenate([c.index for c in channels]).astype(np.int64)
    ranges = np.concatenate([c.range_m for c in channels])
    fill = np.concatenate([c.fill for c in channels])
    if len(channels) == 1:  # one echo per pulse, in pulse order already
        order = np.arange(len(pulse), dtype=np.int64)
    else:
        channel = np.concatenate([np.full(len(c.index), j) for j, c in enumerate(channels)])
        order = np.lexsort((channel, ranges, pulse)).astype(np.int64)
    pulse, ranges = pulse[order], ranges[order]
    return PulseEchoes(
        pulse,
        order,
        ranges,
        _transmission(pulse, ranges, fill[order]),
        tuple(len(c.index) for c in channels),
    )


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
        object_index=None
        if scan.object_index is None
        else np.concatenate([scan.object_index, np.full(m, -1, np.int64)])[order],
    )


@nb.njit(cache=True)
def first_returns(
    u: FloatArray,
    echo_pulse: NDArray[np.int64],
    echo_range: FloatArray,
    echo_rho: FloatArray,
    echo_pd: FloatArray,
    echo_u: FloatArray,
    echo_source: NDArray[np.int8],
    echo_owner: NDArray[np.int64],
    pd_scene: FloatArray,
    scene_range: FloatArray,
    scene_rho: FloatArray,
    r_min: float,
    r_max: float,
    p_fa: float,
) -> tuple[NDArray[np.int64], FloatArray, FloatArray, NDArray[np.int8], NDArray[np.int64]]:
    """Which pulses return, from what range and reflectivity, from what (FROM_*) and from
    which object (−1: the scene or a false alarm).

    The object echoes are sorted by pulse (``echo_pulse``), nearest first on each
    (``pulse_echoes``); echo e is detected if echo_u[e] < echo_pd[e], and the
    first detected one is the return.  With none, the scene returns if u₁ < P_d,scene
    (u = (u₀, u₁, u₂) per pulse).  A return counts within [r_min, r_max].  A pulse
    without one is a false alarm if u₂ < p_fa, at range r_min + (r_max − r_min) u₂ / p_fa
    (given u₂ < p_fa, u₂ / p_fa is uniform on [0, 1)) and reflectivity 0.
    """
    n = u.shape[0]
    keep = np.empty(n, dtype=np.int64)
    r = np.empty(n)
    rho = np.empty(n)
    source = np.empty(n, dtype=np.int8)
    owner = np.empty(n, dtype=np.int64)
    m = 0
    e = 0  # the first echo of pulse i or after
    n_echoes = echo_pulse.shape[0]
    for i in range(n):
        hit = -1
        while e < n_echoes and echo_pulse[e] == i:
            if hit < 0 and echo_u[e] < echo_pd[e]:
                hit = e
            e += 1
        returned = True
        if hit >= 0:
            rng_i, rho_i, src, own = (
                echo_range[hit],
                echo_rho[hit],
                echo_source[hit],
                echo_owner[hit],
            )
        else:
            rng_i, rho_i, src, own = scene_range[i], scene_rho[i], FROM_SCENE, -1
            returned = u[i, 1] < pd_scene[i]
        if returned and r_min <= rng_i <= r_max:
            keep[m] = i
            r[m] = rng_i
            rho[m] = rho_i
            source[m] = src
            owner[m] = own
            m += 1
        elif u[i, 2] < p_fa:
            keep[m] = i
            r[m] = r_min + (r_max - r_min) * (u[i, 2] / p_fa)
            rho[m] = 0.0
            source[m] = FROM_FALSE_ALARM
            owner[m] = -1
            m += 1
    return keep[:m], r[:m], rho[:m], source[:m], owner[:m]
