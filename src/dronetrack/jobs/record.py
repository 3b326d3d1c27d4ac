"""``dronetrack record``'s writer: a simulated run as the recording a real rig would make,
a bag (``sinks.bag_writer``) or a Livox Viewer file (``sinks.lvx_writer``)."""

from __future__ import annotations

from pathlib import Path

from dronetrack.config.rig import turret_spec
from dronetrack.config.run import ScenarioConfig, dump_scenario
from dronetrack.sinks.bag_writer import RecordFormat, RecordingWriter
from dronetrack.sinks.lvx_writer import LVX_FORMATS, LvxWriter

__all__ = ["recording_writer"]


def recording_writer(
    out: Path,
    container: RecordFormat,
    resolved: ScenarioConfig,
    *,
    livox_custom: bool,
    compress: bool,
) -> RecordingWriter | LvxWriter:
    """The writer of a resolved run into ``out`` as ``container``, holding the run's
    configuration so that ``dronetrack track`` replays it with the same settings."""
    observer = resolved.observer is not None
    config_text = dump_scenario(resolved)
    if container in LVX_FORMATS:
        return LvxWriter(out, container, resolved.sensor.model, config_text, observer)
    return RecordingWriter(
        out,
        container,
        turret_spec(resolved.turret).mount,
        livox_custom=livox_custom,
        config_text=config_text,
        observer=observer,
        compress=compress,
    )
