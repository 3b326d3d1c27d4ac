"""Commands for parameter sweeps: ``sweep`` and ``sweep-report``.

Registered on the ``dronetrack`` app by ``cli``.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path
from typing import Annotated, Any

import typer

from dronetrack.cli.app import app, stop_if_interrupted
from dronetrack.cli.options import RunDirOption
from dronetrack.cli.output import err_console, print_markdown, progress_bar
from dronetrack.errors import ConfigError

__all__ = ["sweep", "sweep_report"]


@app.command()
def sweep(
    grid: Annotated[Path, typer.Argument(help="The grid file (TOML; docs/commands.md, sweep).")],
    workers: Annotated[
        int | None,
        typer.Option(
            "--workers", min=1, help="Local worker processes.", show_default="one per core"
        ),
    ] = None,
    scheduler: Annotated[
        str | None,
        typer.Option(
            "--scheduler", help="An existing Dask cluster, tcp://HOST:PORT (extra: dask)."
        ),
    ] = None,
    out: RunDirOption = None,
) -> None:
    """Run every combination of a grid, each a closed-loop simulation or a replay.

    Results stream to DIR/results.jsonl, one line per run.  Run the same command
    again to resume: finished runs are skipped, so a finished sweep adds nothing.
    """

    from dronetrack.experiments.sweep.grid import check_keys, expand, load_grid
    from dronetrack.experiments.sweep.runner import dask_executor, local_executor, run_sweep
    from dronetrack.experiments.sweep.store import RESULTS_FILE, ResultStore
    from dronetrack.sinks.run_folder import default_run_dir, prepare_run_dir

    if scheduler is not None and workers is not None:
        raise ConfigError("give --workers or --scheduler, not both")
    spec = load_grid(grid)
    check_keys(spec, _base_config(spec), grid)
    runs = expand(spec)
    out_dir = prepare_run_dir(out if out is not None else default_run_dir())
    if not (out_dir / "grid.toml").exists():
        shutil.copyfile(grid, out_dir / "grid.toml")
    results = out_dir / RESULTS_FILE
    store = ResultStore(results)
    close = None
    if scheduler is not None:
        make, close = dask_executor(scheduler)
    else:
        make = local_executor(workers or os.cpu_count() or 1)
    try:
        with progress_bar(transient=False) as bar:
            task = bar.add_task(f"sweep {grid.name}", total=len(runs))

            step = max(1, len(runs) // 20)

            def report(done: int, total: int, row: dict[str, Any]) -> None:
                bar.update(task, completed=done, total=total)
                if "error" in row:
                    failed = f"run {row['key']} failed: {row['error']}"
                    bar.console.print(failed, markup=False, highlight=False, soft_wrap=True)
                elif row and not err_console.is_terminal and (done % step == 0 or done == total):
                    # No live bar without a terminal (CI, nohup): a line now and then.
                    err_console.print(f"{done}/{total} runs done")

            counts = run_sweep(runs, store, make, report)
    finally:
        if close is not None:
            close()
    summary = (
        f"{len(runs)} runs: {counts['done']} done now, {counts['skipped']} done before, "
        f"{counts['failed']} failed"
    )
    stop_if_interrupted(
        "unfinished" in counts,
        f"; {summary}, {counts['unfinished']} not run; results in {results} (run the same "
        "command again to resume)",
    )
    typer.echo(f"{summary}; results in {results}")


def _base_config(spec: Any) -> Any:
    """The configuration the grid varies: the named scenario, or the recording's own."""
    if spec.recording is not None:
        from dronetrack.jobs.replay import recording_config
        from dronetrack.sources.recordings.opener import open_recording

        rec = Path(spec.recording)
        return recording_config(open_recording(rec), None)
    from dronetrack.config.scenarios import get_scenario

    return get_scenario(spec.scenario or "default")


@app.command("sweep-report")
def sweep_report(
    folder: Annotated[
        Path,
        typer.Argument(
            metavar="FOLDER", help="A sweep's output folder, or the results.jsonl in it."
        ),
    ],
) -> None:
    """Report on a sweep: seed 000's Fig. 3 and a table of the best combinations.

    The figure plots coverage against maximum tracking distance, coloured by the
    distance from eq. (11).  Writes coverage_vs_distance.png, best.csv and report.md
    in the sweep's folder, and prints report.md.
    """
    from dronetrack.experiments.sweep.report import write_report

    _, paths = write_report(folder)
    print_markdown(next(p for p in paths if p.suffix == ".md"))
    for p in paths:
        typer.echo(str(p))
