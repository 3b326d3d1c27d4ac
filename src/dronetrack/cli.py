"""The ``dronetrack`` command line: parse, build, call, report, exit code.

Errors the user can fix (bad names, files, values) print one ``error:`` line
and exit with code 2.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import numpy as np
import typer
from rich.console import Console

from dronetrack import __version__
from dronetrack.cli_options import (
    ConfigOption,
    DroneOption,
    FlightDurationOption,
    FoxgloveOption,
    ParticlesOption,
    RerunOption,
    RunDirOption,
    SeedOption,
    SensorOption,
    TrackerOption,
    TrajectoryOption,
    TurretMode,
    TurretOption,
    VisibilityOption,
    scenario_from_options,
)
from dronetrack.cli_output import (
    compile_reporter,
    err_console,
    print_kernel_note,
    print_metrics,
    progress_bar,
)
from dronetrack.errors import DronetrackError

if TYPE_CHECKING:
    from dronetrack.io.view import ViewerSink
    from dronetrack.simulate import RunFolder, SimulationRun

__all__ = [
    "app",
    "main",
    "report_run",
    "run",
    "run_outputs",
    "stop_if_interrupted",
]

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    context_settings={"help_option_names": ["-h", "--help"]},
    pretty_exceptions_enable=False,
    rich_markup_mode="rich",
    help="Detect and track small drones with LiDAR on a pan-tilt turret.",
)


def _version(value: bool) -> None:
    if value:
        typer.echo(f"dronetrack {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="Print the version and exit."
        ),
    ] = False,
) -> None:
    """Detect and track small drones with LiDAR on a pan-tilt turret."""


@app.command()
def scenarios(
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="Add each scenario's description.")
    ] = False,
) -> None:
    """List the named scenarios, one per line."""
    from dronetrack.sim.scenarios import SCENARIOS

    width = max(len(n) for n in SCENARIOS)
    for name, cfg in SCENARIOS.items():
        typer.echo(f"{name:<{width}}  {cfg.description}" if verbose else name)


@app.command()
def pattern(
    sensor: Annotated[
        str,
        typer.Argument(
            help="avia, mid40, mid360, vlp16, vlp16-side, or file:PATH (Livox CSV / .npy)"
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
    rpm: Annotated[float | None, typer.Option("--rpm", help="VLP-16 spin rate, 300-1200.")] = None,
) -> None:
    """Write a sensor's scan directions (sensor frame: x forward, y left, z up) as CSV.

    Columns: t_s, azimuth_deg, elevation_deg, line.
    """
    from dronetrack.errors import ConfigError
    from dronetrack.geometry import azimuth_elevation
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


@app.command()
def render(
    scenario: Annotated[
        str, typer.Argument(help="A scenario name (see 'dronetrack scenarios') or a .toml file.")
    ],
    out: Annotated[Path, typer.Option("--out", "-o", help="Output folder.")],
    duration: Annotated[
        float | None,
        typer.Option(
            "--duration",
            "-d",
            min=0.01,
            help="Seconds of flight to render (default: the scenario's); unlike simulate, "
            "no background scan comes first, so this is the whole rendering.",
        ),
    ] = None,
    seed: SeedOption = None,
    turret: Annotated[
        TurretMode, typer.Option("--turret", help="Follow the true target, or hold still.")
    ] = TurretMode.truth,
    trajectory: TrajectoryOption = None,
    visibility: VisibilityOption = None,
    drone: DroneOption = None,
    sensor: SensorOption = None,
    noise: Annotated[
        bool | None,
        typer.Option(
            "--noise/--no-noise", help="Sensor noise and false alarms (default: the scenario's)."
        ),
    ] = None,
) -> None:
    """Simulate a scenario and write its frames, ground truth and a PNG preview.

    Writes frames.npz (points x, y, z in the sensor frame, t, line, intensity,
    hit_target, frame, world points, sensor poses, target pose), frames.csv
    (one row per frame), scenario.toml (the resolved scenario) and preview.png.
    """

    from dronetrack.io.runs import check_run_dir
    from dronetrack.render import render_scenario, write_rendering
    from dronetrack.sim.scenario import apply_overrides
    from dronetrack.sim.scenarios import get_scenario

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
    scenario: Annotated[
        str | None,
        typer.Argument(help="A scenario name or .toml file (default: 'default')."),
    ] = None,
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
) -> None:
    """Run the closed loop: scan the background, then detect, track and follow the drone.

    Writes config.toml (the resolved configuration: re-run it with --config),
    frames.csv, metrics.json and plots to the output folder, and prints the metrics.
    """

    from dronetrack.io.runs import default_run_dir
    from dronetrack.simulate import RunFolder, run_simulation, simulation_viewer_hook

    cfg = scenario_from_options(
        scenario,
        config,
        seed=seed,
        duration=duration,
        trajectory=trajectory,
        visibility=visibility,
        drone=drone,
        sensor=sensor,
        tracker=tracker.value if tracker else None,
        particles=particles,
        turret_mode=turret.value if turret else None,
    )
    folder = RunFolder(out if out is not None else default_run_dir())
    with run_outputs(folder, foxglove, rerun) as viewers, progress_bar() as bar:
        task = bar.add_task(f"simulating {cfg.name}", total=None)
        run = run_simulation(
            cfg,
            progress=lambda i, n: bar.update(task, completed=i, total=n),
            on_frame=simulation_viewer_hook(viewers, cfg) if viewers else None,
            compiling=compile_reporter(bar, task),
            log_sink=folder.log_sink,
        )
    report_run(folder, run, folder.finish(run))


@app.command()
def compare(
    suite: Annotated[
        str,
        typer.Option(
            "--suite",
            help="seed000-outdoor, seed000-ablation, seed000-indoor, seed002 or seed003.",
        ),
    ],
    runs: Annotated[int, typer.Option("--runs", min=1, help="Seeded runs per method.")] = 5,
    out: RunDirOption = None,
    duration: Annotated[
        float | None,
        typer.Option("--duration", "-d", min=0.01, help="Shorten every flight to these seconds."),
    ] = None,
    methods: Annotated[
        str | None,
        typer.Option("--methods", help="Comma-separated subset of the suite's methods."),
    ] = None,
) -> None:
    """Run every method of a seed's table on the same seeded scenarios, side by side.

    Writes table.csv (scenario,method,metric,mean,std,paper), table.md and, for
    seed003, the seed's CSV logs of every run.
    """

    from dronetrack.compare.runner import run_suite
    from dronetrack.compare.suites import get_suite
    from dronetrack.compare.tables import aggregate, write_tables
    from dronetrack.io.runs import check_run_dir, default_run_dir

    chosen = get_suite(suite)
    subset = [m.strip() for m in methods.split(",") if m.strip()] if methods else None
    out_dir = check_run_dir(out if out is not None else default_run_dir())
    with progress_bar() as bar:
        task = bar.add_task(chosen.name, total=None)

        def report(what: str, i: int, n: int) -> None:
            bar.update(task, description=f"{chosen.name}: {what}", completed=i, total=n)

        results = run_suite(
            chosen,
            runs,
            duration=duration,
            methods=subset,
            log_dir=out_dir / "logs" if chosen.tracker is not None else None,
            progress=report,
        )
    rows = aggregate(chosen, results)
    ran = tuple(dict.fromkeys(r.method for r in results))
    paths = write_tables(chosen, rows, out_dir, runs=runs, duration=duration, methods=ran)
    Console().print((out_dir / "table.md").read_text(), markup=False, highlight=False)
    for p in paths:
        typer.echo(str(p))


def run(argv: list[str] | None = None) -> int:
    """Run the command line with ``argv``; return the exit code.

    Ctrl-C ends a running loop after its current frame (``dronetrack.interrupt``); the
    command keeps what it had done and exits with 130 after one ``interrupted`` line.
    """
    from dronetrack.interrupt import handling_sigint

    if argv is not None and not argv:
        argv = ["--help"]  # bare `dronetrack`: the help, and no error
    command = typer.main.get_command(app)
    try:
        with handling_sigint():
            result = command.main(args=argv, prog_name="dronetrack", standalone_mode=False)
    except typer.Exit as stop:
        return int(stop.exit_code)
    except RunInterruptedError as stop:
        return _interrupted(str(stop))
    except (typer.Abort, KeyboardInterrupt):
        return _interrupted()
    except typer.TyperException as err:  # usage errors: unknown option, missing argument, ...
        describe = getattr(err, "format_message", None)
        message = describe() if callable(describe) else str(err)
        return _error(message)
    except (DronetrackError, OSError) as err:
        return _error(str(err))
    except SystemError as err:  # Ctrl-C inside numba's compiler surfaces as SystemError
        if _caused_by_interrupt(err):
            return _interrupted()
        raise
    if result == INTERRUPTED:  # typer turns a KeyboardInterrupt into this exit code
        return _interrupted()
    return int(result) if isinstance(result, int) else 0


class RunInterruptedError(DronetrackError):
    """A command whose loop Ctrl-C stopped, after it wrote what it had; the message
    ends the ``interrupted`` line."""


INTERRUPTED = 130  # 128 + SIGINT, as a shell reports a command killed by Ctrl-C


def _error(message: str) -> int:
    err_console.print(f"error: {message}", markup=False, highlight=False, soft_wrap=True)
    return 2


def _interrupted(note: str = "") -> int:
    err_console.print(f"interrupted{note}", markup=False, highlight=False, soft_wrap=True)
    return INTERRUPTED


def _caused_by_interrupt(err: BaseException) -> bool:
    seen: set[int] = set()
    cause: BaseException | None = err
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            return True
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return False


@contextmanager
def run_outputs(
    folder: RunFolder, foxglove: Path | None, rerun: Path | None, start: float = 0.0
) -> Iterator[list[ViewerSink]]:
    """The viewer files a run writes besides its folder, closed after the block; if
    the block fails, or Ctrl-C stops it at once, the folder keeps the frames done."""
    from dronetrack.io.viewers import close_viewers, open_viewers

    try:
        viewers = open_viewers(foxglove, rerun, start=start)
        try:
            yield viewers
        finally:
            close_viewers(viewers)
    except BaseException:
        folder.close()
        raise


def report_run(folder: RunFolder, run: SimulationRun, metrics: dict[str, Any]) -> None:
    """After a run's folder is written: the kernels' compile time if it compiled, then
    one ``interrupted`` line (exit 130) if Ctrl-C ended it, else the metrics table."""
    print_kernel_note(run.kernels)
    stop_if_interrupted(run.interrupted, f"; kept {len(run.log)} frames in {folder.out_dir}")
    print_metrics(metrics, folder.out_dir)


def stop_if_interrupted(interrupted: bool, note: str = "") -> None:
    """End a command whose loop Ctrl-C stopped (after it wrote what it had): one
    ``interrupted`` line, ending with ``note``, and exit code 130."""
    if interrupted:
        raise RunInterruptedError(note)


def main() -> None:
    """Console-script entry point."""
    from dronetrack.allocator import tune_allocator

    tune_allocator()
    sys.exit(run(sys.argv[1:]))


# The recording (track, info, record), sweep and bench commands register on ``app``.
from dronetrack import cli_bench, cli_recordings, cli_sweep  # noqa: E402, F401
