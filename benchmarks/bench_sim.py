"""Simulator speed: one frame per sensor, on one core.

    python benchmarks/bench_sim.py [--frames 200] [--json out.json]

Targets (issue 2): a 100 ms Avia frame (24,000 rays) against the outdoor scene
plus a drone in at most 10 ms median; one VLP-16 revolution in at most 10 ms.
Each frame is a full ``SimWorld.step()``: turret motion, scan pattern, per-point
poses, ray casting, detection physics and noise.  The turret follows the true
target, as in seed 000's comparison runs.
"""

from __future__ import annotations

import os

# One core: pin every thread pool before numpy and numba load.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from dronetrack.allocator import tune_allocator
from dronetrack.control.aiming import aim_angles
from dronetrack.sim.build import build_world
from dronetrack.sim.scenarios import SCENARIOS
from dronetrack.types import TurretCommand

# Sensor → the scenario whose frames are timed (all in the outdoor scene).
CASES = {
    "avia": ("default", None),
    "mid40": ("default", "mid40"),
    "mid360": ("mid360-aggressive", None),
    "vlp16": ("walk-square", None),
}
TARGET_MS = {"avia": 10.0, "vlp16": 10.0}


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def time_frames(scenario: str, sensor: str | None, n_frames: int, warmup: int = 10) -> np.ndarray:
    """Wall time [ms] of ``n_frames`` simulator steps after ``warmup`` untimed ones."""
    cfg = SCENARIOS[scenario]
    if sensor is not None:
        cfg = cfg.model_copy(update={"sensor": cfg.sensor.model_copy(update={"model": sensor})})
    world = build_world(cfg)
    times = []
    for i in range(warmup + n_frames):
        pan, tilt = aim_angles(world.target_position(world.time), world.mount)
        world.command(TurretCommand(world.time, pan, tilt))
        start = time.perf_counter()
        world.step()
        if i >= warmup:
            times.append(1e3 * (time.perf_counter() - start))
    return np.array(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    tune_allocator()
    print(
        f"machine: {_cpu_model()}, {os.cpu_count()} cores; Python {platform.python_version()}, "
        f"numpy {np.__version__}; one thread"
    )
    print(f"{'sensor':8} {'median':>8} {'mean':>8} {'p95':>8} {'max':>8}  target  [ms per frame]")
    results = {}
    for sensor, (scenario, override) in CASES.items():
        ms = time_frames(scenario, override, args.frames)
        results[sensor] = {
            "median": float(np.median(ms)),
            "mean": float(ms.mean()),
            "p95": float(np.percentile(ms, 95)),
            "max": float(ms.max()),
        }
        target = TARGET_MS.get(sensor)
        verdict = (
            ""
            if target is None
            else (f"≤ {target:g}  " + ("ok" if np.median(ms) <= target else "MISSED"))
        )
        row = " ".join(f"{results[sensor][k]:8.2f}" for k in ("median", "mean", "p95", "max"))
        print(f"{sensor:8} {row}  {verdict}")
    if args.json is not None:
        args.json.write_text(json.dumps({"sim_frame_ms": results, "cpu": _cpu_model()}, indent=2))


if __name__ == "__main__":
    main()
