"""``jobs.lidar_model``: the LiDAR a device or a recording says it is, against the
scenario's ``[sensor] model``: adopted with a warning, refused across kinds, or kept."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dronetrack.config.run import apply_overrides, dump_scenario, load_scenario_file
from dronetrack.config.scenarios import SCENARIOS, get_scenario
from dronetrack.errors import ConfigError
from dronetrack.jobs.lidar_model import (
    FoundLidar,
    adopt_lidar,
    check_lidar_kind,
    livox_lidar,
    recording_lidar,
)
from dronetrack.jobs.replay import recording_config
from dronetrack.sources.recordings.opener import open_recording
from lvx_files import mid40_lvx

SITE = Path(__file__).parents[2] / "examples" / "site.toml"


def test_a_livox_device_type_names_the_model() -> None:
    mid40 = livox_lidar(1, "from its discovery")
    assert mid40 == FoundLidar("Livox Mid-40", "mid40", "device type 1 from its discovery")
    assert livox_lidar(7, "x") == FoundLidar("Livox Avia", "avia", "device type 7 x")
    assert livox_lidar(9, "x") == FoundLidar("Livox Mid-360", "mid360", "device type 9 x")
    assert livox_lidar(3, "x") == FoundLidar("Livox Horizon", None, "device type 3 x")
    assert livox_lidar(None, "x") is None


def test_another_model_replaces_the_files_with_its_reach_and_a_warning() -> None:
    default = get_scenario("default")
    assert (default.sensor.model, default.pipeline.evaluation.reach_m) == ("avia", 130.0)
    cfg, warning = adopt_lidar(default, livox_lidar(1, "from its discovery"), "--lidar livox://x")
    assert cfg.sensor.model == "mid40"
    assert cfg.pipeline.evaluation.reach_m is None  # measured for the Avia only
    kept = cfg.pipeline.model_copy(update={"evaluation": default.pipeline.evaluation})
    assert kept == default.pipeline
    assert warning is not None
    assert "Livox Mid-40" in warning
    assert "'avia'" in warning
    assert "'mid40'" in warning
    assert 'model = "mid40"' in dump_scenario(cfg)


def test_the_same_model_or_nothing_found_changes_nothing() -> None:
    site = load_scenario_file(SITE, SCENARIOS)
    assert adopt_lidar(site, livox_lidar(7, "x"), "it") == (site, None)
    assert adopt_lidar(site, None, "it") == (site, None)


def test_a_model_we_have_none_of_keeps_the_files_with_a_warning() -> None:
    site = load_scenario_file(SITE, SCENARIOS)
    cfg, warning = adopt_lidar(site, livox_lidar(3, "x"), "it")
    assert cfg == site
    assert warning is not None
    assert "Livox Horizon" in warning
    assert "'avia'" in warning


def test_a_spinning_lidar_against_a_livox_scenario_is_refused() -> None:
    default, vlp16, side = (get_scenario(n) for n in ("default", "walk-line", "seed003-field"))
    assert (vlp16.sensor.model, side.sensor.model) == ("vlp16", "vlp16-side")
    with pytest.raises(ConfigError, match=r"VLP-16.*'avia'.*vlp16"):
        check_lidar_kind(default, "velodyne://2368")
    with pytest.raises(ConfigError, match=r"Livox.*'vlp16'"):
        check_lidar_kind(vlp16, "livox://192.168.1.3")
    with pytest.raises(ConfigError, match=r"Livox.*'vlp16-side'"):
        check_lidar_kind(side, "livox2://192.168.1.3")
    for cfg, lidar in ((vlp16, "velodyne://2368"), (side, "velodyne://2368"),
                       (default, "livox://192.168.1.3"), (default, "file:///x.bag")):  # fmt: skip
        check_lidar_kind(cfg, lidar)


def test_an_lvx_file_names_its_device(tmp_path: Path) -> None:
    rec = open_recording(mid40_lvx(tmp_path / "mid40.lvx"))
    assert recording_lidar(rec) == FoundLidar(
        "Livox Mid-40", "mid40", "device type 1 in its LVX header"
    )
    # with no --config and no scenario carried, the replay takes the file's model
    assert recording_config(rec, None).sensor.model == "mid40"
    frames = list(rec.frames())
    assert np.allclose(np.concatenate([f.points for f in frames])[:, 0], 20.0)


def test_a_bag_names_the_sensor_of_the_scenario_it_carries(tmp_path: Path) -> None:
    from dronetrack.config.rig import turret_spec
    from dronetrack.sinks.bag_writer import RecordingWriter
    from dronetrack.types import Frame

    carried = apply_overrides(get_scenario("walk-line"), seed=3)
    assert carried.sensor.model == "vlp16"
    path = tmp_path / "vlp16.bag"
    writer = RecordingWriter(
        path, "ros1", turret_spec(carried.turret).mount, config_text=dump_scenario(carried)
    )
    for k in range(3):
        pts = np.array([[20.0, 0.0, 1.0]])
        frame = Frame(
            stamp=0.1 * k,
            duration=0.1,
            points=pts,
            t=np.array([0.1 * k]),
            line=np.zeros(1, np.uint8),
            intensity=np.ones(1, np.float32),
            pose_t=np.array([0.1 * k]),
            poses=np.eye(4)[None],
        )
        writer.frame(frame, np.array([20.0, 0.0, 1.0]), np.eye(3))
    writer.close()
    rec = open_recording(path)
    found = recording_lidar(rec)
    assert found is not None
    assert (found.name, found.model, found.said) == ("vlp16", "vlp16", "the scenario it carries")
    site = load_scenario_file(SITE, SCENARIOS)
    cfg, warning = adopt_lidar(site, found, "vlp16.bag")
    assert cfg.sensor == carried.sensor.model_copy(
        update={"integration_time_s": site.sensor.integration_time_s}
    )
    assert warning is not None
    assert "'avia'" in warning
