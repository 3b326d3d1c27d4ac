"""WGS-84 geodetic → local ENU and the site frame: known answers and properties, against
the textbook ellipsoid written out here (the code under test is pymap3d's)."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.geometry.geodesy import SiteFrame, enu_from_geodetic

WGS84_A = 6378137.0  # semi-major axis [m]
WGS84_F = 1.0 / 298.257223563  # flattening


def geodetic_to_ecef(lat_deg: float, lon_deg: float, alt_m: float) -> np.ndarray:
    """The oracle: x = (N + h) cos φ cos λ, y = (N + h) cos φ sin λ, z = (N (1 − e²) + h)
    sin φ, with N = a / √(1 − e² sin² φ) and e² = f (2 − f)."""
    e2 = WGS84_F * (2.0 - WGS84_F)
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    N = WGS84_A / np.sqrt(1.0 - e2 * np.sin(lat) ** 2)
    return np.array(
        [
            (N + alt_m) * np.cos(lat) * np.cos(lon),
            (N + alt_m) * np.cos(lat) * np.sin(lon),
            (N * (1.0 - e2) + alt_m) * np.sin(lat),
        ]
    )


def test_enu_small_steps_match_the_radii_of_curvature() -> None:
    lat0, lon0 = 47.4, 19.2  # a site near Budapest
    phi = np.radians(lat0)
    e2 = WGS84_F * (2 - WGS84_F)
    # Meridional M = a (1 − e²) / (1 − e² sin² φ)^{3/2} and prime-vertical N = a / √(1 − e² sin² φ)
    M = WGS84_A * (1 - e2) / (1 - e2 * np.sin(phi) ** 2) ** 1.5
    N = WGS84_A / np.sqrt(1 - e2 * np.sin(phi) ** 2)
    d = 1e-4  # degrees: about 11 m north, 7.5 m east
    north = enu_from_geodetic(lat0 + d, lon0, 100.0, (lat0, lon0, 100.0))
    east = enu_from_geodetic(lat0, lon0 + d, 100.0, (lat0, lon0, 100.0))
    up = enu_from_geodetic(lat0, lon0, 105.0, (lat0, lon0, 100.0))
    np.testing.assert_allclose(north, [0.0, M * np.radians(d), 0.0], atol=2e-3)
    np.testing.assert_allclose(east, [N * np.cos(phi) * np.radians(d), 0.0, 0.0], atol=2e-3)
    np.testing.assert_allclose(up, [0.0, 0.0, 5.0], atol=1e-6)
    np.testing.assert_allclose(
        enu_from_geodetic(lat0, lon0, 100.0, (lat0, lon0, 100.0)), 0.0, atol=1e-9
    )


def test_heading_turns_the_frame_about_up() -> None:
    origin = (10.0, 20.0, 0.0)
    p = enu_from_geodetic(10.0, 20.0 + 1e-4, 0.0, origin)  # due east
    # A frame whose x axis points north (90° from east): east is −y in it.
    q = enu_from_geodetic(10.0, 20.0 + 1e-4, 0.0, origin, heading_deg=90.0)
    np.testing.assert_allclose(q, [p[1], -p[0], p[2]], atol=1e-9)


@given(
    st.floats(-80, 80),
    st.floats(-179, 179),
    st.floats(-0.01, 0.01),
    st.floats(-0.01, 0.01),
    st.floats(-100, 100),
    st.floats(-180, 180),
)
def test_enu_preserves_distances(
    lat: float, lon: float, dlat: float, dlon: float, dalt: float, heading: float
) -> None:
    origin = (lat, lon, 50.0)
    enu = enu_from_geodetic(lat + dlat, lon + dlon, 50.0 + dalt, origin, heading)
    ecef = geodetic_to_ecef(lat + dlat, lon + dlon, 50.0 + dalt) - geodetic_to_ecef(*origin)
    assert abs(np.linalg.norm(enu) - np.linalg.norm(ecef)) < 1e-6


def test_the_site_frame_puts_world_x_on_its_heading() -> None:
    # World x points north-east (ψ = 45°); the turret base stands 1 m above the origin.
    site = SiteFrame(47.4, 19.2, 120.0, heading_deg=45.0, base=(0.0, 0.0, 1.0))
    lat, lon, alt = site.geodetic([0.0, 0.0, 1.0])
    np.testing.assert_allclose([lat, lon, alt], [47.4, 19.2, 120.0], atol=1e-9)
    az, el, rng = site.aer([100.0, 0.0, 1.0])  # 100 m along world x, level with the base
    np.testing.assert_allclose([az, el, rng], [45.0, 0.0, 100.0], atol=1e-6)
    az, el, rng = site.aer([0.0, 100.0, 101.0])  # world y is 90° left of x: bearing 315°
    np.testing.assert_allclose([az, el, rng], [315.0, 45.0, 100.0 * np.sqrt(2)], atol=1e-6)
    # A velocity along world x is north-east in ENU.
    np.testing.assert_allclose(site.enu_vectors([2.0, 0.0, 0.0]), [np.sqrt(2), np.sqrt(2), 0.0])


@given(
    st.floats(-80, 80),
    st.floats(-179, 179),
    st.floats(-360, 360),
    st.lists(st.floats(-2000, 2000), min_size=3, max_size=3),
)
def test_site_frame_round_trips(lat: float, lon: float, heading: float, p: list[float]) -> None:
    site = SiteFrame(lat, lon, 30.0, heading_deg=heading, base=(0.0, 0.0, 1.5))
    back = site.from_geodetic(*site.geodetic(p))
    np.testing.assert_allclose(back, p, atol=1e-6)
    # pymap3d's enu2aer sets ENU components under 1 mm to 0 (its singularity guard)
    np.testing.assert_allclose(site.from_aer(*site.aer(p)), p, atol=2e-3)
    # The covariance turns as the vectors do: var(uᵀ x) is the same in both frames.
    P = np.diag([4.0, 1.0, 0.25])
    u = np.array(p) / max(float(np.linalg.norm(p)), 1e-9)
    assert (
        abs(u @ P @ u - site.enu_vectors(u) @ site.enu_covariance(P) @ site.enu_vectors(u)) < 1e-9
    )
