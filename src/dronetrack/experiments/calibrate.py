"""Constants of the classify stage measured on the simulator's truth: how long a drone
flies without slowing below a bird's stall speed (``classify.rules``' ``steady_flight_s``).

A bird never flies slower than its stall speed v_s; a drone does now and then (it
hovers, turns, stops at a waypoint).  So a track watched for T seconds that never
slowed below v_s is evidence of a bird, weighed by how often a drone in flight has
flown that long unbroken.  At each instant a drone flies at |v| ≥ v_s, its *stretch*
is the time since it last flew slower (or took off); over the flights' fast instants
the survival S(T) = P(stretch ≥ T), the mean over the flights (each kind of flight
weighs the same, however long), falls close to exponentially,

    S(T) ≈ exp(−T / μ),   μ = −Σ T_i² / Σ T_i ln S(T_i)   (least squares through 0)

so T seconds watched in flight multiply a drone's odds against a bird's by exp(−T / μ).
``python -m dronetrack.experiments.calibrate`` measures μ on every drone flight of the
simulator (``sim.flights``, the walkers' left out) over seeds other than the test
scenarios' 0-9.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np

from dronetrack.classify.rules import ClassRules
from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.flights import FLIGHTS, make_flight

__all__ = ["fast_stretches", "flights_steady_flight_s", "steady_flight_scale"]

CALIBRATION_SEEDS = range(10, 20)
CALIBRATION_HORIZON_S = 12.0  # the fit's longest T (S ≈ 0.06 there)


def fast_stretches(speed: FloatArray, dt: float, v_stall: float) -> FloatArray:
    """At each sample of ``speed`` (n,) [m/s], every ``dt`` [s], that is ≥ ``v_stall``:
    how long the flight has been that fast without a break [s] (the first fast sample
    of a stretch counts dt)."""
    fast = np.asarray(speed) >= v_stall
    # stretch_i = dt · (i − index of the last slow sample before i)
    index = np.arange(len(fast))
    last_slow = np.maximum.accumulate(np.where(fast, -1, index))
    out: FloatArray = dt * (index - last_slow)[fast].astype(np.float64)
    return out


def steady_flight_scale(flights: list[FloatArray], horizon_s: float) -> float:
    """μ [s] of the exponential fit S(T) ≈ exp(−T/μ) to the mean over ``flights`` of each
    one's survival of its stretches, over T on a 0.5 s grid up to ``horizon_s`` (see the
    module docstring); a flight never fast is left out."""
    t = np.arange(0.5, horizon_s + 1e-9, 0.5)
    curves = []
    for stretches in flights:
        s = np.sort(np.asarray(stretches, dtype=np.float64))
        if len(s):
            curves.append(1.0 - np.searchsorted(s, t, side="left") / len(s))  # P(stretch ≥ T)
    if not curves:
        raise InputError("no fast flight to measure the steady flight on")
    survival = np.mean(curves, axis=0)
    keep = survival > 0
    t, survival = t[keep], survival[keep]
    return float(-np.sum(t * t) / np.sum(t * np.log(survival)))


def flights_steady_flight_s(
    seeds: Iterable[int] = CALIBRATION_SEEDS,
    v_stall: float = ClassRules().v_stall,
    duration_s: float = 60.0,
    dt: float = 0.1,
) -> float:
    """μ [s] over the simulator's drone flights (the walkers' left out), each built for
    ``duration_s`` and sampled from take-off to its end, one per seed."""
    per_flight = []
    for name in FLIGHTS:
        if name.startswith("walk-"):
            continue
        stretches = []
        for seed in seeds:
            flight = make_flight(name, 0.0, duration_s, np.random.default_rng(seed))
            t = np.arange(max(flight.start, 0.0), flight.end, dt)
            speed = np.linalg.norm(flight.velocity(t), axis=1)
            stretches.append(fast_stretches(speed, dt, v_stall))
        per_flight.append(np.concatenate(stretches))
    return steady_flight_scale(per_flight, CALIBRATION_HORIZON_S)


if __name__ == "__main__":
    print(f"steady_flight_s = {flights_steady_flight_s():.2f} s")
