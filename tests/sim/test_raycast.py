"""Ray–shape intersections against known answers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import unit
from dronetrack.sim.cubemap import build_cube_map, cube_cells
from dronetrack.sim.raycast import Primitives, cast_rays
from dronetrack.sim.shapes import box, cylinder, ellipsoid, ground


def _one_ray(prims: Primitives, o: tuple[float, float, float], d: tuple[float, float, float]):
    t, hit, cos = cast_rays(prims, np.array(o, float), unit(np.array([d], float)))
    return float(t[0]), int(hit[0]), float(cos[0])


def test_box_from_outside_and_inside() -> None:
    b = box((10.0, 0.0, 0.0), (2.0, 40.0, 6.0), 0.5)
    assert _one_ray(b, (0, 0, 0), (1, 0, 0)) == pytest.approx((9.0, 0, 1.0))
    # Oblique entry through the x face: t = 9 / cos 45°, |cos| = cos 45°.
    t, hit, cos = _one_ray(b, (0, 0, 0), (1, 1, 0))
    assert (t, hit) == (pytest.approx(9 * np.sqrt(2)), 0)
    assert cos == pytest.approx(np.sqrt(0.5))
    # From inside the box the exit face is hit.
    assert _one_ray(b, (10, 0, 0), (0, 0, 1))[0] == pytest.approx(3.0)
    assert _one_ray(b, (0, 0, 0), (-1, 0, 0))[1] == -1


def test_rotated_box_uses_its_own_axes() -> None:
    # A 1 m cube turned 45° about z presents its edge: the ray meets it at
    # 10 − √2/2 from the origin.
    b = box((10.0, 0.0, 0.0), (1.0, 1.0, 1.0), 0.5, yaw=np.pi / 4)
    assert _one_ray(b, (0, 0, 0), (1, 0, 0))[0] == pytest.approx(10 - np.sqrt(0.5))


def test_sphere_and_ellipsoid() -> None:
    s = ellipsoid((0.0, 10.0, 0.0), (1.0, 1.0, 1.0), 0.5)
    t, hit, cos = _one_ray(s, (0, 0, 0), (0, 1, 0))
    assert (t, hit, cos) == pytest.approx((9.0, 0, 1.0))
    # A ray grazing at offset b from the centre of a unit sphere: t = √(d² − b²) − √(1 − b²)
    # and the incidence cosine is √(1 − b²).
    b = 0.6
    t, _, cos = _one_ray(s, (b, 0, 0), (0, 1, 0))
    assert t == pytest.approx(10 - np.sqrt(1 - b**2))
    assert cos == pytest.approx(np.sqrt(1 - b**2))
    e = ellipsoid((0.0, 0.0, 5.0), (1.0, 2.0, 3.0), 0.5)
    assert _one_ray(e, (0, 0, 0), (0, 0, 1))[0] == pytest.approx(2.0)
    assert _one_ray(e, (0, -10, 5), (0, 1, 0))[0] == pytest.approx(8.0)
    assert _one_ray(e, (1.01, -10, 5), (0, 1, 0))[1] == -1


def test_cylinder_side_and_caps() -> None:
    c = cylinder((5.0, 0.0, 1.0), 0.5, 2.0, 0.5)
    assert _one_ray(c, (0, 0, 1), (1, 0, 0)) == pytest.approx((4.5, 0, 1.0))
    # Down onto the top cap at z = 2.
    assert _one_ray(c, (5, 0.2, 10), (0, 0, -1)) == pytest.approx((8.0, 0, 1.0))
    # Above the top: miss.
    assert _one_ray(c, (0, 0, 2.1), (1, 0, 0))[1] == -1
    # A cylinder lying along x is met on its cap.
    lying = cylinder((5.0, 0.0, 0.0), 0.5, 2.0, 0.5, rotation=_z_to_x())
    assert _one_ray(lying, (0, 0, 0), (1, 0, 0))[0] == pytest.approx(4.0)


def _z_to_x() -> np.ndarray:
    """A rotation taking local z to world x."""
    return np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def test_ground_plane() -> None:
    g = ground(0.3)
    t, hit, cos = _one_ray(g, (0, 0, 2), (1, 0, -1))
    assert (t, hit) == (pytest.approx(2 * np.sqrt(2)), 0)
    assert cos == pytest.approx(np.sqrt(0.5))
    assert _one_ray(g, (0, 0, 2), (1, 0, 0.1))[1] == -1


def test_nearest_primitive_wins_and_t_max() -> None:
    prims = Primitives.concat(
        [
            box((20.0, 0.0, 0.0), (1.0, 1.0, 1.0), 0.5),
            box((10.0, 0.0, 0.0), (1.0, 1.0, 1.0), 0.5),
        ]
    )
    assert _one_ray(prims, (0, 0, 0), (1, 0, 0))[:2] == pytest.approx((9.5, 1))
    t, hit, _ = cast_rays(prims, np.zeros(3), np.array([[1.0, 0.0, 0.0]]), t_max=5.0)
    assert np.isinf(t[0])
    assert hit[0] == -1


@settings(max_examples=20)
@given(st.integers(0, 2**32 - 1))
def test_cube_map_index_never_changes_the_answer(seed: int) -> None:
    g = np.random.default_rng(seed)
    parts = [ground(0.3)]
    for _ in range(15):
        c = g.uniform([-50, -50, 0], [50, 50, 10])
        parts.append(box(c, g.uniform(0.5, 8, 3), 0.5, yaw=g.uniform(-3, 3)))
        parts.append(ellipsoid(c + np.array([0.0, 0.0, 5.0]), g.uniform(0.5, 4, 3), 0.5))
        parts.append(
            cylinder(c - np.array([3.0, 3.0, 0.0]), g.uniform(0.1, 1), g.uniform(1, 6), 0.5)
        )
    # One shape around the index origin: it must be tested by every ray.
    parts.append(ellipsoid((0.0, 0.0, 1.5), (3.0, 3.0, 3.0), 0.5))
    prims = Primitives.concat(parts)
    origin = np.array([0.0, 0.0, 1.5])
    slack = 0.3
    # Origins anywhere within `slack` of the index origin.
    jitter = unit(g.normal(size=(3000, 3))) * g.uniform(0, slack, (3000, 1))
    dirs = unit(g.normal(size=(3000, 3)))
    index = build_cube_map(prims, origin, slack, n=int(g.integers(4, 40)))
    plain = cast_rays(prims, origin + jitter, dirs)
    indexed = cast_rays(prims, origin + jitter, dirs, index=index)
    for a, b in zip(plain, indexed, strict=True):
        np.testing.assert_array_equal(a, b)
    assert index.covers(origin + 0.1, 0.1)
    assert not index.covers(origin + 0.3, 0.1)


@settings(max_examples=20)
@given(st.integers(0, 2**32 - 1))
def test_cube_map_with_a_margin_holds_for_moved_primitives(seed: int) -> None:
    """An index built on the still scene with a margin per primitive answers rays against
    the scene with each primitive moved by up to its margin (swaying crowns)."""
    g = np.random.default_rng(seed)
    parts = [ground(0.3)]
    for _ in range(30):
        c = g.uniform([-40, -40, 2], [40, 40, 15])
        parts.append(ellipsoid(c, g.uniform(0.5, 4, 3), 0.5))
    prims = Primitives.concat(parts)
    margin = np.r_[0.0, g.uniform(0.0, 2.0, 30)]
    offset = unit(g.normal(size=(31, 3))) * (margin * g.uniform(0, 1, 31))[:, None]
    moved = Primitives(
        prims.kind, prims.center + offset, prims.rotation, prims.half, prims.reflectivity
    )
    origin = np.array([0.0, 0.0, 1.5])
    dirs = unit(g.normal(size=(3000, 3)))
    index = build_cube_map(prims, origin, 0.2, margin=margin)
    plain = cast_rays(moved, origin, dirs)
    indexed = cast_rays(moved, origin, dirs, index=index)
    for a, b in zip(plain, indexed, strict=True):
        np.testing.assert_array_equal(a, b)


def test_cube_cells_cover_the_sphere() -> None:
    centres, radius = cube_cells(8)
    assert centres.shape == (6 * 64, 3)
    d = unit(np.random.default_rng(0).normal(size=(5000, 3)))
    # Every direction is within some cell's radius of that cell's centre.
    nearest = np.max(d @ centres.T, axis=1)
    assert np.all(np.arccos(np.clip(nearest, -1, 1)) <= radius.max() + 1e-12)


def test_bad_shapes_are_rejected() -> None:
    with pytest.raises(InputError, match="positive"):
        box((0, 0, 0), (1.0, 0.0, 1.0), 0.5)
    with pytest.raises(InputError, match=r"\(N, 3\)"):
        cast_rays(ground(0.3), np.zeros(3), np.zeros((4, 2)))
