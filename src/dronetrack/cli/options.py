"""The command line's shared options, names and scenario loading.

Each option that more than one command takes is defined here once, as an
``Annotated`` alias, so its flag, bounds and help read the same everywhere.
"""

from __future__ import annotations

from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, get_args

import typer

from dronetrack.config.pipeline import TrackerKind
from dronetrack.config.rig import SENSOR_MODELS, TARGETS

if TYPE_CHECKING:
    from dronetrack.config.run import ScenarioConfig

__all__ = [
    "MAX_PARTICLES",
    "SCENARIOS_OWN",
    "ConfigOption",
    "ControlMode",
    "DroneOption",
    "FlightDurationOption",
    "FoxgloveOption",
    "ParticlesOption",
    "PublishOption",
    "RerunOption",
    "RosDomainOption",
    "RunDirOption",
    "SapientOption",
    "ScenarioArgument",
    "SeedOption",
    "SensorOption",
    "TrackerOption",
    "TrajectoryOption",
    "TurretMode",
    "TurretOption",
    "VisibilityOption",
    "scenario_from_options",
]

SCENARIOS_OWN = "the scenario's"  # the default of an option that overrides a scenario

# Options shared by several commands.
ScenarioArgument = Annotated[
    str | None,
    typer.Argument(
        help="A scenario name (see 'dronetrack scenarios') or a .toml file.",
        show_default="'default'",
    ),
]
SeedOption = Annotated[
    int | None, typer.Option("--seed", min=0, help="Random seed.", show_default=SCENARIOS_OWN)
]
TrajectoryOption = Annotated[
    list[Path] | None,
    typer.Option(
        "--trajectory",
        metavar="<path>",
        help="The target's path: a CSV with columns t,x,y,z.  Repeat it to add drones: "
        "each further file is another drone of the scenario's model, from the start.",
        show_default=SCENARIOS_OWN,
    ),
]
VisibilityOption = Annotated[
    float | None,
    typer.Option(
        "--visibility", help="Meteorological visibility, metres.", show_default=SCENARIOS_OWN
    ),
]
DroneOption = Annotated[
    str | None,
    typer.Option(
        "--drone", help=f"Target model: {', '.join(TARGETS)}.", show_default=SCENARIOS_OWN
    ),
]
SensorOption = Annotated[
    str | None,
    typer.Option(
        "--sensor",
        help=f"Sensor model: {', '.join(SENSOR_MODELS)}, or file:PATH (a scan pattern: a "
        "Livox CSV or an .npy of azimuths and elevations).",
        show_default=SCENARIOS_OWN,
    ),
]
RunDirOption = Annotated[
    Path | None,
    typer.Option("--out", "-o", help="Output folder.", show_default="runs/<timestamp>/"),
]
FlightDurationOption = Annotated[
    float | None,
    typer.Option(
        "--duration",
        "-d",
        min=0.01,
        help="Seconds of flight, after the background scan (scan_s, 10 s by default): "
        "the run lasts scan + flight.",
        show_default=SCENARIOS_OWN,
    ),
]
FoxgloveOption = Annotated[
    Path | None,
    typer.Option("--foxglove", help="Also write an MCAP file for Foxglove (extra: foxglove)."),
]
RerunOption = Annotated[
    Path | None, typer.Option("--rerun", help="Also write a Rerun .rrd file (extra: rerun).")
]
RosDomainOption = Annotated[
    int | None,
    typer.Option(
        "--ros-domain-id",
        min=0,
        max=232,
        help="ROS 2 domain for everything this command does on ROS 2 (extra: ros2).",
        show_default="ROS_DOMAIN_ID, else 0",
    ),
]
PublishOption = Annotated[
    str | None,
    typer.Option(
        "--publish",
        help="ros2: publish the run for RViz on ROS 2 (estimate, track, particles, "
        "foreground, points, /tf; extra: ros2).",
    ),
]

SapientOption = Annotated[
    str | None,
    typer.Option(
        "--sapient",
        metavar="HOST:PORT",
        help="Send every track and zone alert to a SAPIENT (BSI Flex 335 v2.0) fusion node "
        "over TCP, and take its look-at tasks; needs the site's coordinates (extra: sapient).",
    ),
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
    typer.Option(
        "--tracker",
        metavar="<name>",
        help=f"The tracking method: {', '.join(get_args(TrackerKind))} (see the README's "
        "method table).",
        show_default=SCENARIOS_OWN,
    ),
]
TurretOption = Annotated[
    ControlMode | None,
    typer.Option(
        "--turret",
        metavar="<mode>",
        help="tracking (track the estimate), fixed (hold still), truth (follow the true "
        "target), or one of seed 003's scan strategies: sweep, swing, slowdown, stop, adaptive.",
        show_default=SCENARIOS_OWN,
    ),
]
ParticlesOption = Annotated[
    int | None,
    typer.Option(
        "--particles",
        min=10,
        max=MAX_PARTICLES,
        help=f"Particle count, 10 to {MAX_PARTICLES:,}.",
        show_default="the tracker's",
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
