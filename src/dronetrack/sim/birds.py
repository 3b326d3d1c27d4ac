"""Birds: small targets flying smooth random paths over a scene's area, part of a
scene's clutter (``sim/clutter.py``, ``[scene.clutter]``).

Each bird is an ellipsoid of wingspan L (semi-axes 0.25 L along its
heading, 0.5 L across, 0.1 L thick) flying at a speed s in [v_lo, v_hi]:

    v = s (cos γ cos ψ, cos γ sin ψ, sin γ)
    ω_k = μ + a (ω_{k−1} − μ) + σ √(1 − a²) n,  a = exp(−Δt / τ)   (each OU process)

with the turn rate ω (mean 0), the speed s and a height goal h* Ornstein-Uhlenbeck
processes (s and h* clipped to their ranges), and

    ψ̇ = clip(ω + k_s e, ±ω_max),   γ = γ_max tanh((h* − z) / L_z)

where the steering term k_s e turns the bird towards the area's centre (e the
heading error) once it leaves the inner area: the scene's area less a margin of
2 v_hi / ω_max + 5 m, the widest turn's diameter and some.  γ climbs or sinks
towards the goal, which keeps z within the height range (a step never overshoots
the goal).  The path is integrated with Δt = 50 ms, the positions interpolated
linearly between steps, so a bird's speed is s exactly.  A bird can be sent across
the line of sight: it then passes halfway between the sensor and the target at the
given time, heading across the line; its path before that is integrated backwards
from there.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Protocol

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray, rot_z
from dronetrack.sim.shapes import ellipsoid

__all__ = ["BIRD_DT_S", "BIRD_TURN_MAX", "BirdSettings", "Crossing", "Flock"]

BIRD_DT_S = 0.05  # integration step Δt
BIRD_CHUNK_STEPS = 200  # steps integrated at a time (10 s)
BIRD_TURN_SIGMA = 0.3  # stationary σ of the turn rate ω [rad/s]
BIRD_TURN_TAU_S = 2.0
BIRD_TURN_MAX = 0.8  # ω_max [rad/s]: the tightest turn has radius v / ω_max
BIRD_STEER_GAIN = 4.0  # k_s [1/s]: outside the inner area, turn towards its centre
BIRD_SPEED_TAU_S = 5.0
BIRD_GOAL_TAU_S = 20.0
BIRD_CLIMB_MAX = 0.3  # γ_max [rad], 17°
BIRD_HEIGHT_SCALE_M = 5.0  # L_z
BIRD_SPAN_AXES = (0.25, 0.5, 0.1)  # semi-axes as fractions of the wingspan L


class BirdSettings(Protocol):
    """What a flock reads of the clutter's settings (``sim.clutter.ClutterSpec``)."""

    @property
    def birds(self) -> int: ...
    @property
    def bird_size_m(self) -> tuple[float, float]: ...
    @property
    def bird_speed_m_s(self) -> tuple[float, float]: ...
    @property
    def bird_height_m(self) -> tuple[float, float]: ...
    @property
    def bird_reflectivity(self) -> float: ...


