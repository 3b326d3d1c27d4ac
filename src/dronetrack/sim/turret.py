"""The pan-tilt unit as a plant: per-axis rate and acceleration limits, latency, resolution.

Per axis, every dt (sensor_physics.md §4.1):

    θ_ref(t) = θ_c(t − L)                                   (command latency L)
    e = θ_ref − θ
    v_des = sign(e) · min(ω_max, √(2 α_max |e|), |e| / dt)  (brake in time, no overshoot)
    v ← v + clip(v_des − v, −α_max dt, α_max dt)
    θ ← clip(θ + v dt, θ_min, θ_max)
    pointing = q · round(θ / q)                             (position resolution q)

In velocity mode v_des is the commanded rate, clipped to ±ω_max.  A Dynamixel
"time-based profile" (the Interbotix default) turns each goal into a triangular
move of fixed duration; set ``profile_time_s`` to model it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numba as nb
import numpy as np

from dronetrack.config.rig import AxisSpec, TurretSpec
from dronetrack.errors import ConfigError, InputError
from dronetrack.geometry.mount import MountGeometry
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TurretCommand, TurretState

__all__ = ["TurretPlant"]


@dataclass(slots=True)
class _Axis:
    spec: AxisSpec
    theta: float
    omega: float = 0.0
    mode: str = "position"
    ref: float = 0.0
    # Time-based profile move: start time, start angle, displacement.
    move_t0: float = 0.0
    move_from: float = 0.0
    move_delta: float = 0.0
    # Commands waiting for their latency: (time they act, mode, reference).
    pending: list[tuple[float, str, float]] = field(default_factory=list)

    def queue(self, stamp: float, mode: str, ref: float) -> None:
        self.pending.append((stamp + self.spec.latency, mode, ref))
        self.pending.sort(key=lambda item: item[0])

    def apply_due(self, t: float) -> None:
        while self.pending and self.pending[0][0] <= t + 1e-12:
            t_apply, mode, ref = self.pending.pop(0)
            self.set_goal(mode, ref, t_apply)

    @property
    def next_due(self) -> float:
        return self.pending[0][0] if self.pending else math.inf

    def set_goal(self, mode: str, ref: float, t: float) -> None:
        self.mode = mode
        self.ref = min(max(ref, self.spec.lower), self.spec.upper) if mode == "position" else ref
        self.move_t0, self.move_from, self.move_delta = t, self.theta, self.ref - self.theta

    def run(self, n: int, dt: float, t0: float, profile_time: float) -> FloatArray:
        """Advance n steps of dt from time t0; return the pointing after each step."""
        s = self.spec
        pointing, self.theta, self.omega = _integrate_axis(
            self.theta,
            self.omega,
            self.mode == "position",
            self.ref,
            s.rate,
            s.accel,
            s.lower,
            s.upper,
            s.resolution,
            dt,
            n,
            t0,
            profile_time,
            self.move_t0,
            self.move_from,
            self.move_delta,
        )
        return pointing

    @property
    def pointing(self) -> float:
        return _quantise(self.theta, self.spec.resolution)

    @property
    def at_rest(self) -> bool:
        """Holding a position goal it has reached (to 1 nrad, at 1 nrad/s), with nothing
        queued."""
        return (
            not self.pending
            and self.mode == "position"
            and abs(self.omega) < 1e-9
            and abs(self.theta - self.ref) < 1e-9
        )

    def shift(self, delta: float) -> None:
        """Move the axis's time base by ``delta`` [s] (its move and queued goals with it)."""
        self.move_t0 += delta
        self.pending = [(t + delta, mode, ref) for t, mode, ref in self.pending]


@nb.njit(cache=True)
def _quantise(theta: float, q: float) -> float:
    """pointing = q · round(θ / q)"""
    return q * np.round(theta / q) if q > 0 else theta


@nb.njit(cache=True)
def _integrate_axis(
    theta: float,
    omega: float,
    position_mode: bool,
    ref: float,
    rate: float,
    accel: float,
    lower: float,
    upper: float,
    q: float,
    dt: float,
    n: int,
    t0: float,
    profile_time: float,
    move_t0: float,
    move_from: float,
    move_delta: float,
) -> tuple[FloatArray, float, float]:
    """n steps of one axis (module docstring); returns pointing after each step, θ and ω."""
    out = np.empty(n)
    for i in range(n):
        if position_mode and profile_time > 0:
            # Triangular move: s(u) = 2u² for u < ½, 1 − 2(1 − u)² after, u = (t − t0) / T.
            u = min(max((t0 + (i + 1) * dt - move_t0) / profile_time, 0.0), 1.0)
            s = 2.0 * u * u if u < 0.5 else 1.0 - 2.0 * (1.0 - u) ** 2
            ds = 4.0 * u if u < 0.5 else 4.0 * (1.0 - u)
            theta = min(max(move_from + move_delta * s, lower), upper)
            omega = move_delta * ds / profile_time
        else:
            if position_mode:
                e = ref - theta
                v_des = math.copysign(min(rate, math.sqrt(2.0 * accel * abs(e)), abs(e) / dt), e)
            else:
                v_des = min(max(ref, -rate), rate)
            omega += min(max(v_des - omega, -accel * dt), accel * dt)
            theta += omega * dt
            if theta <= lower or theta >= upper:
                theta = min(max(theta, lower), upper)
                omega = 0.0
        out[i] = _quantise(theta, q)
    return out, theta, omega


