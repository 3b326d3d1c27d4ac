"""Clutter: what else moves or echoes in an outdoor scene besides the target.

Three kinds, each optional (``[scene.clutter]``, ``config.run.ClutterConfig``), all
drawn from the clutter's own random stream (a child of the world's), so a run
without clutter draws exactly what it drew before clutter existed.

**Swaying vegetation.**  The wind moves each tree crown and hedge i (the scene's
``swaying`` primitives) by

    d_i(t) = s_i [A_g sin(2π t / T_g + φ_i) ŵ + A_s sin(2π t / (f_i T_s) + ψ_i) û_i]
    s_i = z_i / H_ref,  H_ref = 10 m

a slow gust along the wind direction ŵ plus a sway at the tree's own natural period
f_i T_s (f_i uniform in [0.8, 1.25]) along its own horizontal direction û_i, with
random phases φ_i, ψ_i.  s_i scales the amplitudes with the height z_i of the part's
centre: a bending stem moves more the higher up, so a hedge 0.8 m up moves a tenth
as much as a crown 8 m up.  Each frame is cast against the scene as it stands at
the frame's middle time: within a 100 ms frame a part moves at most
2π s_i (A_g / T_g + A_s / (0.8 T_s)) · 0.1 s, 7 cm for the tallest crowns (centres
15 m up) at the defaults, so a return is off by at most half that.

**Random false alarms.**  N ~ Poisson(λ T) spurious returns in a frame of T
seconds, each on a pulse of the frame drawn uniformly (so they spread over the
field of view as the scan pattern does, at that pulse's time and line) at a range
uniform in [r_min, r_max] of the sensor.  They come on top of the pulse's own
return, like a second echo.  The sensor's ``false_alarm_rate`` is another thing: a
probability per pulse, tried only on pulses that return nothing else, so its count
grows with the pulse rate and the share of the view that is open sky, and it draws
from the world's stream and is not marked in the truth.

**Birds.**  Each bird is an ellipsoid of wingspan L (semi-axes 0.25 L along its
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
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.config.run import ClutterConfig
from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray, rot_z
from dronetrack.sim.primitives import Primitives
from dronetrack.sim.pulses import Pulses
from dronetrack.sim.scene import Scene
from dronetrack.sim.shapes import ellipsoid

__all__ = [
    "CLUTTER_BIRD",
    "CLUTTER_FALSE_ALARM",
    "CLUTTER_NONE",
    "CLUTTER_SWAY",
    "Clutter",
    "ClutterSpec",
    "Flock",
    "Sway",
]

# What a return is, for the truth: FrameTruth.clutter holds one code per point.
CLUTTER_NONE = 0  # the target, the still scene, or the sensor's own false alarm
CLUTTER_SWAY = 1  # a swaying crown or hedge
CLUTTER_BIRD = 2
CLUTTER_FALSE_ALARM = 3  # a random false alarm of the clutter

SWAY_REFERENCE_HEIGHT_M = 10.0  # H_ref: the amplitudes are those of a part centred this high
SWAY_PERIOD_SPREAD = (0.8, 1.25)  # f_i: trees differ in their natural period

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
CROSSING_FRACTION = 0.5  # a crossing bird passes this far from the sensor to the target


@dataclass(frozen=True, slots=True)
class ClutterSpec:
    """Clutter settings in SI units, with the birds' crossing times on the world's clock."""

    gust_m: float = 0.0
    gust_period_s: float = 20.0
    sway_m: float = 0.0
    sway_period_s: float = 3.0
    false_alarms_per_s: float = 0.0
    birds: int = 0
    crossings_s: tuple[float, ...] = ()  # world times [s]
    bird_size_m: tuple[float, float] = (0.2, 0.5)
    bird_speed_m_s: tuple[float, float] = (5.0, 15.0)
    bird_height_m: tuple[float, float] = (5.0, 60.0)
    bird_reflectivity: float = 0.3

    @classmethod
    def from_config(cls, cfg: ClutterConfig, take_off: float = 0.0) -> ClutterSpec:
        """The settings of ``[scene.clutter]``; crossings count from ``take_off`` [s]."""
        return cls(
            gust_m=cfg.gust_m,
            gust_period_s=cfg.gust_period_s,
            sway_m=cfg.sway_m,
            sway_period_s=cfg.sway_period_s,
            false_alarms_per_s=cfg.false_alarms_per_s,
            birds=cfg.birds,
            crossings_s=tuple(take_off + t for t in cfg.bird_crossings_s),
            bird_size_m=cfg.bird_size_m,
            bird_speed_m_s=cfg.bird_speed_m_s,
            bird_height_m=cfg.bird_height_m,
            bird_reflectivity=cfg.bird_reflectivity,
        )


class Sway:
    """The wind's displacement of a scene's swaying parts (see the module's docstring)."""

    def __init__(self, scene: Scene, spec: ClutterSpec, rng: np.random.Generator) -> None:
        self.index = np.asarray(scene.swaying, dtype=np.int64)
        s = len(self.index)
        self.n_prims = len(scene.prims)
        self.scale = np.maximum(scene.prims.center[self.index, 2], 0.0) / SWAY_REFERENCE_HEIGHT_M
        self.gust_m, self.sway_m = spec.gust_m, spec.sway_m
        wind = rng.uniform(0.0, 2.0 * np.pi)
        self.wind = np.array([np.cos(wind), np.sin(wind), 0.0])
        self.omega_gust = 2.0 * np.pi / spec.gust_period_s
        self.phase_gust = rng.uniform(0.0, 2.0 * np.pi, s)
        self.omega_sway = 2.0 * np.pi / (spec.sway_period_s * rng.uniform(*SWAY_PERIOD_SPREAD, s))
        self.phase_sway = rng.uniform(0.0, 2.0 * np.pi, s)
        azimuth = rng.uniform(0.0, 2.0 * np.pi, s)
        self.direction = np.column_stack([np.cos(azimuth), np.sin(azimuth), np.zeros(s)])

    @property
    def bound(self) -> FloatArray:
        """The largest displacement of each swaying part, s_i (A_g + A_s) [m], (S,)."""
        b: FloatArray = self.scale * (self.gust_m + self.sway_m)
        return b

    def margin(self) -> FloatArray:
        """Per primitive of the scene, how far the wind can move it [m], (P,)."""
        out = np.zeros(self.n_prims)
        out[self.index] = self.bound
        return out

    def offsets(self, t: float) -> FloatArray:
        """d_i(t) of each swaying part [m], (S, 3)."""
        # d_i = s_i [A_g sin(ω_g t + φ_i) ŵ + A_s sin(ω_i t + ψ_i) û_i]
        gust = self.gust_m * np.sin(self.omega_gust * t + self.phase_gust)
        sway = self.sway_m * np.sin(self.omega_sway * t + self.phase_sway)
        d: FloatArray = self.scale[:, None] * (
            gust[:, None] * self.wind[None, :] + sway[:, None] * self.direction
        )
        return d

    def moved(self, prims: Primitives, t: float) -> Primitives:
        """The scene's primitives as the wind has moved them at time t."""
        center = prims.center.copy()
        center[self.index] += self.offsets(t)
        return Primitives(prims.kind, center, prims.rotation, prims.half, prims.reflectivity)


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
        spec: ClutterSpec,
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


class Clutter:
    """A scene's clutter, stepped with the world: sway, false alarms and birds.

    ``crossing(t)`` gives the sensor's and the target's positions at world time t,
    for the birds sent across the line of sight.
    """

    def __init__(
        self,
        spec: ClutterSpec,
        scene: Scene,
        rng: np.random.Generator,
        t0: float = 0.0,
        crossing: Callable[[float], tuple[FloatArray, FloatArray]] | None = None,
    ) -> None:
        self.spec = spec
        self.rng = rng
        self.sway: Sway | None = None
        if (spec.gust_m > 0 or spec.sway_m > 0) and len(scene.swaying):
            self.sway = Sway(scene, spec, rng)
        self.flock: Flock | None = None
        if spec.birds > 0:
            crossings: list[Crossing] = []
            for t in spec.crossings_s:
                if crossing is None:
                    raise ConfigError("bird crossings need the sensor's and the target's paths")
                sensor, target = crossing(t)
                los = target - sensor
                side = 1.0 if rng.random() < 0.5 else -1.0
                heading = math.atan2(los[1], los[0]) + side * 0.5 * np.pi
                crossings.append((t, sensor + CROSSING_FRACTION * los, heading))
            self.flock = Flock(spec, scene.extent, rng, t0, crossings)
        self.false_alarms_per_s = spec.false_alarms_per_s

    def sway_margin(self) -> FloatArray | None:
        """How far the wind can move each primitive of the scene [m], or None if still."""
        return None if self.sway is None else self.sway.margin()

    def scene_at(self, prims: Primitives, t: float) -> Primitives:
        """The scene's primitives at time t."""
        return prims if self.sway is None else self.sway.moved(prims, t)

    def sway_mask(self, n_prims: int) -> NDArray[np.bool_]:
        """Which of the scene's primitives sway, (n_prims + 1,); the last entry (no hit) False."""
        mask = np.zeros(n_prims + 1, dtype=bool)
        if self.sway is not None:
            mask[self.sway.index] = True
        return mask

    def false_alarms(
        self, pulses: Pulses, duration: float, r_min: float, r_max: float
    ) -> tuple[NDArray[np.int64], FloatArray]:
        """This frame's random false alarms: N ~ Poisson(λ T) of them, each on a pulse drawn
        uniformly from ``pulses`` (indices in increasing order, with repeats) at a range
        uniform in [r_min, r_max]; (N,) and (N,)."""
        if self.false_alarms_per_s <= 0 or len(pulses) == 0:
            return np.empty(0, dtype=np.int64), np.empty(0)
        count = int(self.rng.poisson(self.false_alarms_per_s * duration))
        index = np.sort(self.rng.integers(0, len(pulses), count))
        return index, self.rng.uniform(r_min, r_max, count)

    def bird_positions(self, t: float) -> FloatArray:
        """The birds' positions at time t, (B, 3) (none without birds)."""
        return np.empty((0, 3)) if self.flock is None else self.flock.positions(t)
