"""The command line's shared options, names and scenario loading.

Each option that more than one command takes is defined here once, as an
``Annotated`` alias, so its flag, bounds and help read the same everywhere.
"""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from dronetrack.config.pipeline import TrackerKind

if TYPE_CHECKING:
    from dronetrack.config.run import ScenarioConfig

__all__ = [
    "MAX_PARTICLES",
    "ConfigOption",
    "ControlMode",
    "DroneOption",
    "FlightDurationOption",
    "FoxgloveOption",
    "ParticlesOption",
    "RerunOption",
    "RunDirOption",
    "SeedOption",
    "SensorOption",
    "TrackerOption",
    "TrajectoryOption",
    "TurretMode",
    "TurretOption",
    "VisibilityOption",
    "scenario_from_options",
]

# Options shared by several commands.
SeedOption = Annotated[int | None, typer.Option("--seed", min=0, help="Random seed.")]
TrajectoryOption = Annotated[
    Path | None, typer.Option("--trajectory", help="CSV with columns t,x,y,z.")
]
VisibilityOption = Annotated[
    float | None, typer.Option("--visibility", help="Meteorological visibility, metres.")
]
DroneOption = Annotated[str | None, typer.Option("--drone", help="Target model.")]
SensorOption = Annotated[str | None, typer.Option("--sensor", help="Sensor model.")]
RunDirOption = Annotated[
    Path | None, typer.Option("--out", "-o", help="Output folder (default: runs/<timestamp>/).")
]
FlightDurationOption = Annotated[
    float | None,
    typer.Option(
        "--duration",
        "-d",
        min=0.01,
        help="Seconds of flight, after the background scan (scan_s, 10 s by default): "
        "the run lasts scan + flight.",
    ),
]
FoxgloveOption = Annotated[
    Path | None,
    typer.Option("--foxglove", help="Also write an MCAP file for Foxglove (extra: foxglove)."),
]
RerunOption = Annotated[
    Path | None, typer.Option("--rerun", help="Also write a Rerun .rrd file (extra: rerun).")
]


class TurretMode(StrEnum):
    truth = "truth"
    fixed = "fixed"


class ControlMode(StrEnum):
    tracking = "tracking"
    fixed = "fixed"
    truth = "truth"
    sweep = "sweep"
    swing = "swing"
    slowdown = "slowdown"
    stop = "stop"
    adaptive = "adaptive"


MAX_PARTICLES = 2_000_000  # the configuration's upper bound ([pipeline.tracker] particles)
# The choices are config.pipeline.TrackerKind, the one list of tracker names.
TrackerOption = Annotated[
    TrackerKind | None,
    typer.Option("--tracker", help="The tracking method (see the README's method table)."),
]
TurretOption = Annotated[
    ControlMode | None,
    typer.Option(
        "--turret",
        help="Track the estimate, hold still, follow the true target, "
        "or run one of seed 003's scan strategies.",
    ),
]
ParticlesOption = Annotated[
    int | None,
    typer.Option(
        "--particles",
        min=10,
        max=MAX_PARTICLES,
        help=f"Particle count, 10 to {MAX_PARTICLES:,} (default: the tracker's).",
    ),
]
ConfigOption = Annotated[
    Path | None,
    typer.Option(
        "--config",
        help="A full configuration to run again (a run's config.toml, or a scenario or site "
        ".toml); the other options override it.",
    ),
]


def scenario_from_options(
    scenario: str | None, config: Path | None, **overrides: Any
) -> ScenarioConfig:
    """The scenario a command's SCENARIO argument or --config names (not both), with the
    command line's overrides (see ``apply_overrides``)."""
    from dronetrack.config.run import apply_overrides, load_scenario_file
    from dronetrack.config.scenarios import SCENARIOS, get_scenario
    from dronetrack.errors import ConfigError

    if config is not None and scenario is not None:
        raise ConfigError("give a SCENARIO or --config, not both")
    base = load_scenario_file(config, SCENARIOS) if config else get_scenario(scenario or "default")
    return apply_overrides(base, **overrides)
