"""Which LiDAR a run really had: what the device or the recording says it is, set
against the ``[sensor] model`` of the scenario or site file.

What each one can tell:

- ``livox://`` (SDK 1): the device type in its discovery broadcast (1 Mid-40, 7 Avia,
  3 Horizon, …; ``livox_def.h``); nothing when no broadcast reaches the host (the
  handshake's ACK carries only a return code);
- ``livox2://`` (SDK 2): the device type in its discovery answer (9 Mid-360, …);
- ``velodyne://``: the packets' product byte; the client takes a VLP-16's packets only
  (it refuses any other product), and no packet says whether the head stands upright
  or lies on its side;
- an LVX or LVX2 file: the device type of the device info block it replays;
- a bag (ROS 1, ROS 2, MCAP): the scenario a ``dronetrack record``ed bag carries; a
  real rig's bag names no model (a Livox CustomMsg's ``lidar_id`` is an index, and a
  PointCloud2's fields hint at a kind of sensor but name none);
- PCD, LAS/LAZ and seed 003's CSV logs: nothing.

What is done with it:

- the device or recording is another model of ours (say a Mid-40 against the Avia
  of ``examples/site.toml``): its model replaces the file's, with one warning line
  naming both, and the reach (``[pipeline.evaluation] reach_m``) is the one of that
  model; ``config.toml`` records it;
- a model we have no sensor model of (a Horizon, a Tele, a Mid-70, a HAP): a warning
  line; the file's model stays, as nothing better can be written;
- in ``live``, a spinning VLP-16 (``velodyne://``) against a scenario whose sensor is
  not one (a Livox, or a scan-pattern file), or a Livox against a VLP-16 scenario, is
  refused (``check_lidar_kind``): the frames (one a revolution, or of the integration
  time), the head's mount (upright or on its side, which the packets cannot tell)
  and the turret's scan strategies are the scenario's sensor's, so taking the
  device's word would be a guess;
- nothing said: the file's model, without a word.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass

from dronetrack.config.run import ScenarioConfig, SensorConfig, validate_scenario, with_rig_reach
from dronetrack.config.spinning import SPINNING
from dronetrack.errors import ConfigError
from dronetrack.formats.livox.lvx import DEVICE_NAMES
from dronetrack.sources.recordings.recording import Recording

__all__ = [
    "LIVOX_MODELS",
    "FoundLidar",
    "adopt_lidar",
    "check_lidar_kind",
    "livox_lidar",
    "recording_lidar",
]

# Livox device type (SDK 1 ``livox_def.h``, SDK 2 ``livox_lidar_def.h``) → our sensor model
LIVOX_MODELS = {1: "mid40", 7: "avia", 9: "mid360"}
_LIVOX_SCHEMES = ("livox://", "livox2://")
_VELODYNE_SCHEME = "velodyne://"


@dataclass(frozen=True, slots=True)
class FoundLidar:
    """What a device or a recording says its LiDAR is: ``name`` in its own words
    ("Livox Mid-40"), ``model`` the sensor model of ours it is (None: we have none),
    ``said`` where it said so, and ``sensor`` a recorded scenario's whole ``[sensor]``
    section (None: only the model is known)."""

    name: str
    model: str | None
    said: str
    sensor: SensorConfig | None = None


def _key(model: str) -> str:
    return model.strip().lower()


def livox_lidar(dev_type: int | None, said: str) -> FoundLidar | None:
    """The Livox of device type ``dev_type`` (None: not known, so nothing found)."""
    if dev_type is None:
        return None
    name = DEVICE_NAMES.get(dev_type, f"device of type {dev_type}")
    return FoundLidar(f"Livox {name}", LIVOX_MODELS.get(dev_type), f"device type {dev_type} {said}")


def recording_lidar(recording: Recording) -> FoundLidar | None:
    """What ``recording`` says its LiDAR is (the module docstring); None if nothing."""
    from dronetrack.sources.recordings.lvx import LvxRecording

    if isinstance(recording, LvxRecording):
        header = f"in its {recording.file.kind.upper()} header"
        return livox_lidar(recording.device.device_type, header)
    if recording.config_text is None:
        return None
    try:
        carried = validate_scenario(tomllib.loads(recording.config_text), str(recording.path))
    except (tomllib.TOMLDecodeError, ConfigError):
        return None  # the replay's configuration step names what is wrong with it
    model = carried.sensor.model
    return FoundLidar(model, model, "the scenario it carries", carried.sensor)


def check_lidar_kind(cfg: ScenarioConfig, lidar: str) -> None:
    """ConfigError when ``--lidar`` is a spinning VLP-16 and the scenario's sensor is
    not, or the other way round (see the module docstring)."""
    model = cfg.sensor.model
    spinning = _key(model) in SPINNING
    if lidar.startswith(_VELODYNE_SCHEME) and not spinning:
        raise ConfigError(
            f"--lidar {lidar} is a Velodyne VLP-16, a spinning LiDAR, but the scenario "
            f"{cfg.name!r} has the sensor {model!r}, and its frames and scan are that "
            "sensor's: give a scenario or site file whose [sensor] model is vlp16 "
            "(upright) or vlp16-side"
        )
    if lidar.startswith(_LIVOX_SCHEMES) and spinning:
        raise ConfigError(
            f"--lidar {lidar} is a Livox, but the scenario {cfg.name!r} has the spinning "
            f"sensor {model!r}, and its frames and scan are that sensor's: give a scenario "
            "or site file whose [sensor] model is the Livox (avia, mid40 or mid360)"
        )


def adopt_lidar(
    cfg: ScenarioConfig, found: FoundLidar | None, what: str
) -> tuple[ScenarioConfig, str | None]:
    """``cfg`` with the found LiDAR's model as its sensor (and that sensor's reach), and
    the warning to give (None when they agree or nothing was found); ``what`` names the
    device or the recording in the warning."""
    if found is None:
        return cfg, None
    ours = cfg.sensor.model
    if found.model is None:
        return cfg, (
            f"{what} is a {found.name} ({found.said}), which dronetrack has no sensor "
            f"model of; the run keeps the configuration's {ours!r}"
        )
    if _key(found.model) == _key(ours):
        return cfg, None
    if found.sensor is not None:
        update = {"integration_time_s": cfg.sensor.integration_time_s}
        sensor = found.sensor.model_copy(update=update)
    else:  # the keys of other models go with the file's model
        cleared = {"rpm": None, "rate_hz": None, "lines": None, "physics": None}
        sensor = cfg.sensor.model_copy(update={"model": found.model, **cleared})
    adopted = with_rig_reach(cfg.model_copy(update={"sensor": sensor}))
    return adopted, (
        f"{what} is a {found.name} ({found.said}), not the configuration's {ours!r}: the "
        f"run uses {found.model!r}, and config.toml records it"
    )