@nb.njit(cache=True)
def _fly(
    p0: FloatArray,
    psi0: FloatArray,
    omega0: FloatArray,
    speed0: FloatArray,
    goal0: FloatArray,
    noise: FloatArray,
    dt: float,
    inner: FloatArray,
    outer: FloatArray,
    heights: FloatArray,
    speeds: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Fly B birds K steps of dt from p0 (B, 3) with heading, turn rate, speed and height
    goal (B,) each, on standard normals ``noise`` (K, B, 3).  inner and outer are areas
    (x0, y0, x1, y1), heights and speeds (low, high).  Returns the positions (K + 1, B, 3),
    the velocities (K, B, 3) and the final heading, turn rate, speed and goal (B,)."""
    k_steps, n_birds = noise.shape[0], noise.shape[1]
    pos = np.empty((k_steps + 1, n_birds, 3))
    vel = np.empty((k_steps, n_birds, 3))
    psi, omega, speed, goal = psi0.copy(), omega0.copy(), speed0.copy(), goal0.copy()
    a_w = math.exp(-dt / BIRD_TURN_TAU_S)
    a_s = math.exp(-dt / BIRD_SPEED_TAU_S)
    a_g = math.exp(-dt / BIRD_GOAL_TAU_S)
    mu_s, sigma_s = 0.5 * (speeds[0] + speeds[1]), 0.25 * (speeds[1] - speeds[0])
    mu_g, sigma_g = 0.5 * (heights[0] + heights[1]), 0.25 * (heights[1] - heights[0])
    cx, cy = 0.5 * (inner[0] + inner[2]), 0.5 * (inner[1] + inner[3])
    for b in range(n_birds):
        x, y, z = p0[b, 0], p0[b, 1], p0[b, 2]
        pos[0, b, 0], pos[0, b, 1], pos[0, b, 2] = x, y, z
        for k in range(k_steps):
            n0, n1, n2 = noise[k, b, 0], noise[k, b, 1], noise[k, b, 2]
            # x_k = μ + a (x_{k−1} − μ) + σ √(1 − a²) n   (exact OU step)
            omega[b] = a_w * omega[b] + BIRD_TURN_SIGMA * math.sqrt(1.0 - a_w * a_w) * n0
            s = mu_s + a_s * (speed[b] - mu_s) + sigma_s * math.sqrt(1.0 - a_s * a_s) * n1
            speed[b] = min(max(s, speeds[0]), speeds[1])
            g = mu_g + a_g * (goal[b] - mu_g) + sigma_g * math.sqrt(1.0 - a_g * a_g) * n2
            goal[b] = min(max(g, heights[0]), heights[1])
            turn = omega[b]
            if x < inner[0] or x > inner[2] or y < inner[1] or y > inner[3]:
                # e = wrap(atan2(c − p) − ψ) to (−π, π]
                e = math.atan2(cy - y, cx - x) - psi[b]
                e = math.atan2(math.sin(e), math.cos(e))
                turn += BIRD_STEER_GAIN * e
            turn = min(max(turn, -BIRD_TURN_MAX), BIRD_TURN_MAX)
            psi[b] += turn * dt
            # γ = γ_max tanh((h* − z) / L_z);  v = s (cos γ cos ψ, cos γ sin ψ, sin γ)
            gamma = BIRD_CLIMB_MAX * math.tanh((goal[b] - z) / BIRD_HEIGHT_SCALE_M)
            vx = speed[b] * math.cos(gamma) * math.cos(psi[b])
            vy = speed[b] * math.cos(gamma) * math.sin(psi[b])
            vz = speed[b] * math.sin(gamma)
            vel[k, b, 0], vel[k, b, 1], vel[k, b, 2] = vx, vy, vz
            # A safeguard only: the steering keeps the birds well inside the outer area.
            x = min(max(x + vx * dt, outer[0]), outer[2])
            y = min(max(y + vy * dt, outer[1]), outer[3])
            z = min(max(z + vz * dt, heights[0]), heights[1])
            pos[k + 1, b, 0], pos[k + 1, b, 1], pos[k + 1, b, 2] = x, y, z
    return pos, vel, psi, omega, speed, goal


# A crossing: the world time, the point the bird passes through and its heading there.
Crossing = tuple[float, FloatArray, float]


class Flock:
    """Birds flying smooth random paths over a scene's area (see the module's docstring).

    The paths are tables of positions every ``BIRD_DT_S`` from ``t0``, extended
    ``BIRD_CHUNK_STEPS`` at a time as the clock runs, from ``rng``.
    """

    def __init__(
        self,
        spec: BirdSettings,
        extent: tuple[float, float, float, float],
        rng: np.random.Generator,
        t0: float = 0.0,
        crossings: Sequence[Crossing] = (),
    ) -> None:
        n = spec.birds
        if n < len(crossings):
            raise ConfigError(f"{len(crossings)} bird crossings need at least as many birds")
        self.rng = rng
        self.t0 = float(t0)
        self.dt = BIRD_DT_S
        self.speeds = np.array(spec.bird_speed_m_s, dtype=np.float64)
        self.heights = np.array(spec.bird_height_m, dtype=np.float64)
        x0, y0, x1, y1 = extent
        margin = 2.0 * self.speeds[1] / BIRD_TURN_MAX + 5.0
        if min(x1 - x0, y1 - y0) < 4.0 * margin:
            raise ConfigError(
                f"birds at up to {self.speeds[1]:g} m/s need an area at least {4 * margin:.0f} m "
                f"across; this scene's is {x1 - x0:g} × {y1 - y0:g} m"
            )
        self.outer = np.array([x0, y0, x1, y1], dtype=np.float64)
        self.inner = np.array([x0 + margin, y0 + margin, x1 - margin, y1 - margin])
        self.span = rng.uniform(*spec.bird_size_m, n)
        self.reflectivity = float(spec.bird_reflectivity)
        self.bodies = [
            ellipsoid((0.0, 0.0, 0.0), np.multiply(BIRD_SPAN_AXES, L), self.reflectivity)
            for L in self.span
        ]
        self.radius = 0.5 * self.span  # the largest semi-axis
        self.enter_s = np.full(n, -np.inf)  # every bird is there from the start
        # Starting states, drawn for every bird so the draws do not depend on the crossings.
        p = np.column_stack(
            [
                rng.uniform(self.inner[0], self.inner[2], n),
                rng.uniform(self.inner[1], self.inner[3], n),
                rng.uniform(self.heights[0], self.heights[1], n),
            ]
        )
        psi = rng.uniform(-np.pi, np.pi, n)
        omega = np.zeros(n)
        speed = rng.uniform(self.speeds[0], self.speeds[1], n)
        goal = p[:, 2].copy()
        k_end = BIRD_CHUNK_STEPS
        steps = [self._step_of(t) for t, _, _ in crossings]
        if steps:
            k_end = max(k_end, max(steps) + BIRD_CHUNK_STEPS)
        self._pos = np.empty((k_end + 1, n, 3))
        self._vel = np.empty((k_end, n, 3))
        self._state = (psi, omega, speed, goal)
        free = np.arange(len(crossings), n)
        if len(free):
            self._fly_into(free, p[free], psi[free], omega[free], speed[free], goal[free], 0, k_end)
        for b, ((_, point, heading), k_c) in enumerate(zip(crossings, steps, strict=True)):
            c = self._inside(point)
            one = np.ones(1)
            s_c = rng.uniform(self.speeds[0], self.speeds[1], 1)
            if k_c > 0:
                # Backwards from the crossing: fly away from it, then reverse time.
                back, vb, *_ = _fly(
                    c[None, :],
                    one * (heading + np.pi),
                    one * 0.0,
                    s_c,
                    one * c[2],
                    rng.standard_normal((k_c, 1, 3)),
                    self.dt,
                    self.inner,
                    self.outer,
                    self.heights,
                    self.speeds,
                )
                self._pos[: k_c + 1, b] = back[::-1, 0]
                self._vel[:k_c, b] = -vb[::-1, 0]
            self._fly_into(
                np.array([b]), c[None, :], one * heading, one * 0.0, s_c, one * c[2], k_c, k_end
            )

    def _step_of(self, t: float) -> int:
        """The table step nearest world time t (0 for times before the start)."""
        return max(0, round((t - self.t0) / self.dt))

    def _inside(self, point: FloatArray) -> FloatArray:
        """``point`` moved into the area 1 m in from its edges and into the height range."""
        lo = np.array([self.outer[0] + 1.0, self.outer[1] + 1.0, self.heights[0]])
        hi = np.array([self.outer[2] - 1.0, self.outer[3] - 1.0, self.heights[1]])
        out: FloatArray = np.clip(np.asarray(point, dtype=np.float64), lo, hi)
        return out

    def _fly_into(
        self,
        birds: NDArray[np.int64],
        p: FloatArray,
        psi: FloatArray,
        omega: FloatArray,
        speed: FloatArray,
        goal: FloatArray,
        k_start: int,
        k_end: int,
    ) -> None:
        """Fly ``birds`` from table step k_start to k_end and keep their final states."""
        noise = self.rng.standard_normal((k_end - k_start, len(birds), 3))
        pos, vel, *state = _fly(
            p,
            psi,
            omega,
            speed,
            goal,
            noise,
            self.dt,
            self.inner,
            self.outer,
            self.heights,
            self.speeds,
        )
        self._pos[k_start : k_end + 1, birds] = pos
        self._vel[k_start:k_end, birds] = vel
        for mine, new in zip(self._state, state, strict=True):
            mine[birds] = new

    def __len__(self) -> int:
        return len(self.span)

    def _extend(self, k: int) -> None:
        """Make the table reach step k + 1."""
        while len(self._vel) <= k:
            n = len(self)
            k_end = len(self._vel)
            self._pos = np.concatenate([self._pos, np.empty((BIRD_CHUNK_STEPS, n, 3))])
            self._vel = np.concatenate([self._vel, np.empty((BIRD_CHUNK_STEPS, n, 3))])
            self._fly_into(
                np.arange(n), self._pos[k_end], *self._state, k_end, k_end + BIRD_CHUNK_STEPS
            )

    def _locate(self, t: FloatArray) -> tuple[NDArray[np.int64], FloatArray]:
        u = np.maximum((np.asarray(t, dtype=np.float64) - self.t0) / self.dt, 0.0)
        k = np.floor(u).astype(np.int64)
        if k.size:
            self._extend(int(k.max()))
        return k, u - k

    def positions(self, t: float) -> FloatArray:
        """Every bird's position at time t, (B, 3)."""
        k, f = self._locate(np.array([t]))
        p: FloatArray = self._pos[k[0]] + f[0] * (self._pos[k[0] + 1] - self._pos[k[0]])
        return p

    def velocities(self, t: float) -> FloatArray:
        """Every bird's velocity at time t, (B, 3)."""
        k, _ = self._locate(np.array([t]))
        v: FloatArray = self._vel[k[0]].copy()
        return v

    def path(self, bird: int, times: FloatArray) -> FloatArray:
        """Bird ``bird``'s positions at ``times`` (N,), (N, 3)."""
        k, f = self._locate(times)
        p0 = self._pos[k, bird]
        out: FloatArray = p0 + f[:, None] * (self._pos[k + 1, bird] - p0)
        return out

    def attitude(self, bird: int, t: float) -> FloatArray:
        """world_R_body of a bird at time t: body x along its horizontal heading."""
        v = self.velocities(t)[bird]
        R: FloatArray = rot_z(math.atan2(v[1], v[0]))
        return R
