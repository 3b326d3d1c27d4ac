"""[scene.clutter]: off by default, validated, read from TOML and written back."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from pydantic import ValidationError

from dronetrack.config.run import ClutterConfig, ScenarioConfig, dump_scenario, load_scenario_file
from dronetrack.config.scenarios import SCENARIOS, get_scenario
from dronetrack.errors import ConfigError, ScenarioError
from dronetrack.sim.build import build_world, resolve_scenario


def test_clutter_is_off_unless_asked_for() -> None:
    assert ScenarioConfig().scene.clutter is None
    named = [n for n, cfg in SCENARIOS.items() if cfg.scene.clutter is not None]
    assert named == ["outdoor-clutter"]


@pytest.mark.parametrize(
    ("values", "key"),
    [
        ({"false_alarms_per_s": -1.0}, "false_alarms_per_s"),
        ({"false_alarms_per_s": float("inf")}, "false_alarms_per_s"),
        ({"birds": -1}, "birds"),
        ({"gust_m": -0.1}, "gust_m"),
        ({"sway_m": float("nan")}, "sway_m"),
        ({"sway_period_s": 0.0}, "sway_period_s"),
        ({"gust_period_s": -5.0}, "gust_period_s"),
        ({"bird_reflectivity": 0.0}, "bird_reflectivity"),
        ({"bird_reflectivity": 1.5}, "bird_reflectivity"),
        ({"bird_speed_m_s": (15.0, 5.0)}, "bird_speed_m_s"),
        ({"bird_size_m": (0.0, 0.5)}, "bird_size_m"),
        ({"bird_height_m": (-5.0, 60.0)}, "bird_height_m"),
        ({"birds": 1, "bird_crossings_s": (-1.0,)}, "bird_crossings_s"),
        ({"birds": 1, "bird_crossings_s": (5.0, 9.0)}, "bird_crossings_s"),
        ({"wind": 3.0}, "wind"),
    ],
)
def test_bad_clutter_values_are_refused(values: dict[str, Any], key: str) -> None:
    with pytest.raises(ValidationError, match=key):
        ClutterConfig(**values)


def test_a_bad_value_in_a_scenario_file_names_its_key(tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text('base = "default"\n[scene.clutter]\nfalse_alarms_per_s = -3.0\n')
    with pytest.raises(ScenarioError, match=r"scene\.clutter\.false_alarms_per_s"):
        get_scenario(str(path))


def test_clutter_from_a_scenario_file_round_trips(tmp_path: Path) -> None:
    path = tmp_path / "windy.toml"
    path.write_text(
        'base = "default"\n[scene.clutter]\ngust_m = 0.5\nbirds = 3\n'
        "bird_crossings_s = [4.0]\nfalse_alarms_per_s = 10.0\n"
    )
    cfg = get_scenario(str(path))
    assert cfg.scene.clutter == ClutterConfig(
        gust_m=0.5, birds=3, bird_crossings_s=(4.0,), false_alarms_per_s=10.0
    )
    for named in (cfg, SCENARIOS["outdoor-clutter"]):
        resolved = resolve_scenario(named)
        again = tmp_path / "again.toml"
        again.write_text(dump_scenario(resolved))
        assert load_scenario_file(again, SCENARIOS) == resolved


def test_birds_need_an_outdoor_sized_area() -> None:
    cfg = SCENARIOS["indoor-horizontal"]
    indoor = cfg.model_copy(
        update={"scene": cfg.scene.model_copy(update={"clutter": ClutterConfig(birds=1)})}
    )
    with pytest.raises(ConfigError, match="birds"):
        build_world(indoor)
