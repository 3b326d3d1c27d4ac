"""``dronetrack simulate``, ``scenarios``, ``pattern`` and ``render``: the simulator's commands."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from dronetrack.cli.app import app, report_run, run_outputs, site_outputs
from dronetrack.cli.options import (
    SCENARIOS_OWN,
    ConfigOption,
    DroneOption,
    FlightDurationOption,
    FoxgloveOption,
    ParticlesOption,
    PublishOption,
    RerunOption,
    RosDomainOption,
    RunDirOption,
    SapientOption,
    ScenarioArgument,
    SeedOption,
    SensorOption,
    TrackerOption,
    TrajectoryOption,
    TurretMode,
    TurretOption,
    VisibilityOption,
    scenario_from_options,
)
from dronetrack.cli.output import (
    compile_reporter,
    err_console,
    progress_bar,
)
from dronetrack.config.rig import SENSOR_MODELS
from dronetrack.config.spinning import DEFAULT_RPM

__all__ = ["pattern", "render", "scenarios", "simulate"]


@app.command()
def scenarios(
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="Add each scenario's description.")
    ] = False,
) -> None:
    """List the named scenarios, one per line."""
    from dronetrack.config.scenarios import SCENARIOS

    width = max(len(n) for n in SCENARIOS)
    for name, cfg in SCENARIOS.items():
        typer.echo(f"{name:<{width}}  {cfg.description}" if verbose else name)


@app.command()
def pattern(
    sensor: Annotated[
        str,
        typer.Argument(
            help=f"{', '.join(SENSOR_MODELS)}, or file:PATH (a scan pattern: a Livox CSV or "
            "an .npy of azimuths and elevations)."
        ),
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="CSV file to write.")],
    duration: Annotated[
        float,
        typer.Option(
            "--duration", "-d", min=0.0, max=3600.0, help="Seconds of pattern, more than 0."
        ),
    ] = 0.1,
    start: Annotated[
        float, typer.Option("--start", min=0.0, max=1e6, help="Start time, seconds.")
    ] = 0.0,
    rate: Annotated[
        float | None,
        typer.Option("--rate", min=1.0, help="Point rate of a file: pattern, points per second."),
    ] = None,
    lines: Annotated[
        int | None, typer.Option("--lines", min=1, help="Line count of a file: pattern.")
    ] = None,
    rpm: Annotated[
        float | None,
        typer.Option("--rpm", help="VLP-16 spin rate, 300-1200.", show_default=f"{DEFAULT_RPM:g}"),
    ] = None,
) -> None:
    """Write a sensor's scan directions (sensor frame: x forward, y left, z up) as CSV.

    Columns: t_s, azimuth_deg, elevation_deg, line.
    """
    from dronetrack.errors import ConfigError
    from dronetrack.geometry.transforms import azimuth_elevation
    from dronetrack.sim.sensors import make_sensor

    if not duration > 0:
        raise ConfigError(f"--duration must be more than 0 s, got {duration:g}")
    model = make_sensor(sensor, rpm=rpm, rate_hz=rate, lines=lines)
    pulses = model.pattern.pulses(start, start + duration)
    az, el = azimuth_elevation(pulses.dirs)
    out.parent.mkdir(parents=True, exist_ok=True)
    table = np.column_stack([pulses.t, np.degrees(az), np.degrees(el), pulses.line])
    np.savetxt(
        out,
        table,
        delimiter=",",
        fmt=("%.9f", "%.6f", "%.6f", "%d"),
        header="t_s,azimuth_deg,elevation_deg,line",
        comments="",
    )
    err_console.print(f"wrote {len(pulses)} directions of {model.name} to {out}")


_RenderScenario = Annotated[
    str, typer.Argument(help="A scenario name (see 'dronetrack scenarios') or a .toml file.")
]
_RenderOut = Annotated[Path, typer.Option("--out", "-o", help="Output folder.")]
_RenderDuration = Annotated[
    float | None,
    typer.Option(
        "--duration",
        "-d",
        min=0.01,
        help="Seconds of flight to render; unlike simulate, no background scan comes "
        "first, so this is the whole rendering.",
        show_default=SCENARIOS_OWN,
    ),
]
_RenderTurret = Annotated[
    TurretMode, typer.Option("--turret", help="Follow the true target, or hold still.")
]
_Noise = Annotated[
    bool | None,
    typer.Option(
        "--noise/--no-noise", help="Sensor noise and false alarms.", show_default=SCENARIOS_OWN
    ),
]


@app.command()
def render(
    scenario: _RenderScenario,
    out: _RenderOut,
    duration: _RenderDuration = None,
    seed: SeedOption = None,
    turret: _RenderTurret = TurretMode.truth,
    trajectory: TrajectoryOption = None,
    visibility: VisibilityOption = None,
    drone: DroneOption = None,
    sensor: SensorOption = None,
    noise: _Noise = None,
) -> None:
    """Simulate a scenario and write its frames, ground truth and a PNG preview.

    Writes frames.npz (points x, y, z in the sensor frame, t, line, intensity,
    hit_target, frame, world points, sensor poses, target pose), frames.csv
    (one row per frame), scenario.toml (the resolved scenario) and preview.png.
    """

    from dronetrack.config.run import apply_overrides
    from dronetrack.config.scenarios import get_scenario
    from dronetrack.jobs.render import render_scenario, write_rendering
    from dronetrack.sinks.run_folder import check_run_dir

    cfg = apply_overrides(
        get_scenario(scenario),
        seed=seed,
        duration=duration,
        trajectory=trajectory,
        visibility=visibility,
        drone=drone,
        sensor=sensor,
        noise=noise,
    )
    check_run_dir(out)
    with progress_bar(columns=False) as bar:
        task = bar.add_task(f"rendering {cfg.name}", total=None)
        rendering = render_scenario(
            cfg, turret.value, progress=lambda i, n: bar.update(task, completed=i, total=n)
        )
    paths = write_rendering(rendering, out)
    n_points = sum(len(f) for f in rendering.frames)
    n_target = sum(t.n_target_points for t in rendering.truths)
    err_console.print(
        f"{len(rendering.frames)} frames, {n_points} points, {n_target} on the target"
    )
    for p in paths:
        typer.echo(str(p))


@app.command()
def simulate(
    scenario: ScenarioArgument = None,
    tracker: TrackerOption = None,
    turret: TurretOption = None,
    particles: ParticlesOption = None,
    seed: SeedOption = None,
    duration: FlightDurationOption = None,
    config: ConfigOption = None,
    trajectory: TrajectoryOption = None,
    visibility: VisibilityOption = None,
    drone: DroneOption = None,
    sensor: SensorOption = None,
    out: RunDirOption = None,
    foxglove: FoxgloveOption = None,
    rerun: RerunOption = None,
    publish: PublishOption = None,
    ros_domain_id: RosDomainOption = None,
    sapient: SapientOption = None,
) -> None:
    """Run the closed loop: scan the background, then detect, track and follow the drone.

    Writes config.toml (the resolved configuration: re-run it with --config),
    frames.csv, metrics.json and plots to the output folder, and prints the metrics.
    """

    from dronetrack.config.rig import turret_spec
    from dronetrack.jobs.simulate import run_simulation
    from dronetrack.jobs.site import run_folder, site_view
    from dronetrack.sinks.view import ViewerFeed

    cfg = scenario_from_options(
        scenario,
        config,
        seed=seed,
        duration=duration,
        trajectory=trajectory,
        visibility=visibility,
        drone=drone,
        sensor=sensor,
        tracker=tracker,
        particles=particles,
        turret_mode=turret.value if turret else None,
    )
    folder = run_folder(out, cfg)
    # the turret's links for the viewers; on a moving observer, the sensor's pose alone
    mount = None if cfg.observer is not None else turret_spec(cfg.turret).mount
    outputs = run_outputs(
        folder, foxglove, rerun, publish=publish, ros_domain_id=ros_domain_id, site=site_view(cfg)
    )
    with outputs as viewers, site_outputs(cfg, folder, sapient) as site, progress_bar() as bar:
        task = bar.add_task(f"simulating {cfg.name}", total=None)
        run = run_simulation(
            cfg,
            progress=lambda i, n: bar.update(task, completed=i, total=n),
            sinks=[*([ViewerFeed(viewers, mount)] if viewers else []), *site],
            compiling=compile_reporter(bar, task),
            log_sink=folder.log_sink,
        )
    report_run(folder, run, folder.finish(run))
