"""The fused foreground extraction against the stage-by-stage reference; outlier filters."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.geometry.transforms import make_pose, rot_y, rot_z
from dronetrack.preprocess.background import VoxelBackground
from dronetrack.preprocess.crop import box_mask, finite_mask
from dronetrack.preprocess.foreground import extract_foreground
from dronetrack.preprocess.outliers import radius_outlier_mask, statistical_outlier_mask
from dronetrack.types import Frame


def _frame(g: np.random.Generator, n: int = 3000, nan_rows: int = 20) -> Frame:
    """A frame whose sensor turns during the integration, with some NaN rows."""
    pose_t = np.linspace(0.0, 0.1, 11)
    poses = make_pose(
        rot_z(np.linspace(0.0, 0.4, 11)) @ rot_y(np.linspace(0.1, -0.1, 11)),
        np.column_stack([np.zeros(11), np.zeros(11), np.linspace(1.0, 1.1, 11)]),
    )
    points = g.uniform([-5, -30, -5], [60, 30, 20], (n, 3))
    points[g.choice(n, nan_rows, replace=False), g.integers(0, 3, nan_rows)] = np.nan
    return Frame(
        0.0,
        0.1,
        points,
        np.sort(g.uniform(0, 0.1, n)),
        np.zeros(n, np.uint8),
        np.zeros(n, np.float32),
        pose_t,
        poses,
    )


@settings(max_examples=15)
@given(st.integers(0, 2**32 - 1), st.sampled_from([0.0, 0.5, 1.0]), st.integers(0, 2))
def test_fused_extraction_equals_the_stages(seed: int, resolution: float, depth: int) -> None:
    g = np.random.default_rng(seed)
    frame = _frame(g)
    lo, hi = np.array([1.0, -20.0, 0.5]), np.array([50.0, 20.0, 15.0])
    bg = None
    if resolution > 0:
        bg = VoxelBackground(resolution, inflate=1, lookup_depth=depth)
        bg.insert(g.uniform([0, -25, 0], [55, 25, 16], (400, 3)))
        bg.build()
    fg = extract_foreground(frame, lo, hi, bg)
    world = frame.world_points()
    keep = finite_mask(world) & box_mask(world, lo, hi)
    if bg is not None:
        keep[keep] &= ~bg.is_background(world[keep])
    np.testing.assert_array_equal(fg.index, np.flatnonzero(keep))
    np.testing.assert_allclose(fg.points, world[keep], rtol=0, atol=1e-9)
    finite = finite_mask(world)
    assert fg.n_nonfinite == int((~finite).sum())
    assert fg.n_outside == int((finite & ~box_mask(world, lo, hi)).sum())
    assert len(fg.index) + fg.n_nonfinite + fg.n_outside + fg.n_background == len(frame)


def test_radius_outlier_removal() -> None:
    cluster = np.random.default_rng(0).normal([10, 0, 5], 0.05, (20, 3))
    lonely = np.array([[30.0, 0.0, 5.0], [10.0, 8.0, 5.0]])
    keep = radius_outlier_mask(np.vstack([cluster, lonely]), radius=0.5, min_neighbors=3)
    np.testing.assert_array_equal(keep, [True] * 20 + [False, False])
    assert radius_outlier_mask(np.empty((0, 3)), 1.0, 2).shape == (0,)


def test_statistical_outlier_removal() -> None:
    cluster = np.random.default_rng(1).normal([0, 0, 0], 0.1, (50, 3))
    far = np.array([[5.0, 5.0, 5.0]])
    keep = statistical_outlier_mask(np.vstack([cluster, far]), k=4, std_mul=1.0)
    assert not keep[-1]
    assert keep[:-1].mean() > 0.8
    # Fewer points than neighbours: nothing to judge, keep all.
    assert statistical_outlier_mask(far, k=4, std_mul=1.0).all()
