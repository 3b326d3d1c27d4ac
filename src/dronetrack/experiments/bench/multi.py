"""The pipeline step with many objects in view, timed: ``multi_step_ms``.

The pipeline workload's 24,000-point Avia frame (``pipeline.worst_case_frames``: the
ground in the background map, a Phantom 4 hovering 2.5 m ahead and tracked) with
``OBJECTS`` more objects in front of it, each six returns (σ = 0.1 m) moving at up to
1 m/s, and ``CLUTTER`` single returns at random places in the air every frame
(``_in_the_air``).  With
single-return clusters allowed (the acquisition's default), a frame holds 51 clusters,
and the objects and the drone are 11 tracks, so every stage runs at the size the issue
names: at least 10 tracks and 50 candidates a frame.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from dronetrack.experiments.bench.pipeline import (
    PERIOD_S,
    PIPELINE_WARMUP,
    AviaFrames,
    scanned_pipeline,
    shifted,
    worst_case_frames,
)
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import Frame

__all__ = ["CLUTTER", "MULTI_PARTICLES", "MULTI_WARMUP", "OBJECTS", "multi_step_ms"]

OBJECTS = 10  # moving objects besides the drone: tracks
CLUTTER = 40  # single random returns a frame: clusters that never become tracks
MULTI_PARTICLES = 5000  # the outdoor preset's particle filter
MULTI_WARMUP = 20  # untimed steps: every object is a track after them


def _in_front(rng: np.random.Generator, n: int) -> FloatArray:
    """``n`` world points in the Avia's view 8-20 m ahead, 1-4 m up (the sensor looks
    40° down from 0.5 m; its 77° field spans about ±8 m across there)."""
    return rng.uniform([8.0, -6.0, 1.0], [20.0, 6.0, 4.0], size=(n, 3))


def _in_the_air(rng: np.random.Generator, n: int) -> FloatArray:
    """``n`` random returns anywhere in the outdoor crop box above 1 m (10-300 m out,
    ±200 m across, up to 100 m): clusters of one return that seldom pair into a
    confirmed candidate (one per 290,000 m³ at 40 a frame)."""
    return rng.uniform([10.0, -200.0, 1.0], [300.0, 200.0, 100.0], size=(n, 3))


def _with_points(frame: Frame, world: FloatArray) -> Frame:
    """``frame`` with ``world`` (M, 3) returns added, in its sensor frame at its end."""
    pose = frame.poses[-1]
    sensor = (world - pose[:3, 3]) @ pose[:3, :3]  # p_s = Rᵀ (p_w − o)
    m = len(world)
    return replace(
        frame,
        points=np.concatenate([frame.points, sensor]),
        t=np.concatenate([frame.t, np.full(m, frame.end)]),
        line=np.concatenate([frame.line, np.zeros(m, dtype=frame.line.dtype)]),
        intensity=np.concatenate([frame.intensity, np.full(m, 30.0, dtype=np.float32)]),
    )


def multi_step_ms(
    repeats: int, frames: AviaFrames | None = None, seed: int = 11
) -> tuple[FloatArray, int, int]:
    """Wall time [ms] of ``repeats`` pipeline steps with ``OBJECTS`` objects and
    ``CLUTTER`` clutter returns a frame, after ``MULTI_WARMUP`` untimed steps; and the
    fewest tracks and clusters of a timed frame.  RuntimeError if the workload is not
    what it claims (fewer than ``OBJECTS`` tracks, the drone not tracked)."""
    frames = worst_case_frames() if frames is None else frames
    pipe = scanned_pipeline(MULTI_PARTICLES, frames)
    rng = np.random.default_rng(seed)
    start = _in_front(rng, OBJECTS)
    velocity = rng.uniform(-1.0, 1.0, size=(OBJECTS, 3)) * np.array([1.0, 1.0, 0.2])
    blob = rng.normal(0.0, 0.1, size=(6, 3))
    out = np.empty(repeats)
    fewest_tracks = fewest_clusters = 1 << 30
    for k in range(repeats + MULTI_WARMUP + PIPELINE_WARMUP):
        base = shifted(frames.probe, PERIOD_S * k)
        objects = start + velocity * (PERIOD_S * k)
        world = np.concatenate(
            [(objects[:, None, :] + blob).reshape(-1, 3), _in_the_air(rng, CLUTTER)]
        )
        frame = _with_points(base, world)
        tic = time.perf_counter()
        result = pipe.step(frame)
        timed = k - MULTI_WARMUP - PIPELINE_WARMUP
        if timed >= 0:
            out[timed] = 1e3 * (time.perf_counter() - tic)
            fewest_tracks = min(fewest_tracks, len(result.tracks or ()))
            fewest_clusters = min(fewest_clusters, len(result.detections or ()))
    if fewest_tracks < OBJECTS or result.estimate is None or not result.estimate.tracked:
        raise RuntimeError(
            f"the many-objects benchmark is not what it claims: {fewest_tracks} tracks, "
            f"drone tracked: {result.estimate is not None and result.estimate.tracked}"
        )
    return out, fewest_tracks, fewest_clusters
