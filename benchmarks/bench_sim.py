"""Simulator speed: one frame per sensor, on one core.

    python benchmarks/bench_sim.py [--frames 200] [--json out.json]

Targets (issue 2): a 100 ms Avia frame (24,000 rays) against the outdoor scene
plus a drone in at most 10 ms median; one VLP-16 revolution in at most 10 ms.
Each frame is a full ``SimWorld.step()``: turret motion, scan pattern, per-point
poses, ray casting, detection physics and noise.  The turret follows the true
target, as in seed 000's comparison runs.  The timing is ``dronetrack.experiments.bench``'s
(``sim_frame_ms``), which ``dronetrack bench`` runs with the rest of the suite.
"""

from __future__ import annotations

import os

# One core: pin every thread pool before numpy and numba load.
for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ[_var] = "1"

import argparse
import json
import platform
from pathlib import Path

import numpy as np

from dronetrack.allocator import tune_allocator
from dronetrack.experiments.bench import SIM_CASES, TARGETS, cpu_model, sim_frame_ms, single_thread

# Sensor → the scenario whose frames are timed (all in the outdoor scene).
CASES = SIM_CASES
TARGET_MS = {
    **{t.path[1]: t.limit for t in TARGETS if t.path[0] == "sim_frame_ms"},
    "vlp16": 10.0,  # issue 2; not one of ``dronetrack bench``'s targets
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=200)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    tune_allocator()
    with single_thread():
        _run(args)


def _run(args: argparse.Namespace) -> None:
    print(
        f"machine: {cpu_model()}, {os.cpu_count()} cores; Python {platform.python_version()}, "
        f"numpy {np.__version__}; one thread"
    )
    print(f"{'sensor':8} {'median':>8} {'mean':>8} {'p95':>8} {'max':>8}  target  [ms per frame]")
    results = {}
    for sensor, (scenario, override) in CASES.items():
        ms = sim_frame_ms(scenario, override, args.frames)
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
        args.json.write_text(json.dumps({"sim_frame_ms": results, "cpu": cpu_model()}, indent=2))


if __name__ == "__main__":
    main()
