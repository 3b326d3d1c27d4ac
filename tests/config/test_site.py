"""``[site]`` and ``[[zones]]``: the site's frame on the Earth, the zones in it, and every
bad zone a user can write, each refused in one line that names it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dronetrack.config.run import ScenarioConfig, dump_scenario, load_scenario_file
from dronetrack.config.scenarios import SCENARIOS
from dronetrack.errors import ScenarioError
from dronetrack.jobs.site import site_frame, site_zones

SITE = """
base = "default"
[site]
latitude_deg = 47.4
longitude_deg = 19.2
altitude_m = 120.0
heading_deg = 90.0
"""


def _load(tmp_path: Path, text: str) -> ScenarioConfig:
    path = tmp_path / "site.toml"
    path.write_text(text)
    return load_scenario_file(path, SCENARIOS)


def test_a_zone_lands_where_its_coordinates_say_in_the_world_frame(tmp_path: Path) -> None:
    # world x points east (heading 90°); a circle 0.001° east of the site is about 75 m
    # along x, and a square north of it along +y (y is 90° left of x: north).
    cfg = _load(
        tmp_path,
        SITE
        + """
[[zones]]
name = "east"
centre = [47.4, 19.201]
radius_m = 20.0
margin_m = 10.0
[[zones]]
name = "north"
polygon = [[47.4010, 19.1995], [47.4010, 19.2005], [47.4020, 19.2005], [47.4020, 19.1995]]
floor_m = 0.0
ceiling_m = 80.0
margin_s = 5.0
""",
    )
    east, north = site_zones(cfg)
    centre = np.array(east.shape.centroid.coords[0])
    # 0.001° of longitude at 47.4° N: N cos φ Δλ ≈ 75.4 m
    np.testing.assert_allclose(centre, [75.4, 0.0], atol=0.5)
    assert east.margin_m == 10.0
    assert east.margin_s == 0.0
    assert north.contains([0.0, 165.0, 10.0])
    assert not north.contains([0.0, 165.0, 90.0])
    lo_x, lo_y, hi_x, hi_y = north.shape.bounds
    assert 100.0 < lo_y < 120.0 < 215.0 < hi_y < 230.0  # 0.001° of latitude ≈ 111.2 m
    assert lo_x < 0.0 < hi_x
    site = site_frame(cfg)
    assert site is not None
    assert site.base == (0.0, 0.0, 1.0)  # the WidowX's base, 1 m above the ground
    lat, lon, alt = site.geodetic([0.0, 0.0, 1.0])
    np.testing.assert_allclose([lat, lon, alt], [47.4, 19.2, 120.0], atol=1e-9)
    # the resolved configuration writes them back as they were read
    again = _load(tmp_path, dump_scenario(cfg))
    assert again.site == cfg.site
    assert again.zones == cfg.zones


@pytest.mark.parametrize(
    ("zone", "message"),
    [
        ("polygon = [[47.4, 19.2], [47.41, 19.2]]\nmargin_m = 5", "at least 3 distinct vertices"),
        (
            "polygon = [[47.4, 19.2], [47.41, 19.21], [47.41, 19.2], [47.4, 19.21]]\nmargin_m = 5",
            "edges cross each other",
        ),
        (
            "polygon = [[47.4, 19.2], [47.41, 19.21], [47.42, 19.22]]\nmargin_m = 5",
            "lie on one line",
        ),
        ("centre = [47.4, 19.2]\nradius_m = 10", "give its warning margin"),
        ("centre = [47.4, 19.2]\nmargin_m = 5", "a circle needs radius_m"),
        ("margin_m = 5", "give either polygon"),
        ("centre = [190.0, 19.2]\nradius_m = 10\nmargin_m = 3", "latitude first"),
        ("centre = [47.4, 19.2]\nradius_m = -1\nmargin_m = 3", "radius_m"),
        (
            "centre = [47.4, 19.2]\nradius_m = 10\nmargin_m = 3\nfloor_m = 50\nceiling_m = 20",
            "is not above floor_m",
        ),
    ],
)
def test_a_bad_zone_is_refused_in_one_line(tmp_path: Path, zone: str, message: str) -> None:
    with pytest.raises(ScenarioError, match=message) as err:
        _load(tmp_path, SITE + f'[[zones]]\nname = "z"\n{zone}\n')
    text = str(err.value)
    assert "\n" not in text
    assert "Value error" not in text
    assert "zones.0" in text


def test_zones_need_a_site_and_names_of_their_own(tmp_path: Path) -> None:
    zone = '[[zones]]\nname = "z"\ncentre = [47.4, 19.2]\nradius_m = 10\nmargin_m = 5\n'
    with pytest.raises(ScenarioError, match=r"need the site's coordinates"):
        _load(tmp_path, 'base = "default"\n' + zone)
    with pytest.raises(ScenarioError, match=r"two \[\[zones\]\] are named 'z'"):
        _load(tmp_path, SITE + zone + zone)
    with pytest.raises(ScenarioError, match=r"site.latitude_deg"):
        _load(tmp_path, 'base = "default"\n[site]\nlatitude_deg = 91.0\nlongitude_deg = 0.0\n')
    with pytest.raises(ScenarioError, match=r"site.longitude_deg: Field required"):
        _load(tmp_path, 'base = "default"\n[site]\nlatitude_deg = 47.0\n')
