"""Seed 000's particle filter (Gazdag et al., §II-C), as pure functions and thin classes.

State of particle i: s = [x, y, z, v_x, v_y, v_z, a_x, a_y, a_z] (an (N, 9) array).
Predict, every period T, with p ~ N(0, σ²) drawn per axis (eqs. 1-7):

    delta position:  x_k = x + v T + p_x,                v_k = ρ (x_k − x) / T        (1)-(3)
    constant vel.:   x_k = x + v T + p_x,                v_k = v + p_v                (1), (4)-(5)
    constant acc.:   x_k = x + v T + ½ a T² + p_x,       v_k = v + a T + p_v,
                     a_k = a + p_a                                                   (1), (4)-(7)

    ρ = 1 if σ_particles < σ_threshold, else σ_pos / σ_particles                     (2)

Update, when the filtered cloud holds points (eqs. 8-9), with d_i the distance of
particle i to its nearest point:

    w_i = N(d_i; 0, σ_m²) + w_floor,        w̃_i = w_i / Σ_j w_j

then resample on every update.  The estimate is the particle mean; the spread
σ_particles is the mean of the per-axis standard deviations of the positions,
and the target counts as tracked while σ_particles < σ_threshold = 1.5 max(σ_pos, σ_m).

Parameters follow from the drone's dynamics by eq. (11):
σ_pos = v_max T / 3, σ_vel = a_max T / 3, σ_acc = 0, σ_m = s_diag / 2.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import ConfigError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.track.nearest import nearest_distances
from dronetrack.track.resample import RESAMPLERS
from dronetrack.types import Candidates, TrackEstimate

__all__ = [
    "MotionModel",
    "NoiseParameters",
    "ParticleFilter",
    "ParticleTracker",
    "cylinder_particles",
    "eq11_parameters",
    "gate_margin",
    "likelihood_weights",
    "predict",
    "spread",
]

MotionModel = Literal["delta", "cv", "ca"]
STATE_DIM = 9
# The reference adds 1e-4 m² to every squared distance before the Gaussian.
DISTANCE_EPS2 = 1e-4


@dataclass(frozen=True, slots=True)
class NoiseParameters:
    """Process and measurement noise [m, m/s, m/s², m] and the period T [s]."""

    sigma_pos: float
    sigma_vel: float
    sigma_acc: float
    sigma_m: float
    period: float

    @property
    def threshold(self) -> float:
        """σ_threshold = 1.5 · max(σ_pos, σ_m)"""
        return 1.5 * max(self.sigma_pos, self.sigma_m)


def eq11_parameters(v_max: float, a_max: float, s_diag: float, period: float) -> NoiseParameters:
    """Seed 000's eq. (11): σ_pos = v_max T/3, σ_vel = a_max T/3, σ_acc = 0, σ_m = s_diag/2."""
    return NoiseParameters(v_max * period / 3.0, a_max * period / 3.0, 0.0, s_diag / 2.0, period)


def cylinder_particles(
    rng: np.random.Generator, n: int, center: FloatArray, radius: float, height: float
) -> FloatArray:
    """(n, 9) particles at rest in a vertical cylinder on ``center`` (its base centre).

    As the reference: θ ~ U[0, 2π), r ~ U[0, R] (denser near the axis), z ~ U[z0, z0 + H].
    """
    theta = rng.uniform(0.0, 2.0 * np.pi, n)
    r = rng.uniform(0.0, radius, n)
    X = np.zeros((n, STATE_DIM))
    X[:, 0] = center[0] + r * np.sin(theta)
    X[:, 1] = center[1] + r * np.cos(theta)
    X[:, 2] = center[2] + rng.uniform(0.0, height, n)
    return X


