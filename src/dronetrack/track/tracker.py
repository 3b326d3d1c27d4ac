"""The tracker interface the pipeline drives, and seed 000's particle filter behind it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np

from dronetrack.geometry.transforms import FloatArray
from dronetrack.track.particle import MotionModel, NoiseParameters, ParticleFilter

__all__ = ["ParticleTracker", "TrackEstimate", "Tracker"]


@dataclass(frozen=True, slots=True)
class TrackEstimate:
    """A tracker's belief after a frame."""

    t: float  # [s]
    position: FloatArray  # (3,) world [m]
    velocity: FloatArray  # (3,) world [m/s]
    tracked: bool
    spread: float  # σ_particles for a particle filter, √max position variance for a Kalman one [m]
    particles: FloatArray | None = None  # (N, 3) positions, for display
    # diag of the position and velocity covariance (6,) [m², (m/s)²]
    variance: FloatArray | None = None
    measurement: FloatArray | None = None  # (3,) z of this frame's update or (re)start [m]


class Tracker(Protocol):
    """Anything the pipeline can feed with foreground points."""

    @property
    def period(self) -> float:
        """The filter period T [s]."""
        ...

    def step(self, t: float, points: FloatArray, steps: int) -> TrackEstimate:
        """Predict ``steps`` periods (0 for a repeated frame), update with ``points`` (M, 3)."""
        ...

    def reset(self) -> None:
        """Start again from the initial belief."""
        ...


class ParticleTracker:
    """Seed 000's particle filter: predict every period, update when points arrive."""

    def __init__(
        self,
        n: int,
        model: MotionModel,
        noise: NoiseParameters,
        rng: np.random.Generator,
        cylinder_center: FloatArray,
        cylinder_radius: float,
        cylinder_height: float,
        resampling: str = "multinomial",
        weight_floor: float = 1e-4,
    ) -> None:
        self.filter = ParticleFilter(n, model, noise, rng, resampling, weight_floor)
        self._cylinder = (
            np.asarray(cylinder_center, dtype=np.float64),
            cylinder_radius,
            cylinder_height,
        )
        self.reset()

    @property
    def period(self) -> float:
        return self.filter.noise.period

    def reset(
        self,
        center: FloatArray | None = None,
        radius: float | None = None,
        height: float | None = None,
    ) -> None:
        """Scatter the particles in the start cylinder, or in a new one."""
        c, r, h = self._cylinder
        if center is not None:
            c = np.asarray(center, dtype=np.float64)
        self._cylinder = (c, r if radius is None else radius, h if height is None else height)
        self.filter.reset(*self._cylinder)

    def step(self, t: float, points: FloatArray, steps: int) -> TrackEstimate:
        for _ in range(steps):
            self.filter.predict()
        if steps > 0:
            self.filter.update(points)
        position, velocity = self.filter.estimate()
        return TrackEstimate(
            t,
            position,
            velocity,
            self.filter.tracked,
            self.filter.sigma_particles,
            self.filter.X[:, 0:3],
            self.filter.variance(),
        )
