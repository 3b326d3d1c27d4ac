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

**Birds** (``sim/birds.py``): small ellipsoids flying smooth random paths over the
scene's area, some sent across the line of sight between the sensor and the target.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.config.run import ClutterConfig
from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.birds import Crossing, Flock
from dronetrack.sim.primitives import Primitives
from dronetrack.sim.pulses import Pulses
from dronetrack.sim.scene import Scene

__all__ = [
    "CLUTTER_BIRD",
    "CLUTTER_FALSE_ALARM",
    "CLUTTER_NONE",
    "CLUTTER_SWAY",
    "Clutter",
    "ClutterSpec",
    "Sway",
]

# What a return is, for the truth: FrameTruth.clutter holds one code per point.
CLUTTER_NONE = 0  # the target, the still scene, or the sensor's own false alarm
CLUTTER_SWAY = 1  # a swaying crown or hedge
CLUTTER_BIRD = 2
CLUTTER_FALSE_ALARM = 3  # a random false alarm of the clutter

SWAY_REFERENCE_HEIGHT_M = 10.0  # H_ref: the amplitudes are those of a part centred this high
SWAY_PERIOD_SPREAD = (0.8, 1.25)  # f_i: trees differ in their natural period

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