def birth_particles(
    rng: np.random.Generator,
    n: int,
    position: FloatArray,
    velocity: FloatArray,
    sigma_p: float,
    sigma_v: float,
) -> FloatArray:
    """(n, 9) particles born on a confirmed candidate, at rest in acceleration:
    x ~ N(position, σ_p² I), v ~ N(velocity, σ_v² I)."""
    X = np.zeros((n, STATE_DIM))
    X[:, 0:3] = position + sigma_p * rng.standard_normal((n, 3))
    X[:, 3:6] = velocity + sigma_v * rng.standard_normal((n, 3))
    return X


_MODEL_CODE = {"delta": 0, "cv": 1, "ca": 2}


def predict(
    X: FloatArray, model: MotionModel, noise: NoiseParameters, rho: float, Z: FloatArray
) -> FloatArray:
    """One prediction step of eqs. (1)-(7); Z (N, 9) holds standard normal draws."""
    out = np.empty_like(X)
    _predict_kernel(
        X,
        out,
        _MODEL_CODE[model],
        noise.sigma_pos,
        noise.sigma_vel,
        noise.sigma_acc,
        rho,
        noise.period,
        Z,
    )
    return out


@nb.njit(cache=True, fastmath=True)
def _predict_kernel(
    X: FloatArray,
    out: FloatArray,
    model: int,
    s_pos: float,
    s_vel: float,
    s_acc: float,
    rho: float,
    T: float,
    Z: FloatArray,
) -> None:
    for i in range(X.shape[0]):
        for k in range(3):
            p, v, a = X[i, k], X[i, 3 + k], X[i, 6 + k]
            if model == 2:
                # x_k = x + v T + ½ a T² + p_x;  v_k = v + a T + p_v;  a_k = a + p_a
                out[i, k] = p + v * T + 0.5 * a * T * T + s_pos * Z[i, k]
                out[i, 3 + k] = v + a * T + s_vel * Z[i, 3 + k]
                out[i, 6 + k] = a + s_acc * Z[i, 6 + k]
            else:
                # x_k = x + v T + p_x
                p_new = p + v * T + s_pos * Z[i, k]
                out[i, k] = p_new
                # delta: v_k = ρ (x_k − x) / T;  constant velocity: v_k = v + p_v
                out[i, 3 + k] = rho * (p_new - p) / T if model == 0 else v + s_vel * Z[i, 3 + k]
                out[i, 6 + k] = 0.0


def likelihood_weights(distances: FloatArray, sigma_m: float, floor: float) -> FloatArray:
    """w_i = N(d_i; 0, σ_m²) + floor, normalised to sum to one (eqs. 8-9).

    With a floor every w_i ≥ floor, so the sum cannot underflow and the weights are
    formed directly.  Without one, N(d; 0, σ_m²) underflows to 0 beyond d ≈ 38 σ_m,
    so the weights come from the log-likelihoods by log-sum-exp instead.
    """
    d2 = distances**2 + DISTANCE_EPS2
    if floor > 0.0:
        w = np.exp(-0.5 * d2 / sigma_m**2) / (sigma_m * np.sqrt(2.0 * np.pi)) + floor
    else:
        # ℓ_i = −d_i² / (2 σ_m²) (the normaliser cancels);
        # w_i = exp(ℓ_i − max ℓ) / Σ_j exp(ℓ_j − max ℓ)
        log_w = -0.5 * d2 / sigma_m**2
        w = np.exp(log_w - log_w.max()) if len(log_w) else log_w
    total = float(w.sum())
    if not np.isfinite(total) or total <= 0.0:
        return np.full(len(w), 1.0 / len(w))
    out: FloatArray = w / total
    return out


def gate_margin(sigma_m: float, floor: float) -> float:
    """Distance [m] beyond which a point cannot change a weight: 8 σ_m, where
    N(8 σ_m; 0, σ_m²) = e^{−32} / (σ_m √(2π)) is below 10⁻⁶ of the floor; ∞ (no
    gate) without a floor, as then even tiny likelihoods set the weights' ratios.
    """
    density = np.exp(-32.0) / (sigma_m * np.sqrt(2.0 * np.pi))
    return 8.0 * sigma_m if density < 1e-6 * floor else np.inf


