"""Clustering: DBSCAN against a textbook reference, cluster statistics, voxel grid, ROI."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.detect.clusters import (
    cluster_features,
    cluster_features_reference,
    connected_components,
    cylinder_mask,
    dbscan,
    voxel_centroids,
)


def _reference_dbscan(P: np.ndarray, eps: float, min_points: int) -> np.ndarray:
    """Ester et al.'s DBSCAN by breadth-first expansion over an O(n²) distance matrix."""
    n = len(P)
    d = np.linalg.norm(P[:, None, :] - P[None, :, :], axis=2)
    neighbours = [np.flatnonzero(d[i] <= eps) for i in range(n)]
    core = np.array([len(nb) >= min_points for nb in neighbours], dtype=bool)
    labels = np.full(n, -1)
    k = 0
    for i in range(n):
        if not core[i] or labels[i] != -1:
            continue
        labels[i] = k
        queue = [i]
        while queue:
            j = queue.pop()
            for m in neighbours[j]:
                if labels[m] == -1:
                    labels[m] = k
                    if core[m]:
                        queue.append(m)
        k += 1
    return labels


def _same_partition(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> bool:
    """Labels a and b split the points in ``mask`` the same way (up to renaming)."""
    pairs = {(int(x), int(y)) for x, y in zip(a[mask], b[mask], strict=True)}
    return len(pairs) == len({x for x, _ in pairs}) == len({y for _, y in pairs})


def _blobs(rng: np.random.Generator, n_blobs: int, n_noise: int) -> np.ndarray:
    centres = rng.uniform(-20, 20, size=(n_blobs, 3))
    parts = [c + 0.2 * rng.standard_normal((rng.integers(2, 30), 3)) for c in centres]
    parts.append(rng.uniform(-25, 25, size=(n_noise, 3)))
    return np.concatenate(parts)


@settings(max_examples=60, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    eps=st.floats(0.2, 1.5),
    min_points=st.integers(1, 6),
)
def test_dbscan_matches_the_textbook_algorithm(seed: int, eps: float, min_points: int) -> None:
    rng = np.random.default_rng(seed)
    P = _blobs(rng, int(rng.integers(0, 6)), int(rng.integers(0, 40)))
    ours = dbscan(P, eps, min_points)
    ref = _reference_dbscan(P, eps, min_points)
    d = np.linalg.norm(P[:, None, :] - P[None, :, :], axis=2)
    core = (d <= eps).sum(axis=1) >= min_points
    # Core points: the same clusters.  Noise: the same points.
    assert _same_partition(ours, ref, core)
    np.testing.assert_array_equal(ours == -1, ref == -1)
    # A border point sits in a cluster of some core point within ε (which one is
    # order-dependent in the textbook algorithm; ours takes the lowest label).
    for i in np.flatnonzero(~core & (ours >= 0)):
        near_core = np.flatnonzero(core & (d[i] <= eps))
        assert ours[i] == ours[near_core].min()
    # Labels run 0..k−1 in order of first appearance.
    seen = ours[ours >= 0]
    if len(seen):
        first = [int(x) for x in dict.fromkeys(seen.tolist())]
        assert first == list(range(len(first)))


def test_dbscan_separates_two_drones_from_noise() -> None:
    rng = np.random.default_rng(3)
    a = np.array([30.0, 0.0, 10.0]) + 0.1 * rng.standard_normal((12, 3))
    b = np.array([30.0, 3.0, 10.0]) + 0.1 * rng.standard_normal((8, 3))
    stray = np.array([[10.0, 10.0, 5.0], [50.0, -5.0, 20.0]])
    labels = dbscan(np.concatenate([a, b, stray]), eps=0.5, min_points=3)
    np.testing.assert_array_equal(labels, [0] * 12 + [1] * 8 + [-1, -1])


def test_dbscan_of_nothing_and_of_lone_points() -> None:
    assert len(dbscan(np.empty((0, 3)), 0.5, 3)) == 0
    np.testing.assert_array_equal(dbscan(np.eye(3) * 10, 0.5, 2), [-1, -1, -1])


def test_cluster_features_of_a_known_box() -> None:
    # The 8 corners of a 2 × 1 × 0.5 box, rotated: extents along the principal axes.
    corners = np.array([[x, y, z] for x in (0, 2) for y in (0, 1) for z in (0, 0.5)], float)
    c, s = np.cos(0.7), np.sin(0.7)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])
    P = corners @ R.T + [5, 6, 7]
    (box,) = cluster_features(P, np.zeros(8, dtype=np.int64))
    np.testing.assert_allclose(box.centroid, R @ [1, 0.5, 0.25] + [5, 6, 7])
    np.testing.assert_allclose(box.extent, [2, 1, 0.5], atol=1e-12)
    # Population variances of ±a/2 corners are (a/2)²: 1, 0.25, 0.0625.
    lam = np.linalg.eigvalsh(box.covariance)[::-1]
    np.testing.assert_allclose(lam, [1, 0.25, 0.0625], atol=1e-12)
    assert box.planarity == pytest.approx((0.25 - 0.0625) / 1)
    assert box.n == 8


