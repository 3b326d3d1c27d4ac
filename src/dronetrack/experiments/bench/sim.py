"""Simulator frames, timed.

``sim_frame_ms``: a full ``SimWorld.step()`` (turret motion, scan pattern,
per-point poses, ray casting, detection and noise) per sensor, with the turret
following the true target, in the outdoor scenarios of ``SIM_CASES``.  The
simulator must produce frames faster than the sensor does for runs, sweeps and
recordings to be quicker than real time; aiming the turret is not timed.
"""

from __future__ import annotations

import time

import numpy as np

from dronetrack.geometry.transforms import FloatArray

__all__ = ["SENSORS", "SIM_CASES", "SIM_WARMUP", "sim_frame_ms"]

# Sensor → (scenario, sensor override) whose frames are timed (all outdoors).
SIM_CASES: dict[str, tuple[str, str | None]] = {
    "avia": ("default", None),
    "mid40": ("default", "mid40"),
    "mid360": ("mid360-aggressive", None),
    "vlp16": ("walk-square", None),
}
SENSORS: tuple[str, ...] = tuple(SIM_CASES)
SIM_WARMUP = 10  # untimed simulator frames


def sim_frame_ms(
    scenario: str, sensor: str | None, n_frames: int, warmup: int = SIM_WARMUP
) -> FloatArray:
    """Wall time [ms] of ``n_frames`` simulator steps of ``scenario`` (with the sensor
    model ``sensor`` instead of its own, if given) after ``warmup`` untimed ones;
    the turret is aimed at the true target before every frame (not timed)."""
    from dronetrack.config.scenarios import SCENARIOS
    from dronetrack.control.aiming import aim_angles
    from dronetrack.sim.build import build_world
    from dronetrack.types import TurretCommand

    cfg = SCENARIOS[scenario]
    if sensor is not None:
        cfg = cfg.model_copy(update={"sensor": cfg.sensor.model_copy(update={"model": sensor})})
    world = build_world(cfg)
    out = np.empty(n_frames)
    for i in range(warmup + n_frames):
        pan, tilt = aim_angles(world.target_position(world.time), world.mount)
        world.command(TurretCommand(world.time, pan, tilt))
        start = time.perf_counter()
        world.step()
        if i >= warmup:
            out[i - warmup] = 1e3 * (time.perf_counter() - start)
    return out