def spread(X: FloatArray) -> float:
    """σ_particles: the mean of the per-axis standard deviations of the positions."""
    return float(_spread_kernel(X))


@nb.njit(cache=True, fastmath=True)
def _spread_kernel(X: FloatArray) -> float:
    n = X.shape[0]
    total = 0.0
    for k in range(3):
        mean = 0.0
        for i in range(n):
            mean += X[i, k]
        mean /= n
        var = 0.0
        for i in range(n):
            d = X[i, k] - mean
            var += d * d
        total += np.sqrt(var / n)
    return total / 3.0


@nb.njit(cache=True)
def _position_bounds(X: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Per-axis minimum and maximum of the particle positions."""
    lo = X[0, 0:3].copy()
    hi = X[0, 0:3].copy()
    for i in range(1, X.shape[0]):
        for k in range(3):
            lo[k] = min(lo[k], X[i, k])
            hi[k] = max(hi[k], X[i, k])
    return lo, hi


@nb.njit(cache=True)
def _column_means(X: FloatArray) -> FloatArray:
    out = np.zeros(X.shape[1])
    for i in range(X.shape[0]):
        for k in range(X.shape[1]):
            out[k] += X[i, k]
    for k in range(X.shape[1]):
        out[k] /= X.shape[0]
    return out


@nb.njit(cache=True)
def _column_variances(X: FloatArray, k: int) -> FloatArray:
    """Population variance of the first ``k`` columns: (1/N) Σᵢ (xᵢ − x̄)²."""
    mean = np.zeros(k)
    for i in range(X.shape[0]):
        for c in range(k):
            mean[c] += X[i, c]
    mean /= X.shape[0]
    out = np.zeros(k)
    for i in range(X.shape[0]):
        for c in range(k):
            d = X[i, c] - mean[c]
            out[c] += d * d
    out /= X.shape[0]
    return out


@nb.njit(cache=True)
def _gather(X: FloatArray, idx: NDArray[np.int64]) -> FloatArray:
    """The particles X[idx] (resampling's copy)."""
    out = np.empty((idx.shape[0], X.shape[1]))
    for j in range(idx.shape[0]):
        out[j] = X[idx[j]]
    return out


class ParticleFilter:
    """The particles and their bookkeeping; the maths is in the functions above."""

    def __init__(
        self,
        n: int,
        model: MotionModel,
        noise: NoiseParameters,
        rng: np.random.Generator,
        resampling: str = "multinomial",
        weight_floor: float = 1e-4,
    ) -> None:
        if model not in ("delta", "cv", "ca"):
            raise ConfigError(f"unknown motion model {model!r}")
        if resampling not in RESAMPLERS:
            raise ConfigError(
                f"unknown resampling {resampling!r}; choose one of {', '.join(RESAMPLERS)}"
            )
        if n < 1:
            raise ConfigError(f"the particle count must be positive, got {n}")
        self.n = n
        self.model: MotionModel = model
        self.noise = noise
        self.rng = rng
        self.weight_floor = weight_floor
        self._gate_m = gate_margin(noise.sigma_m, weight_floor)
        self._resample = RESAMPLERS[resampling]
        self.X = np.zeros((n, STATE_DIM))
        self.sigma_particles = np.inf
        # Standard normal draws, STATE_DIM or 6 per particle (column blocks, contiguous).
        self._Z = np.zeros((n, STATE_DIM))

    @property
    def tracked(self) -> bool:
        return self.sigma_particles < self.noise.threshold

    def reset(self, center: FloatArray, radius: float, height: float) -> None:
        """Scatter the particles in a new cylinder (start-up, or an operator's reset)."""
        self.X = cylinder_particles(
            self.rng, self.n, np.asarray(center, dtype=np.float64), radius, height
        )
        self.sigma_particles = spread(self.X)

    def birth(self, position: FloatArray, velocity: FloatArray, share: float) -> None:
        """Move a share of the particles, drawn at random, onto a confirmed candidate.

        They are spread by σ_p = max(σ_pos, σ_m), so that once the update has kept
        them their spread is about σ_threshold / 1.5 and the filter locks; their
        velocities by σ_v = σ_pos / T (= v_max / 3 under eq. 11), the uncertainty of
        a velocity from a few frames of centroids.
        """
        k = round(share * self.n)
        if k == 0:
            return
        idx = self.rng.choice(self.n, size=k, replace=False)
        noise = self.noise
        self.X[idx] = birth_particles(
            self.rng,
            k,
            np.asarray(position, dtype=np.float64),
            np.asarray(velocity, dtype=np.float64),
            max(noise.sigma_pos, noise.sigma_m),
            noise.sigma_pos / noise.period,
        )
        self.sigma_particles = spread(self.X)

    def predict(self) -> None:
        """Move every particle one period ahead (eqs. 1-7)."""
        # ρ from the spread after the previous step, eq. (2)
        rho = 1.0 if self.tracked else self.noise.sigma_pos / self.sigma_particles
        # Draws for the noise terms the model uses: position (delta), + velocity (cv),
        # + acceleration (ca).
        dims = {"delta": 3, "cv": 6, "ca": STATE_DIM}[self.model]
        self._Z[:, :dims] = self.rng.standard_normal((self.n, dims), dtype=np.float32)
        self.X = predict(self.X, self.model, self.noise, rho, self._Z)
        self.sigma_particles = spread(self.X)

    def update(self, points: FloatArray) -> bool:
        """Weight by the nearest point and resample (eqs. 8-9); False if there are no points."""
        if len(points) == 0:
            return False
        # Points far from every particle leave all weights at the floor: keep only
        # those near the cloud's bounding box.
        near = points
        if np.isfinite(self._gate_m):
            lo, hi = _position_bounds(self.X)
            m = self._gate_m
            near = points[np.all((points >= lo - m) & (points <= hi + m), axis=1)]
        if len(near) == 0:
            w = np.full(self.n, 1.0 / self.n)
        else:
            d = nearest_distances(self.X[:, 0:3], near)
            w = likelihood_weights(d, self.noise.sigma_m, self.weight_floor)
        self.X = _gather(self.X, self._resample(w, self.rng))
        self.sigma_particles = spread(self.X)
        return True

    def estimate(self) -> tuple[FloatArray, FloatArray]:
        """Mean position and mean velocity of the particles."""
        mean = _column_means(self.X)
        return mean[0:3].copy(), mean[3:6].copy()

    def variance(self) -> FloatArray:
        """Population variance of the particle positions and velocities (6,)."""
        out: FloatArray = _column_variances(self.X, 6)
        return out


class ParticleTracker:
    """Seed 000's particle filter behind the ``track.base.Tracker`` protocol: predict
    every period, update when points arrive."""

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
        birth_share: float = 0.5,
    ) -> None:
        self.filter = ParticleFilter(n, model, noise, rng, resampling, weight_floor)
        if not 0.0 <= birth_share <= 1.0:
            raise ConfigError(f"birth_share must be in [0, 1], got {birth_share}")
        self.birth_share = birth_share
        self._births: Candidates | None = None
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
        self._births = None

    def acquire(self, candidates: Candidates) -> None:
        """Births on the best confirmed candidate in the next step (``track.base.CandidateStart``).

        Only the best (``candidates`` come best first): births spread over several
        candidates would leave the weights split between them, and the cloud would
        never condense enough to lock.  ``birth_share`` of the particles move (0.5 by
        default): the rest keep the filter's own belief, so a drone that reappears
        where the cloud waits is kept, while a candidate far from it takes over in
        one update (particles far from every point fall to the weight floor).
        """
        self._births = candidates if len(candidates) else None

    def step(self, t: float, points: FloatArray, steps: int) -> TrackEstimate:
        for _ in range(steps):
            self.filter.predict()
        births, self._births = self._births, None
        if births is not None and steps > 0 and not self.filter.tracked:
            self.filter.birth(births.positions[0], births.velocities[0], self.birth_share)
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