def test_cluster_features_skip_noise_and_keep_label_order() -> None:
    P = np.array([[0, 0, 0], [9, 9, 9], [1, 0, 0], [5, 5, 5]], float)
    out = cluster_features(P, np.array([1, -1, 1, 0]))
    assert [c.n for c in out] == [1, 2]
    np.testing.assert_allclose(out[1].centroid, [0.5, 0, 0])
    assert out[0].planarity == 0.0
    assert cluster_features(P, np.full(4, -1)) == []


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), size=st.floats(0.05, 2.0))
def test_voxel_centroids_are_voxel_means(seed: int, size: float) -> None:
    rng = np.random.default_rng(seed)
    P = rng.uniform(-3, 3, size=(int(rng.integers(1, 200)), 3))
    out = voxel_centroids(P, size)
    keys = np.floor(P / size)
    expected = {
        tuple(k): P[np.all(keys == k, axis=1)].mean(axis=0) for k in np.unique(keys, axis=0)
    }
    assert len(out) == len(expected)
    for centroid in out:
        # Each centroid lies in the voxel whose mean it is.
        got = expected[tuple(np.floor(centroid / size))]
        np.testing.assert_allclose(centroid, got, atol=1e-12)


def test_cylinder_mask_bounds() -> None:
    P = np.array([[3, 4, 2], [3, 4.1, 2], [0, 0, 0.5], [0, 0, 5], [1, 1, 4.99], [0, 0, 1.0]], float)
    mask = cylinder_mask(P, (0.0, 0.0), radius=5.0, z_min=1.0, z_max=5.0)
    np.testing.assert_array_equal(mask, [False, False, False, False, True, False])
    np.testing.assert_array_equal(
        cylinder_mask(P + np.array([10.0, 0.0, 0.0]), (10.0, 0.0), 5.0, 1.0, 5.0), mask
    )


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 60), st.integers(0, 2**32 - 1), st.integers(0, 120))
def test_components_partition_as_scipys(n: int, seed: int, m: int) -> None:
    """The same partition as scipy.sparse.csgraph, each labelled by its smallest node."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components as scipy_components

    edges = np.random.default_rng(seed).integers(0, n, (m, 2)).astype(np.int64)
    ours = connected_components(n, edges)
    graph = coo_matrix((np.ones(m), (edges[:, 0], edges[:, 1])), shape=(n, n))
    _, theirs = scipy_components(graph, directed=False)
    # same partition: equal labels exactly where scipy's are equal
    np.testing.assert_array_equal(
        ours[:, None] == ours[None, :], theirs[:, None] == theirs[None, :]
    )
    for label in np.unique(ours):
        assert label == np.flatnonzero(ours == label).min()


def test_a_single_return_is_a_cluster_without_spread() -> None:
    """The shortcut for one point gives what the general formulas give."""
    pts = np.array([[3.0, -2.0, 7.5]])
    (one,) = cluster_features(pts, np.array([0]))
    np.testing.assert_array_equal(one.centroid, pts[0])
    np.testing.assert_array_equal(one.covariance, np.zeros((3, 3)))
    np.testing.assert_array_equal(one.extent, np.zeros(3))
    assert (one.planarity, one.n) == (0.0, 1)
    # two coincident returns take the general path: the same statistics
    (two,) = cluster_features(np.vstack([pts, pts]), np.array([0, 0]))
    np.testing.assert_array_equal(two.centroid, one.centroid)
    np.testing.assert_array_equal(two.covariance, one.covariance)
    np.testing.assert_array_equal(two.extent, one.extent)
    assert two.planarity == one.planarity


@settings(max_examples=60, deadline=None)
@given(st.integers(0, 2**31 - 1), st.integers(1, 12), st.integers(0, 40))
def test_batched_statistics_equal_the_per_cluster_definition(seed: int, k: int, extra: int) -> None:
    """All clusters at once (compiled moments, batched eigh) give each cluster's own
    statistics: clusters of 1 to 1 + extra points, anisotropic, with noise labels."""
    rng = np.random.default_rng(seed)
    sizes = 1 + rng.integers(0, extra + 1, k)
    pts = np.concatenate(
        [
            rng.uniform(-100, 100, 3) + rng.normal(0.0, rng.uniform(0.01, 1.0, 3), (m, 3))
            for m in sizes
        ]
    )
    labels = np.repeat(np.arange(k), sizes)
    labels[rng.random(len(labels)) < 0.1] = -1  # some noise
    order = rng.permutation(len(labels))
    pts, labels = pts[order], labels[order]
    kept = labels >= 0
    labels[kept] = np.unique(labels[kept], return_inverse=True)[1]  # 0..k'−1, no gaps
    got = cluster_features(pts, labels)
    want = cluster_features_reference(pts, labels)
    assert len(got) == len(want)
    for g, w in zip(got, want, strict=True):
        assert g.n == w.n
        np.testing.assert_allclose(g.centroid, w.centroid, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(g.covariance, w.covariance, rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(g.extent, w.extent, rtol=1e-9, atol=1e-9)
        assert g.planarity == pytest.approx(w.planarity, rel=1e-6, abs=1e-9)
