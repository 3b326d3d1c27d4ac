"""The pipeline on good and bad frames: it never crashes and never returns a NaN estimate."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from dronetrack.config import BackgroundConfig, PipelineConfig, TrackerConfig
from dronetrack.factory import build_pipeline
from dronetrack.geometry import make_pose
from dronetrack.pipeline import Pipeline
from dronetrack.sim.turret import make_turret
from dronetrack.types import Frame

TURRET = make_turret("widowx")


def _pipeline(scan_s: float = 0.0, particles: int = 2000) -> Pipeline:
    cfg = PipelineConfig(
        background=BackgroundConfig(
            enabled=scan_s > 0, scan_s=scan_s, resolution_m=0.5, lookup_depth=0
        ),
        tracker=TrackerConfig(
            particles=particles,
            cylinder_center_m=(30.0, 0.0, 5.0),
            cylinder_radius_m=5.0,
            cylinder_height_m=5.0,
        ),
    )
    return build_pipeline(
        cfg,
        0.1,
        TURRET.mount,
        (TURRET.pan.lower, TURRET.pan.upper),
        (TURRET.tilt.lower, TURRET.tilt.upper),
        np.random.default_rng(0),
    )


def _frame(stamp: float, points: np.ndarray) -> Frame:
    """A frame from a sensor at 1 m height looking along +x (sensor frame = world − (0, 0, 1))."""
    n = len(points)
    pose = make_pose(np.eye(3), [0.0, 0.0, 1.0])
    return Frame(
        stamp,
        0.1,
        points - np.array([0.0, 0.0, 1.0]),
        np.full(n, stamp + 0.05),
        np.zeros(n, np.uint8),
        np.zeros(n, np.float32),
        np.array([stamp, stamp + 0.1]),
        np.stack([pose, pose]),
    )


def _drone(g: np.random.Generator, at: tuple[float, float, float] = (30.0, 0.0, 6.0)) -> np.ndarray:
    return np.array(at) + g.normal(0.0, 0.05, (6, 3))


def test_tracks_a_drone_and_commands_the_turret() -> None:
    g = np.random.default_rng(1)
    pipe = _pipeline()
    for k in range(20):
        result = pipe.step(_frame(0.1 * k, _drone(g)))
    assert result.estimate is not None
    assert result.estimate.tracked
    np.testing.assert_allclose(result.estimate.position, [30.0, 0.0, 6.0], atol=0.2)
    assert result.command is not None
    assert result.command.stamp == pytest.approx(result.t + 0.014)
    assert result.n_points == 6


def test_background_is_scanned_then_subtracted() -> None:
    g = np.random.default_rng(2)
    wall = np.column_stack([np.full(500, 40.0), g.uniform(-10, 10, 500), g.uniform(1, 9, 500)])
    pipe = _pipeline(scan_s=1.0)
    phases = []
    for k in range(10):
        phases.append(pipe.step(_frame(0.1 * k, wall)).phase)
    assert phases == ["scan"] * 10
    assert not pipe.scanning
    result = pipe.step(_frame(1.0, np.vstack([wall, _drone(g)])))
    assert result.phase == "track"
    assert result.n_points == 6  # the wall is gone, the drone is left


@pytest.mark.parametrize(
    ("make", "flag"),
    [
        (lambda g: np.empty((0, 3)), "empty"),
        (lambda g: np.full((5, 3), np.nan), "nonfinite_points"),
        (lambda g: np.vstack([_drone(g), [[np.inf, 0.0, 0.0]]]), "nonfinite_points"),
    ],
)
def test_bad_points_are_counted_and_survived(make, flag: str) -> None:  # type: ignore[no-untyped-def]
    g = np.random.default_rng(3)
    pipe = _pipeline()
    for k in range(10):
        pipe.step(_frame(0.1 * k, _drone(g)))
    result = pipe.step(_frame(1.0, make(g)))
    assert flag in result.flags
    assert pipe.counts[flag] == 1
    assert result.estimate is not None
    assert np.all(np.isfinite(result.estimate.position))


def test_frames_out_of_order_repeated_and_after_gaps() -> None:
    g = np.random.default_rng(4)
    pipe = _pipeline()
    for k in range(10):
        pipe.step(_frame(0.1 * k, _drone(g)))
    repeated = pipe.step(_frame(0.9, _drone(g)))
    assert "repeated" in repeated.flags
    assert repeated.command is None
    older = pipe.step(_frame(0.5, _drone(g)))
    assert "out_of_order" in older.flags
    # A 1 s gap: the filter predicts through it (10 periods) and carries on.
    after_gap = pipe.step(_frame(1.9, _drone(g)))
    assert "gap" in after_gap.flags
    for result in (repeated, older, after_gap):
        assert result.estimate is not None
        assert np.all(np.isfinite(result.estimate.position))
    assert after_gap.estimate is not None
    np.testing.assert_allclose(after_gap.estimate.position, [30.0, 0.0, 6.0], atol=0.5)
    assert (pipe.counts["repeated"], pipe.counts["out_of_order"], pipe.counts["gap"]) == (1, 1, 1)


def test_bad_time_and_bad_poses() -> None:
    g = np.random.default_rng(5)
    pipe = _pipeline()
    pipe.step(_frame(0.0, _drone(g)))
    nan_time = replace(_frame(0.1, _drone(g)), stamp=math.nan)
    assert "bad_time" in pipe.step(nan_time).flags
    frame = _frame(0.2, _drone(g))
    bad_pose = replace(frame, pose_t=np.array([0.3, 0.3]))  # pose times must increase
    result = pipe.step(bad_pose)
    assert "bad_pose" in result.flags
    assert result.estimate is not None
    assert np.all(np.isfinite(result.estimate.position))
