"""``[[walkers]]`` and ``[[vehicles]]`` in a scenario file: defaults, round trips, the
scan's offset on a vehicle's arrival, and bad values named one line each."""

from __future__ import annotations

from pathlib import Path

import pytest

from dronetrack.config.run import dump_scenario, load_scenario_file
from dronetrack.config.scenarios import SCENARIOS, get_scenario
from dronetrack.errors import ScenarioError
from dronetrack.jobs.simulate import flight_config
from dronetrack.sim.build import build_world, resolve_scenario
from sim_helpers import assert_same_frames

MOVERS = (
    'base = "default"\nduration_s = 20.0\n'
    "[[walkers]]\ncount = 2\narea_m = [10.0, -5.0, 20.0, 5.0]\n"
    "[[walkers]]\narea_m = [-20.0, -5.0, -10.0, 5.0]\n"
    "speed_m_s = [1.2, 1.4]\npause_s = [1.0, 2.0]\n"
    "[[vehicles]]\npath_m = [[60.0, -30.0], [30.0, -10.0]]\narrive_s = 8.0\n"
)


def test_walkers_and_vehicles_load_with_their_defaults(tmp_path: Path) -> None:
    path = tmp_path / "busy.toml"
    path.write_text(MOVERS)
    cfg = get_scenario(str(path))
    assert [w.count for w in cfg.walkers] == [2, 1]
    assert cfg.walkers[0].speed_m_s == (1.0, 1.6)
    assert cfg.walkers[0].pause_s == (0.0, 5.0)
    assert cfg.walkers[1].speed_m_s == (1.2, 1.4)
    (car,) = cfg.vehicles
    assert car.path_m == ((60.0, -30.0), (30.0, -10.0))
    assert (car.arrive_s, car.speed_m_s, car.size_m, car.reflectivity) == (
        8.0,
        5.0,
        (4.5, 1.8, 1.5),
        0.4,
    )
    world = build_world(cfg)
    assert world.movers is not None
    assert [m.kind for m in world.movers.movers] == ["walker"] * 3 + ["vehicle"]


def test_a_scenario_file_with_walkers_and_vehicles_round_trips(tmp_path: Path) -> None:
    path = tmp_path / "busy.toml"
    path.write_text(MOVERS)
    resolved = resolve_scenario(get_scenario(str(path)))
    text = dump_scenario(resolved)
    assert text.count("[[walkers]]") == 2
    assert text.count("[[vehicles]]") == 1
    again = tmp_path / "again.toml"
    again.write_text(text)
    reloaded = load_scenario_file(again, SCENARIOS)
    assert reloaded == resolved
    assert_same_frames(resolved, reloaded, 5)


def test_a_scenario_without_walkers_or_vehicles_writes_none() -> None:
    text = dump_scenario(resolve_scenario(SCENARIOS["default"]))
    assert "walkers" not in text
    assert "vehicles" not in text


def test_simulate_counts_an_arrival_from_the_end_of_the_background_scan() -> None:
    cfg = SCENARIOS["site-busy"]
    scan_s = cfg.pipeline.background.scan_s
    flight = flight_config(cfg)
    assert flight.vehicles[0].arrive_s == scan_s + cfg.vehicles[0].arrive_s
    assert flight.walkers == cfg.walkers  # walkers walk from the start, the scan's too
    assert cfg.vehicles[0].arrive_s == 20.0  # the configuration itself is not changed


@pytest.mark.parametrize(
    ("entry", "message"),
    [
        (
            "[[walkers]]\narea_m = [0, 0, 10, 10]\nspeed_m_s = [-1.0, 1.5]\n",
            r"walkers\.0: .*speed_m_s must be \(low, high\) with 0 < low ≤ high ≤ 5 m/s, got -1",
        ),
        ("[[walkers]]\narea_m = [0, 0, 10, 10]\nspeed_m_s = [1.6, 1.0]\n", "got 1.6, 1"),
        ("[[walkers]]\narea_m = [0, 0, 10, 10]\nspeed_m_s = [1.0, 7.0]\n", "≤ 5 m/s"),
        ("[[walkers]]\narea_m = [0, 0, 10, 10]\npause_s = [-2.0, 1.0]\n", "pause_s must be"),
        ("[[walkers]]\narea_m = [0, 0, 1, 10]\n", "area_m must be"),
        ("[[walkers]]\narea_m = [10, 0, 0, 10]\n", "area_m must be"),
        ("[[walkers]]\ncount = 0\narea_m = [0, 0, 10, 10]\n", r"walkers\.0\.count"),
        ("[[walkers]]\ncount = 2\n", r"walkers\.0\.area_m: Field required"),
        (
            "[[walkers]]\narea_m = [0, 0, 10, 10]\nheight_m = 2\n",
            "unknown key 'walkers.0.height_m'",
        ),
        (
            "[[vehicles]]\npath_m = [[0, 0], [10, 0]]\nspeed_m_s = -5.0\n",
            r"vehicles\.0\.speed_m_s: Input should be greater than 0",
        ),
        ("[[vehicles]]\npath_m = [[0, 0]]\n", r"vehicles\.0\.path_m"),
        ("[[vehicles]]\npath_m = [[0, 0], [10, 0]]\narrive_s = -1\n", r"vehicles\.0\.arrive_s"),
        (
            "[[vehicles]]\npath_m = [[0, 0], [10, 0]]\narrive_s = 30\n",
            r"vehicles\.0\.arrive_s = 30 s is not before the run ends \(duration_s = 20 s\)",
        ),
        ("[[vehicles]]\npath_m = [[0, 0], [10, 0]]\nsize_m = [4, 0, 1]\n", "size_m must be"),
    ],
)
def test_bad_walker_and_vehicle_entries_name_the_entry(
    tmp_path: Path, entry: str, message: str
) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(f'base = "default"\nduration_s = 20.0\n{entry}')
    with pytest.raises(ScenarioError, match=message):
        get_scenario(str(path))


def test_a_run_cut_short_leaves_out_the_vehicle_that_would_park_after_it() -> None:
    """``site-busy``'s car parks 20 s into the flight: ``--duration 10`` leaves it out
    rather than refusing the run; 30 s keeps it; a file that sets both stays refused."""
    from dronetrack.config.run import apply_overrides

    busy = get_scenario("site-busy")
    assert len(busy.vehicles) == 1
    assert apply_overrides(busy, duration=10.0).vehicles == ()
    assert apply_overrides(busy, duration=30.0).vehicles == busy.vehicles
    with pytest.raises(ValueError, match="would never park"):  # pydantic's ValidationError
        busy.model_validate({**busy.model_dump(), "duration_s": 10.0})
