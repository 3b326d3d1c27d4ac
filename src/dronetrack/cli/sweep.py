"""Commands for parameter sweeps: ``sweep`` and ``sweep-report``.

Registered on the ``dronetrack`` app by ``cli``.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any

import typer

from dronetrack.cli.app import app, stop_if_interrupted
from dronetrack.cli.options import RunDirOption
from dronetrack.cli.output import err_console, print_markdown, progress_bar

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID

__all__ = ["sweep", "sweep_report"]


_Grid = Annotated[Path, typer.Argument(help="The grid file (TOML; docs/commands.md, sweep).")]
_Workers = Annotated[
    int | None,
    typer.Option("--workers", min=1, help="Local worker processes.", show_default="one per core"),
]
_Scheduler = Annotated[
    str | None,
    typer.Option("--scheduler", help="An existing Dask cluster, tcp://HOST:PORT (extra: dask)."),
]


@app.command()
def sweep(
    grid: _Grid,
    workers: _Workers = None,
    scheduler: _Scheduler = None,
    out: RunDirOption = None,
) -> None:
    """Run every combination of a grid, each a closed-loop simulation or a replay.

    Results stream to DIR/results.jsonl, one line per run.  Run the same command
    again to resume: finished runs are skipped, so a finished sweep adds nothing.
    """
    from dronetrack.experiments.sweep.grid import planned_runs
    from dronetrack.experiments.sweep.runner import run_sweep, sweep_executor
    from dronetrack.experiments.sweep.store import RESULTS_FILE, ResultStore
    from dronetrack.sinks.run_folder import default_run_dir, prepare_run_dir

    runs = planned_runs(grid)
    with sweep_executor(workers, scheduler) as make:
        out_dir = prepare_run_dir(out if out is not None else default_run_dir())
        if not (out_dir / "grid.toml").exists():
            shutil.copyfile(grid, out_dir / "grid.toml")
        results = out_dir / RESULTS_FILE
        with progress_bar(transient=False) as bar:
            task = bar.add_task(f"sweep {grid.name}", total=len(runs))
            counts = run_sweep(runs, ResultStore(results), make, _reporter(bar, task, len(runs)))
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


def _reporter(bar: Progress, task: TaskID, runs: int) -> Callable[[int, int, dict[str, Any]], None]:
    """What the sweep calls after each run: the bar moves, a failed run is named, and
    without a terminal (CI, nohup) a line says how far it is now and then."""
    step = max(1, runs // 20)

    def report(done: int, total: int, row: dict[str, Any]) -> None:
        bar.update(task, completed=done, total=total)
        if "error" in row:
            failed = f"run {row['key']} failed: {row['error']}"
            bar.console.print(failed, markup=False, highlight=False, soft_wrap=True)
        elif row and not err_console.is_terminal and (done % step == 0 or done == total):
            err_console.print(f"{done}/{total} runs done")

    return report


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
