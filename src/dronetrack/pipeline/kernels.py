"""The numba kernels, compiled (or loaded from numba's cache) before a timed loop.

numba compiles a kernel the first time it is called with new argument types and
caches the machine code on disk (``cache=True``).  On a fresh install the first
run would otherwise pay 10-40 s of compilation inside its first tracking frames,
and report it as step time and as a slow real-time factor.  ``warm_up`` calls
every kernel a run needs on a few synthetic points, with the argument types the
pipeline uses, before the clock starts.  Once the cache holds them, a warm-up
costs well under a second (loading), and nothing compiles again.

The warm-up steps never touch a run's own objects or random streams: they build
throwaway filters, maps and frames (``SimWorld.warm_up`` a throwaway turret and
LiDAR), so a seeded run gives the same numbers with or without one.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = [
    "PIPELINE_WARM_UPS",
    "CompileProgress",
    "KernelWarmUp",
    "WarmUpStep",
    "compiled_signatures",
    "dispatchers",
    "synthetic_frame",
    "warm_up",
]

# (steps done, steps in all, whether any kernel was compiled rather than loaded so far)
CompileProgress = Callable[[int, int, bool], None]
WarmUpStep = Callable[[], object]


@dataclass(frozen=True, slots=True)
class KernelWarmUp:
    """What a warm-up did: its wall time [s] and the kernel signatures it compiled
    (0 when numba's cache held them all)."""

    seconds: float
    compiled: int


def dispatchers() -> Iterator[Any]:
    """Every numba dispatcher defined in a loaded ``dronetrack`` module."""
    from numba.core.registry import CPUDispatcher

    for name, module in list(sys.modules.items()):
        if name != "dronetrack" and not name.startswith("dronetrack."):
            continue
        for value in list(vars(module).values()):
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == name:
                yield value


def compiled_signatures() -> dict[str, int]:
    """Signatures each loaded kernel holds (compiled or loaded from the cache), by name."""
    return {f"{d.py_func.__module__}.{d.__name__}": len(d.signatures) for d in dispatchers()}


def _cache_misses() -> int:
    return sum(sum(d.stats.cache_misses.values()) for d in dispatchers())


def _poses(n: int, step: float) -> tuple[np.ndarray, np.ndarray]:
    """n pose samples 0.05 s apart, turning ``step`` rad about z and moving 0.1 m each."""
    t = 0.05 * np.arange(n, dtype=np.float64)
    T = np.tile(np.eye(4), (n, 1, 1))
    angle = step * np.arange(n)
    T[:, 0, 0] = T[:, 1, 1] = np.cos(angle)
    T[:, 1, 0] = np.sin(angle)
    T[:, 0, 1] = -T[:, 1, 0]
    T[:, 0, 3] = 0.1 * np.arange(n)
    return t, T


def synthetic_frame(n_points: int = 12) -> Any:
    """A frame of ``n_points`` returns about 10 m out, over three sensor poses."""
    from dronetrack.types import Frame

    rng = np.random.default_rng(0)
    pose_t, poses = _poses(3, 0.01)
    return Frame(
        stamp=0.0,
        duration=0.1,
        points=np.column_stack([np.full(n_points, 10.0), rng.normal(0.0, 1.0, (n_points, 2))]),
        t=np.linspace(0.0, 0.1, n_points),
        line=np.zeros(n_points, dtype=np.uint8),
        intensity=np.zeros(n_points, dtype=np.float32),
        pose_t=pose_t,
        poses=poses,
    )


def _geometry() -> None:
    """Pose checks, pose interpolation and the per-point transform."""
    from dronetrack.geometry.transforms import apply_interpolated_poses, transform_at_times

    pose_t, poses = _poses(3, 0.01)
    t = np.array([0.0, 0.04, 0.09])
    transform_at_times(pose_t, poses, t, np.ones((3, 3)))
    apply_interpolated_poses(pose_t, poses, t, np.ones((3, 3)), np.ones((3, 3)))


def _foreground() -> None:
    """The background map (its hash table and dense grid), the one-pass foreground,
    and the ball and the scan's range image around a locked target."""
    from dronetrack.preprocess.background import VoxelBackground
    from dronetrack.preprocess.crop import ball_mask
    from dronetrack.preprocess.foreground import extract_foreground
    from dronetrack.preprocess.range_image import RangeImage

    frame = synthetic_frame()
    lo, hi = np.array([-50.0, -50.0, -50.0]), np.array([50.0, 50.0, 50.0])
    background = VoxelBackground(1.0, inflate=1, lookup_depth=1)
    background.insert(frame.world_points()[:4])
    background.build()
    extract_foreground(frame, lo, hi, background)
    fg = extract_foreground(frame, lo, hi, None)
    background.is_background(frame.points)
    ball_mask(fg.world, np.zeros(3), 1.0)
    ranges = RangeImage(np.zeros(3))
    ranges.insert(fg.world)
    ranges.build()
    ranges.in_front(fg.world, 1.0)


def _particle_filters() -> None:
    """Every motion model with every resampler: predict, update, estimate."""
    from dronetrack.track.particle import NoiseParameters, ParticleFilter
    from dronetrack.track.resample import RESAMPLERS

    noise = NoiseParameters(0.5, 0.5, 0.1, 0.2, 0.1)
    points = synthetic_frame().points
    for model in ("delta", "cv", "ca"):
        for resampling in RESAMPLERS:
            pf = ParticleFilter(16, model, noise, np.random.default_rng(0), resampling)
            pf.reset(points[0], 1.0, 1.0)
            pf.predict()
            pf.update(points)
            pf.estimate()
            pf.variance()


def _detection() -> None:
    """The detect stage's clustering."""
    from dronetrack.detect.clusters import cluster_statistics, dbscan

    points = synthetic_frame().points
    cluster_statistics(points, dbscan(points, 1.0, 1))


def _object_tracks() -> None:
    """Every object's track: the filter bank's predict, gates and update."""
    from dronetrack.track.cv_bank import cv_predict, cv_update, gate_costs

    x, P = np.zeros((1, 6)), np.eye(6)[None]
    x, P = cv_predict(x, P, np.array([0.1]), 1.0)
    cost = gate_costs(x, P, x[:, :3], np.array([1.0]), np.zeros((1, 3)), np.eye(3)[None], 10.0)
    cv_update(x, P, np.zeros((1, 3)), np.eye(3)[None] + cost[0, 0] * 0.0)


def _classes() -> None:
    """The classify stage's test of the column below each track (``propped``)."""
    from dronetrack.classify.observe import stands_on

    c = np.array([[10.0, 0.0, 5.0]])
    below = np.array([[10.0, 0.0, 4.0], [10.0, 3.0, 4.5]])
    stands_on(c, np.array([4.8]), np.array([11.0]), np.array([0.5]), below)


def _learning() -> None:
    """The learning background map: direction cells, looks and the sampled directions."""
    from dronetrack.preprocess.learning import LearningBackground, LearningSettings

    model = LearningBackground(LearningSettings(min_occupied_s=0.0), 0.1)
    pts = np.array([[10.0, 0.5, 0.5], [30.0, 1.0, 2.0]])
    none = np.empty((0, 3))
    for t in (0.0, 0.5):  # the second frame closes a window and looks at the first's voxels
        model.observe(t, pts, pts, np.eye(4), pts, none, np.empty(0))


# Smallest first: the first step tells within a second whether the cache is cold.
PIPELINE_WARM_UPS: tuple[WarmUpStep, ...] = (
    _geometry,
    _foreground,
    _particle_filters,
    _detection,
    _object_tracks,
    _classes,
    _learning,
)


def warm_up(steps: Sequence[WarmUpStep], progress: CompileProgress | None = None) -> KernelWarmUp:
    """Run each warm-up step, reporting after each; how long it took and how many kernel
    signatures had to be compiled."""
    begin = time.perf_counter()
    misses = _cache_misses()
    for i, step in enumerate(steps):
        step()
        if progress is not None:
            progress(i + 1, len(steps), _cache_misses() > misses)
    return KernelWarmUp(time.perf_counter() - begin, _cache_misses() - misses)
