"""Voxel keys, the key set and the background model."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from dronetrack.errors import InputError
from dronetrack.preprocess import voxel
from dronetrack.preprocess.background import (
    NEAR_ANGLE,
    VoxelBackground,
    aloft_objects,
    free_objects,
    lookup_level,
    single_hits,
)
from dronetrack.preprocess.voxel import (
    KeySet,
    coarsen_keys,
    dilate_keys,
    neighbour_counts,
    shifted_keys,
    unique_keys,
    voxel_keys,
)

coords = arrays(np.float64, (40, 3), elements=st.floats(-500, 500))


@given(coords, st.sampled_from([0.1, 0.25, 1.0, 4.0]))
def test_keys_identify_voxels(points: np.ndarray, size: float) -> None:
    keys = voxel_keys(points, size)
    idx = np.floor(points / size).astype(np.int64)
    # Same key exactly when same voxel.
    same_key = keys[:, None] == keys[None, :]
    same_voxel = np.all(idx[:, None, :] == idx[None, :, :], axis=2)
    np.testing.assert_array_equal(same_key, same_voxel)


def test_dilation_and_coarsening() -> None:
    one = voxel_keys(np.array([[0.5, 0.5, 0.5]]), 1.0)
    assert len(dilate_keys(one, 1)) == 27
    assert len(dilate_keys(one, 2)) == 125
    # Voxel indices -1 and 0..3 fall in coarse cells -1 and 0 two levels up (4 m).
    fine = voxel_keys(np.array([[-0.5, 0, 0], [0.5, 0, 0], [3.9, 0, 0]]), 1.0)
    coarse = coarsen_keys(fine, 2)
    np.testing.assert_array_equal(
        coarse, unique_keys(voxel_keys(np.array([[-3.9, 0, 0], [1.0, 0, 0]]), 4.0))
    )


@settings(max_examples=30)
@given(arrays(np.int64, 60, elements=st.integers(-50, 50)), st.booleans())
def test_key_set_membership_matches_isin(values: np.ndarray, dense: bool) -> None:
    pts = np.column_stack([values, np.roll(values, 1), np.roll(values, 2)]).astype(np.float64) + 0.5
    stored = voxel_keys(pts[:30], 1.0)
    probe = voxel_keys(pts, 1.0)
    limit = voxel.DENSE_MAX_CELLS
    try:
        voxel.DENSE_MAX_CELLS = limit if dense else 0
        ks = KeySet.of(stored)
        assert (ks.grid.size > 0) == dense
        np.testing.assert_array_equal(ks.contains(probe), np.isin(probe, stored))
    finally:
        voxel.DENSE_MAX_CELLS = limit


def _wall(n: int = 5000) -> np.ndarray:
    g = np.random.default_rng(0)
    return np.column_stack([np.full(n, 20.0), g.uniform(-10, 10, n), g.uniform(0, 8, n)])


def test_background_subtracts_the_scanned_scene_and_keeps_the_rest() -> None:
    bg = VoxelBackground(resolution=0.5, inflate=1, lookup_depth=0)
    bg.insert(_wall())
    bg.build()
    near_wall = np.array([[20.3, 0.0, 4.0], [19.6, 5.0, 1.0]])  # within the inflation
    free = np.array([[15.0, 0.0, 4.0], [20.0, 30.0, 4.0], [np.nan, 0.0, 0.0]])
    np.testing.assert_array_equal(bg.is_background(near_wall), [True, True])
    np.testing.assert_array_equal(bg.is_background(free), [False, False, False])


def test_min_hits_drops_sparse_voxels() -> None:
    bg = VoxelBackground(resolution=1.0, inflate=0, min_hits=3)
    bg.insert(np.array([[0.5, 0.5, 0.5]] * 3 + [[5.5, 0.5, 0.5]] * 2))
    bg.build()
    np.testing.assert_array_equal(
        bg.is_background(np.array([[0.2, 0.2, 0.2], [5.2, 0.2, 0.2]])), [True, False]
    )


def test_neighbour_counts_by_brute_force() -> None:
    rng = np.random.default_rng(3)
    idx = rng.integers(-3, 4, size=(120, 3))
    keys = unique_keys(voxel_keys(idx + 0.5, 1.0))
    support = unique_keys(voxel_keys(rng.integers(-3, 4, size=(80, 3)) + 0.5, 1.0))
    cells = lambda k: np.column_stack(voxel._unpack(k))  # noqa: E731
    a, b = cells(keys), cells(support)
    chebyshev = np.abs(a[:, None, :] - b[None, :, :]).max(axis=2)
    np.testing.assert_array_equal(
        neighbour_counts(keys, support), np.count_nonzero(chebyshev == 1, axis=1)
    )
    assert not neighbour_counts(keys, support[:0]).any()


def test_min_neighbours_drops_lone_returns_and_keeps_surfaces() -> None:
    """A wall's voxels hold each other up; one false return in the sky stands alone,
    and one return next to the wall is kept (a neighbour was hit)."""
    wall = np.array([[20.5, y + 0.5, z + 0.5] for y in range(-3, 3) for z in range(1, 5)])
    lone = np.array([[10.5, 0.5, 12.5]])
    beside = np.array([[21.5, 0.5, 5.5]])  # diagonal to the wall's top row
    probe = np.vstack([wall[:1], lone, beside])
    for need, expected in ((0, [True, True, True]), (1, [True, False, True])):
        bg = VoxelBackground(resolution=1.0, inflate=0, min_neighbours=need)
        bg.insert(np.vstack([wall, lone, beside]))
        bg.build()
        np.testing.assert_array_equal(bg.is_background(probe), expected)
    with pytest.raises(InputError, match="min_neighbours must be 0-26"):
        VoxelBackground(1.0, min_neighbours=27)


def test_neighbours_count_any_hit_voxel_even_below_min_hits() -> None:
    """Support comes from every voxel hit, so a surface seen sparsely (a voxel with
    one return beside one with two) keeps the voxel that has enough returns."""
    bg = VoxelBackground(resolution=1.0, inflate=0, min_hits=2, min_neighbours=1)
    bg.insert(np.array([[0.5, 0.5, 0.5]] * 2 + [[1.5, 0.5, 0.5]] + [[9.5, 0.5, 0.5]] * 2))
    bg.build()
    probe = np.array([[0.5, 0.5, 0.5], [1.5, 0.5, 0.5], [9.5, 0.5, 0.5]])
    np.testing.assert_array_equal(bg.is_background(probe), [True, False, False])


def test_lookup_depth_coarsens_like_an_octree() -> None:
    bg = VoxelBackground(resolution=1.0, inflate=0, lookup_depth=2)
    bg.insert(np.array([[0.5, 0.5, 0.5]]))
    bg.build()
    assert bg.cell_size == 4.0
    np.testing.assert_array_equal(
        bg.is_background(np.array([[3.9, 3.9, 3.9], [4.1, 0, 0]])), [True, False]
    )


def test_an_unbuilt_model_refuses_lookups() -> None:
    with pytest.raises(InputError, match="not been built"):
        VoxelBackground(1.0).is_background(np.zeros((1, 3)))


def _keys(cells: list[tuple[int, int, int]], size: float = 0.5) -> np.ndarray:
    return unique_keys(voxel_keys((np.array(cells, dtype=float) + 0.5) * size, size))


def test_a_small_part_standing_free_is_left_out_and_a_large_one_stays() -> None:
    drone = [(4, 1, 4), (5, 1, 4), (4, 2, 4)]  # 1 m across at 0.5 m voxels
    pole = [(10, 0, z) for z in range(8)]  # 4 m tall
    keys = _keys(drone + pole)
    free = free_objects(keys, 0.5, 2.0)
    centres = voxel.key_centres(keys, 0.5)
    np.testing.assert_array_equal(free, centres[:, 0] < 4.0)


def test_single_returns_never_join_a_free_part_to_anything() -> None:
    """Two false alarms side by side beside a hovering drone make the three one part
    (2.5 m) until voxels a single return hit stop joining parts: the drone is then
    free, and so are the false alarms, out of reach of anything that stays; a single
    return within reach of what stays (the post's sparse top) stays with it."""
    drone = [(4, 1, 4), (5, 1, 4), (4, 2, 4)]
    alarms = [(1, 1, 3), (2, 2, 4)]
    post = [(-3, 1, z) for z in range(6)]  # 3 m tall, 2 m from the first alarm
    top = [(-3, 1, 7)]  # one return a voxel above the post's top
    cells = drone + alarms + post + top
    keys = _keys(cells)
    returns = np.concatenate([np.repeat(_keys([c]), 1 if c in alarms + top else 3) for c in cells])
    weak = single_hits(returns, keys)
    np.testing.assert_array_equal(weak, np.isin(keys, _keys(alarms + top)))
    assert not free_objects(keys, 0.5, 2.0).any()  # drone and alarms one part, 2.5 m long
    free = free_objects(keys, 0.5, 2.0, weak)
    np.testing.assert_array_equal(free, np.isin(keys, _keys(drone + alarms)))


# 0.5 m voxels (index · 0.5 m is a voxel's bottom): the crop's floor at level 1 (0.5 m)
PERSON = [(x, 0, z) for x in (6, 7) for z in range(1, 4)]  # 0.5-2.0 m up, standing
BESIDE = [(4, 0, 4), (4, 1, 4), (3, 0, 4)]  # 2.0-2.5 m up, 1 m beside its head
GROUND = [(x, y, 1) for x in range(20, 22) for y in range(2)]  # a patch of ground, far off
POLE = [(-6, 0, z) for z in range(1, 8)]  # a post 3.5 m tall ...
ON_POLE = [(-6, 0, 9), (-7, 0, 9)]  # ... and a lamp 0.5 m above its top


def test_a_small_part_with_nothing_beneath_it_is_in_the_air() -> None:
    """A drone hovering 1 m beside and 0.5 m above a person standing still is one part
    of the scan with the person by the free-standing gap (2.5 m long, too large), yet
    nothing lies beneath it and it is 1.5 m above the floor: it is in the air.  The
    person stands on the floor; a patch of ground has nothing beneath it but is the
    floor; a lamp 0.5 m above its post has the post within 1 m beneath it; the pieces of
    a sparsely sampled wall have more of it beside them at their level."""
    keys = _keys(PERSON + BESIDE + GROUND + POLE + ON_POLE)
    assert not free_objects(keys, 0.5, 2.0)[np.isin(keys, _keys(BESIDE))].any()
    aloft = aloft_objects(keys, 0.5, 2.0)
    np.testing.assert_array_equal(aloft, np.isin(keys, _keys(BESIDE)))
    # the patch's copy 1 m up has it within 1 m beneath; 2 m up, nothing: in the air
    for rise, up in ((2, False), (4, True)):
        lifted = _keys([(x, y, z + rise) for x, y, z in GROUND])
        both = unique_keys(np.concatenate([keys, lifted]))
        assert (aloft_objects(both, 0.5, 2.0)[np.isin(both, lifted)] == up).all(), rise
    assert not aloft_objects(keys, 0.5, 0.5).any()  # the drone's part is 1.5 m long
    # a wall sampled sparsely 3 m up, over the ground: each of its pieces stands alone
    # and has nothing beneath, but the next piece beside it at its level, 1 voxel away
    pieces = [(x, 10, 6) for x in range(0, 12, 2)]
    floor = [(x, 10, 1) for x in range(12)]
    wall = _keys(pieces + floor)
    assert not aloft_objects(wall, 0.5, 2.0).any()
    lone = _keys(pieces[:1] + floor)
    np.testing.assert_array_equal(aloft_objects(lone, 0.5, 2.0), np.isin(lone, _keys(pieces[:1])))


def test_a_short_scan_leaves_a_drone_hovering_beside_a_person_out() -> None:
    """The scan's map of the person, the drone beside its head, a post and its lamp:
    the drone is left out (foreground), the rest stays; the map is provisional."""
    cells = PERSON + BESIDE + POLE + ON_POLE
    bg = VoxelBackground(resolution=0.5, inflate=0, free_object_m=2.0)
    bg.insert((np.array(cells, dtype=float) + 0.5) * 0.5)
    bg.build()
    assert bg.provisional
    assert bg.left_out == len(BESIDE)
    centres = (np.array(cells, dtype=float) + 0.5) * 0.5
    np.testing.assert_array_equal(bg.is_background(centres), [c not in BESIDE for c in cells])
    assert not VoxelBackground(resolution=0.5).provisional


def test_shifted_keys_move_each_voxel_by_whole_voxels() -> None:
    keys = _keys([(0, 0, 0), (-3, 5, 2)])
    np.testing.assert_array_equal(shifted_keys(keys, 1, -2, 3), _keys([(1, -2, 3), (-2, 3, 5)]))
    np.testing.assert_array_equal(
        np.column_stack(voxel.key_indices(keys)), np.array([(-3, 5, 2), (0, 0, 0)])
    )


def test_the_lookup_level_keeps_cells_within_an_angle_of_the_sensor() -> None:
    # 0.5 m voxels, depth 2: 0.5 m cells below 4 m, 1 m to 8 m, 2 m beyond
    r = np.array([0.3, 3.9, 4.0, 7.9, 8.0, 500.0])
    np.testing.assert_array_equal(lookup_level(r, 0.5, 2), [0, 0, 1, 1, 2, 2])
    size = 0.5 * 2.0 ** lookup_level(r, 0.5, 2)
    assert np.all((size <= NEAR_ANGLE * r + 1e-12) | (size == 0.5))


def test_near_the_sensor_a_built_model_looks_up_in_finer_cells() -> None:
    """A wall 1 m below a drone that hovers 3 m from the sensor: its 2 m cell holds
    the drone's place, the finer cell there does not; far out, the coarse cells rule."""
    wall = np.array([[x, y, 0.75] for x in np.arange(2.0, 4.0, 0.1) for y in (0.1, 0.3)])
    bg = VoxelBackground(resolution=0.5, inflate=0, lookup_depth=2)
    bg.insert(wall)
    bg.build()
    assert bg.near_m == pytest.approx(0.5 * 4 / NEAR_ANGLE)
    drone = np.array([[3.0, 0.2, 1.7]])
    sensor = np.zeros(3)
    assert bg.is_background(drone).tolist() == [True]  # the 2 m cell [0, 2) in z
    assert bg.is_background(drone, sensor).tolist() == [False]
    assert bg.is_background(drone, np.array([-20.0, 0.2, 1.7])).tolist() == [True]
    loaded = VoxelBackground.from_cells(bg.cells.keys, 0.5, 0, 2)
    assert loaded.near_m == 0.0  # a saved model has its coarse cells only
    assert loaded.is_background(drone, sensor).tolist() == [True]
