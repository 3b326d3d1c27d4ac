"""``dronetrack record``'s set-up: a simulated run as the recording a real rig would
make, a bag (``sinks.bag_writer``) or a Livox Viewer file (``sinks.lvx_writer``)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from dronetrack.config.rig import turret_spec
from dronetrack.config.run import ScenarioConfig, apply_overrides, dump_scenario
from dronetrack.jobs.simulate import hold_still, resolve_run
from dronetrack.sinks.bag_writer import RecordFormat, RecordingWriter, record_format
from dronetrack.sinks.lvx_writer import LVX_FORMATS, LvxWriter, lvx_turret_mode
from dronetrack.sinks.run_folder import check_run_dir

__all__ = ["RecordingPlan", "prepare_recording", "recording_writer"]


@dataclass(frozen=True, slots=True)
class RecordingPlan:
    """What ``record`` runs: the container, the resolved run and its open writer."""

    container: RecordFormat
    resolved: ScenarioConfig
    writer: RecordingWriter | LvxWriter


def prepare_recording(
    cfg: ScenarioConfig,
    out: Path,
    fmt: str | None,
    *,
    turret_mode: str | None,
    livox_custom: bool,
    compress: bool,
) -> RecordingPlan:
    """The run ``cfg`` set up to be recorded into ``out``: the container (``fmt``, else
    from the suffix), the turret mode (an LVX file holds one fixed pose, so its turret
    holds still), and the writer opened.  ConfigError for options the container does
    not take; RunDirError for a folder that cannot be written."""
    container = record_format(out, fmt)
    lvx = container in LVX_FORMATS
    if lvx:
        turret_mode = lvx_turret_mode(container, turret_mode, compress, livox_custom)
    if turret_mode is not None:
        cfg = apply_overrides(cfg, turret_mode=turret_mode)
    resolved = hold_still(resolve_run(cfg)) if lvx else resolve_run(cfg)
    check_run_dir(out.parent)
    writer = recording_writer(
        out, container, resolved, livox_custom=livox_custom, compress=compress
    )
    return RecordingPlan(container, resolved, writer)


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
