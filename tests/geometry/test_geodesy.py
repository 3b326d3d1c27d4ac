"""WGS-84 geodetic → ECEF → local ENU: known answers and properties."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.geometry.geodesy import WGS84_A, WGS84_F, enu_from_geodetic, geodetic_to_ecef


def test_ecef_known_points() -> None:
    np.testing.assert_allclose(geodetic_to_ecef(0.0, 0.0, 0.0), [WGS84_A, 0.0, 0.0])
    np.testing.assert_allclose(
        geodetic_to_ecef(0.0, 90.0, 10.0), [0.0, WGS84_A + 10.0, 0.0], atol=1e-6
    )
    # The pole lies on the semi-minor axis b = a (1 − f).
    np.testing.assert_allclose(
        geodetic_to_ecef(90.0, 0.0, 0.0), [0.0, 0.0, WGS84_A * (1 - WGS84_F)], atol=1e-6
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
