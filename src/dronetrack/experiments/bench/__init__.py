"""The benchmark suite: pipeline, tracker, simulator and replay speed, as data.

``bench`` runs every measurement and returns the dictionary that ``dronetrack
bench`` writes as ``bench.json``; the scripts in ``benchmarks/`` time single
parts with the same functions.  What is timed, and where:

- ``pf_step_ms`` (``pipeline``): one full pipeline step (world transform with
  per-point poses, crop, background lookup of every point, particle-filter
  predict, update and resample) on a 24,000-point Avia frame, at each of
  ``PF_PARTICLES``.  The Avia is tilted 40° down at open ground, so every pulse
  returns, and the crop box keeps the ground, so every point is looked up in the
  background (the worst case); a Phantom 4 hovers 2.5 m ahead and is tracked.
- ``tracker_step_ms`` (``pipeline``): ``Tracker.step(t, points, steps=1)`` of
  every tracker in ``TRACKER_NAMES`` (factory defaults: 5,000 particles,
  pf-systematic 2,000) on a synthetic foreground: 100 points (σ = 0.1 m) around a
  target 20 m ahead moving at a constant 0.5 m/s, one 0.1 s period per step,
  after ``TRACKER_WARMUP`` untimed steps that lock every filter.
- ``sim_frame_ms`` (``sim``): a full ``SimWorld.step()`` (turret motion, scan
  pattern, per-point poses, ray casting, detection and noise) per sensor, with
  the turret following the true target, in the outdoor scenarios of ``SIM_CASES``.
- ``replay_x_realtime`` (``replay``): ``run_replay`` of a worst-case 10 Hz Avia
  recording (every pulse returns, /tf at 100 Hz, the drone hovering 2.5 m ahead)
  with 5,000 particles, end to end: reading, decoding, /tf lookup, pipeline and
  the ground-truth bookkeeping; written both as ROS 1 with Livox CustomMsg and as
  ROS 2 MCAP with PointCloud2.  The figure is the slower format's.

The live chain (``live``, ``dronetrack bench --live``, bench_live.json) is timed
apart, in real time against ``dronetrack emulate`` in another process:

- ``live_latency``: p50 and p99 of the latency from a frame's last firing to its
  turret command, at the Avia's full 240,000 points/s with the Dynamixel turret on
  the emulated servos (target p99 ≤ 20 ms), frames dropped, packets lost;
- ``live_soak``: resident memory through a 10-minute live run, its growth after a
  60 s warm-up (target ≤ 5 %), with no packet lost and no frame dropped.

``suite`` runs them all, with the statistics and the speed targets; ``machine``
describes the machine and pins its thread pools.  Every measurement runs
``rounds`` times and keeps the round with the lowest median (replay: the fastest
round), as ``timeit`` does: on a shared virtual machine the neighbours only ever
add time.

This package never changes process-wide settings by itself; ``single_thread``
pins numba's and OpenBLAS's thread pools for the caller.
"""

from __future__ import annotations

from dronetrack.experiments.bench.live import live_bench, live_latency, live_soak
from dronetrack.experiments.bench.live_settings import (
    LATENCY_P99_TARGET_MS,
    LIVE_FULL,
    LIVE_QUICK,
    LIVE_TARGETS,
    RSS_GROWTH_TARGET_PCT,
    LiveRequest,
    LiveSettings,
    check_mode,
    live_request,
)
from dronetrack.experiments.bench.machine import (
    cpu_model,
    machine_info,
    single_thread,
    thread_counts,
)
from dronetrack.experiments.bench.memory import resident_mb, rss_growth_pct
from dronetrack.experiments.bench.pipeline import (
    PF_PARTICLES,
    AviaFrames,
    pipeline_step_ms,
    tracker_foreground,
    tracker_step_ms,
    worst_case_frames,
)
from dronetrack.experiments.bench.replay import (
    REPLAY_FORMATS,
    ReplayTiming,
    replay_config,
    time_replay,
    write_recording,
)
from dronetrack.experiments.bench.sim import SENSORS, SIM_CASES, sim_frame_ms
from dronetrack.experiments.bench.suite import (
    FULL,
    QUICK,
    STAT_KEYS,
    TARGETS,
    Settings,
    Target,
    bench,
    best_round,
    evaluate_targets,
    heavy_repeats,
    stats,
)

__all__ = [
    "FULL",
    "LATENCY_P99_TARGET_MS",
    "LIVE_FULL",
    "LIVE_QUICK",
    "LIVE_TARGETS",
    "PF_PARTICLES",
    "QUICK",
    "REPLAY_FORMATS",
    "RSS_GROWTH_TARGET_PCT",
    "SENSORS",
    "SIM_CASES",
    "STAT_KEYS",
    "TARGETS",
    "AviaFrames",
    "LiveRequest",
    "LiveSettings",
    "ReplayTiming",
    "Settings",
    "Target",
    "bench",
    "best_round",
    "check_mode",
    "cpu_model",
    "evaluate_targets",
    "heavy_repeats",
    "live_bench",
    "live_latency",
    "live_request",
    "live_soak",
    "machine_info",
    "pipeline_step_ms",
    "replay_config",
    "resident_mb",
    "rss_growth_pct",
    "sim_frame_ms",
    "single_thread",
    "stats",
    "thread_counts",
    "time_replay",
    "tracker_foreground",
    "tracker_step_ms",
    "worst_case_frames",
    "write_recording",
]