class TurretPlant:
    """The simulated turret: takes commands, advances in time, reports its state."""

    def __init__(
        self,
        spec: TurretSpec,
        mount: MountGeometry | None = None,
        pan: float = 0.0,
        tilt: float = 0.0,
        dt: float = 1e-3,
        t0: float = 0.0,
    ) -> None:
        self.spec = spec
        self.mount = mount or spec.mount
        self.dt = dt
        self.time = t0
        self._pan = _Axis(spec.pan, min(max(pan, spec.pan.lower), spec.pan.upper))
        self._tilt = _Axis(spec.tilt, min(max(tilt, spec.tilt.lower), spec.tilt.upper))
        self._pan.set_goal("position", self._pan.theta, t0)
        self._tilt.set_goal("position", self._tilt.theta, t0)
        # The last advance's sample times and pan/tilt pointing (see ``advance``).
        self.last_path: tuple[FloatArray, FloatArray, FloatArray] | None = None

    def command(self, cmd: TurretCommand) -> None:
        """Queue a command; each axis acts on it after its own latency."""
        if cmd.mode not in ("position", "velocity"):
            raise ConfigError(f"unknown turret command mode {cmd.mode!r}")
        if not (math.isfinite(cmd.pan) and math.isfinite(cmd.tilt)):
            raise ConfigError("turret command angles must be finite")
        self._pan.queue(cmd.stamp, cmd.mode, cmd.pan)
        self._tilt.queue(cmd.stamp, cmd.mode, cmd.tilt)

    def command_axis(self, axis: str, stamp: float, angle: float) -> None:
        """Queue a position goal [rad] for one axis ('pan' or 'tilt') alone, as a servo
        takes its own goal; it acts after that axis's latency."""
        if axis not in ("pan", "tilt"):
            raise ConfigError(f"a turret axis is 'pan' or 'tilt', not {axis!r}")
        if not math.isfinite(angle):
            raise ConfigError("turret command angles must be finite")
        (self._pan if axis == "pan" else self._tilt).queue(stamp, "position", angle)

    def advance(self, t_end: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Run to ``t_end``; return sample times and pan/tilt pointing, both ends included
        (also kept as ``last_path``)."""
        if not t_end > self.time:
            raise InputError(f"turret time runs forward: asked for {t_end} s at {self.time} s")
        n = max(1, math.ceil((t_end - self.time) / self.dt - 1e-9))
        dt = (t_end - self.time) / n
        times: FloatArray = self.time + dt * np.arange(n + 1, dtype=np.float64)
        out = {}
        profile = self.spec.profile_time_s
        for name, axis in (("pan", self._pan), ("tilt", self._tilt)):
            pointing = np.empty(n + 1)
            pointing[0] = axis.pointing
            i = 0
            while i < n:
                axis.apply_due(float(times[i]))
                # Run up to the step at whose start the next queued command acts.
                due = int(np.searchsorted(times[:n], axis.next_due - 1e-12, side="left"))
                j = min(n, max(due, i + 1))
                pointing[i + 1 : j + 1] = axis.run(j - i, dt, float(times[i]), profile)
                i = j
            axis.apply_due(float(t_end))
            out[name] = pointing
        self.time = float(t_end)
        self.last_path = (times, out["pan"], out["tilt"])
        return times, out["pan"], out["tilt"]

    @property
    def at_rest(self) -> bool:
        """Both axes hold a position goal they have reached, with nothing queued: advancing
        changes nothing but the time."""
        return self._pan.at_rest and self._tilt.at_rest

    def rebase(self, t: float) -> None:
        """Make the present time ``t`` [s], keeping the state (angles, rates, the move in
        hand and the queued goals, each moved with the clock): a turret that moved before
        a run's clock started carries on from where it is at the run's time 0."""
        delta = t - self.time
        self._pan.shift(delta)
        self._tilt.shift(delta)
        self.time = float(t)
        self.last_path = None

    def state(self) -> TurretState:
        """The measured joint state now."""
        return TurretState(
            self.time, self._pan.pointing, self._tilt.pointing, self._pan.omega, self._tilt.omega
        )
