"""The detect stage: CandidateDetector's Detections against statistics computed here."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from dronetrack.detect.candidates import (
    SEED002_DETECTOR,
    SEED003_DETECTOR,
    CandidateDetector,
    engulfed,
)
from dronetrack.errors import ConfigError, InputError
from dronetrack.types import Detections

NO_VOXELS = CandidateDetector(voxel_size=0.0)


def _blob(rng: np.random.Generator, center: tuple[float, float, float], n: int) -> np.ndarray:
    """n points within 0.15 m of ``center`` on each axis: one DBSCAN cluster at ε = 0.5 m."""
    return np.asarray(center) + rng.uniform(-0.15, 0.15, (n, 3))


def test_detections_hold_each_clusters_statistics_in_label_order() -> None:
    rng = np.random.default_rng(5)
    first, second = _blob(rng, (10.0, 0.0, 5.0), 12), _blob(rng, (20.0, 3.0, 8.0), 30)
    lone = np.array([[40.0, 0.0, 5.0]])  # noise: fewer than min_points = 3 within ε
    found = NO_VOXELS(np.vstack([first, lone, second]))
    assert len(found) == 2
    for i, pts in enumerate((first, second)):
        np.testing.assert_allclose(found.centroids[i], pts.mean(axis=0), rtol=0, atol=1e-12)
        np.testing.assert_allclose(
            found.covariances[i], np.cov(pts.T, bias=True), rtol=0, atol=1e-12
        )
        # Extents: the span of the points along the principal axes (the right singular
        # vectors of the centred points, largest singular value first).
        centred = pts - pts.mean(axis=0)
        axes = np.linalg.svd(centred, full_matrices=False)[2]
        np.testing.assert_allclose(found.extents[i], np.ptp(centred @ axes.T, axis=0), atol=1e-9)
        assert 0.0 <= found.planarity[i] <= 1.0
    np.testing.assert_array_equal(found.counts, [12, 30])
    assert found.largest() == 1


def test_the_largest_is_the_first_of_equal_counts_and_needs_a_candidate() -> None:
    rng = np.random.default_rng(6)
    found = NO_VOXELS(np.vstack([_blob(rng, (5.0, 0.0, 2.0), 8), _blob(rng, (9.0, 0.0, 2.0), 8)]))
    assert found.largest() == 0
    with pytest.raises(InputError, match="no detections"):
        Detections.empty().largest()


def test_nothing_found_is_empty_arrays_of_the_right_shapes() -> None:
    for points in (np.zeros((0, 3)), np.array([[1.0, 2.0, 3.0]])):  # nothing, and noise
        found = SEED002_DETECTOR(points)
        assert len(found) == 0
        assert found.centroids.shape == (0, 3)
        assert found.counts.shape == (0,)
        assert found.extents.shape == (0, 3)
        assert found.covariances.shape == (0, 3, 3)
        assert found.planarity.shape == (0,)


def test_detections_are_read_only_and_checked() -> None:
    rng = np.random.default_rng(7)
    found = NO_VOXELS(_blob(rng, (5.0, 0.0, 2.0), 10))
    with pytest.raises(ValueError, match="read-only"):
        found.centroids[0, 0] = 0.0
    with pytest.raises(InputError, match="shape"):
        Detections(
            np.zeros((2, 3)), np.zeros(1), np.zeros((2, 3)), np.zeros((2, 3, 3)), np.zeros(2)
        )


def test_the_size_check_and_the_roi_drop_candidates() -> None:
    rng = np.random.default_rng(8)
    # A 3 m rod, 0.1 m apart: one cluster, longer than a drone (2 m).
    rod = np.column_stack([np.linspace(10.0, 13.0, 31), np.zeros(31), np.full(31, 5.0)])
    drone = _blob(rng, (30.0, 0.0, 5.0), 10)
    points = np.vstack([rod, drone])
    assert len(NO_VOXELS(points)) == 1
    assert len(CandidateDetector(voxel_size=0.0, max_extent=math.inf)(points)) == 2
    # A cylinder of 20 m around the origin keeps the rod only; z ∈ (0, 4) neither.
    roi = CandidateDetector(voxel_size=0.0, max_extent=math.inf, roi_radius=20.0)
    np.testing.assert_allclose(roi(points).centroids, [rod.mean(axis=0)], atol=1e-12)
    assert len(CandidateDetector(voxel_size=0.0, z_min=0.0, z_max=4.0)(points)) == 0


def test_the_presets_differ_as_their_seeds_say() -> None:
    single = np.array([[15.0, 0.0, 4.0]])
    # Seed 003 reacts to a single return; seed 002's DBSCAN needs 3 points.
    np.testing.assert_array_equal(SEED003_DETECTOR(single).centroids, single)
    assert len(SEED002_DETECTOR(single)) == 0


@pytest.mark.parametrize(
    "kwargs", [{"eps": 0.0}, {"min_points": 0}, {"voxel_size": -0.1}, {"z_min": 2.0, "z_max": 1.0}]
)
def test_bad_settings_are_config_errors(kwargs: dict[str, float]) -> None:
    with pytest.raises(ConfigError):
        CandidateDetector(**kwargs)  # type: ignore[arg-type]


def test_the_detect_stage_does_not_import_the_trackers() -> None:
    code = (
        "import sys, dronetrack.detect.candidates; "
        "print(sorted(m for m in sys.modules if m.startswith('dronetrack.track')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_the_points_of_a_cluster_too_large_for_a_candidate_are_kept_as_oversized() -> None:
    """A drone-sized blob is a candidate; a 3 m pole's column of returns (one DBSCAN
    cluster at ε = 0.5 m, 0.2 m apart) is larger than ``max_extent`` (2 m): no
    candidate, its points exactly ``oversized``; a lone return is neither."""
    rng = np.random.default_rng(3)
    blob = _blob(rng, (10.0, 0.0, 5.0), 12)
    pole = np.column_stack([np.full(16, 30.0), np.zeros(16), np.arange(16) * 0.2])
    lone = np.array([[50.0, 0.0, 5.0]])
    found = NO_VOXELS(np.vstack([pole, blob, lone]))
    assert len(found) == 1
    np.testing.assert_allclose(found.centroids[0], blob.mean(axis=0), atol=1e-12)
    np.testing.assert_array_equal(found.oversized, pole)
    alone = NO_VOXELS(pole)  # no candidate at all: the pole's points still kept
    assert len(alone) == 0
    np.testing.assert_array_equal(alone.oversized, pole)
    assert NO_VOXELS(blob).oversized.shape == (0, 3)
    # with no size limit nothing is oversized
    assert len(SEED003_DETECTOR(pole).oversized) == 0


@settings(max_examples=60, deadline=None)
@given(
    points=hnp.arrays(
        np.float64, st.tuples(st.integers(0, 30), st.just(3)), elements=st.floats(-5, 5)
    ),
    positions=hnp.arrays(
        np.float64, st.tuples(st.integers(0, 6), st.just(3)), elements=st.floats(-6, 6)
    ),
    radius=st.floats(0.05, 3.0),
)
def test_a_place_is_engulfed_where_an_oversized_point_lies_within_the_radius(
    points: np.ndarray, positions: np.ndarray, radius: float
) -> None:
    """``engulfed`` against the brute-force least distance (points exactly at the
    radius are left out: the k-d tree and the norm may round either way)."""
    found = Detections.empty(points)
    got = engulfed(found, positions, radius)
    assert got.shape == (len(positions),)
    if len(points) == 0:
        assert not got.any()
        return
    d = np.linalg.norm(positions[:, None, :] - points[None, :, :], axis=2).min(axis=1)
    clear = np.abs(d - radius) > 1e-9
    np.testing.assert_array_equal(got[clear], (d <= radius)[clear])
