"""The learning background map over a long all-round run: ``learning_map``.

The ``default`` world (an Avia on the turret, a Phantom 4 flying, a static scene out
to 200 m and more) with the turret's field of regard all round (pan ±180°, tilt −30°
to 5°), swept at 30°/s by seed 003's ``sweep`` strategy (a revolution every 12 s, so
every bearing is seen again well within the map's memory), with no background scan:
the learning map (``preprocess.learning``) holds all the static world it knows.  The
map's own memory (``LearningBackground.nbytes``) is sampled after every frame; its
peak is the figure the issue bounds (200 MB over 10 minutes).
"""

from __future__ import annotations

import math
import resource
import time

import numpy as np

from dronetrack.config.pipeline import FieldOfRegardConfig
from dronetrack.config.scenarios import get_scenario
from dronetrack.jobs.run import run_seeds, turret_pipeline
from dronetrack.jobs.simulate import flight_config, place_at_start, resolve_run
from dronetrack.sim.build import build_world
from dronetrack.sim.rig import SimSource, SimTurret

__all__ = ["MAP_S", "SWEEP_DEG_S", "learning_map"]

MAP_S = 600.0  # ten minutes
SWEEP_DEG_S = 30.0


def learning_map(seconds: float = MAP_S, seed: int = 0) -> dict[str, float]:
    """Run the all-round sweep for ``seconds``; the learning map's peak and final memory
    [MB], its voxels with a history and in the map at their peak, the process's peak
    resident memory [MB], the pipeline step's median and 99th percentile [ms] and the
    wall time [s]."""
    cfg = get_scenario("default")
    p = cfg.pipeline
    pipeline = p.model_copy(
        update={
            "controller": p.controller.model_copy(
                update={
                    "mode": "sweep",
                    "sweep_pan_deg": (-180.0, 180.0),
                    "sweep_rate_deg_s": SWEEP_DEG_S,
                }
            ),
            "field_of_regard": FieldOfRegardConfig(pan_deg=(-180.0, 180.0)),
            "background": p.background.model_copy(update={"scan_s": 0.0, "learn": True}),
        }
    )
    cfg = resolve_run(
        cfg.model_copy(update={"duration_s": seconds, "seed": seed, "pipeline": pipeline})
    )
    sim_seed, filter_seed = run_seeds(cfg.seed)
    world = build_world(flight_config(cfg), np.random.default_rng(sim_seed))
    period = cfg.sensor.integration_time_s
    pipe = turret_pipeline(cfg, period, world.plant.spec, np.random.default_rng(filter_seed))
    learning = pipe.learning
    if learning is None:
        raise RuntimeError("the learning map is off in the bench's configuration")
    place_at_start(world, pipe, "sweep")
    turret = SimTurret(world)
    peak = voxels = learnt = 0
    steps: list[float] = []
    start = time.perf_counter()
    for sample in SimSource(world, max(1, math.ceil(seconds / period - 1e-9))):
        result = pipe.step(sample.frame)
        if result.command is not None:
            turret.command(result.command)
        steps.append(result.step_ms)
        peak = max(peak, learning.nbytes)
        voxels = max(voxels, learning.voxels)
        learnt = max(learnt, len(learning))
    ms = np.asarray(steps)
    return {
        "seconds": seconds,
        "peak_mb": peak / 1e6,
        "final_mb": learning.nbytes / 1e6,
        "voxels_peak": float(voxels),
        "learnt_peak": float(learnt),
        "rss_peak_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "step_median_ms": float(np.median(ms)),
        "step_p99_ms": float(np.percentile(ms, 99)),
        "wall_s": time.perf_counter() - start,
    }
