"""``dronetrack compare``: every method of a seed's table on the same seeded scenarios."""

from __future__ import annotations

from typing import Annotated

import typer

from dronetrack.cli.app import app
from dronetrack.cli.options import RunDirOption
from dronetrack.cli.output import print_markdown, progress_bar
from dronetrack.experiments.compare.suites import SUITES

__all__ = ["compare"]


_Suite = Annotated[
    str, typer.Option("--suite", help=f"{', '.join(list(SUITES)[:-1])} or {list(SUITES)[-1]}.")
]
_Runs = Annotated[int, typer.Option("--runs", min=1, help="Seeded runs per method.")]
_Duration = Annotated[
    float | None,
    typer.Option(
        "--duration",
        "-d",
        min=0.01,
        help="Shorten every flight to these seconds.",
        show_default="the suite's",
    ),
]
_Methods = Annotated[
    str | None,
    typer.Option(
        "--methods",
        help="Comma-separated subset of the suite's methods.",
        show_default="all of them",
    ),
]


@app.command()
def compare(
    suite: _Suite,
    runs: _Runs = 5,
    out: RunDirOption = None,
    duration: _Duration = None,
    methods: _Methods = None,
) -> None:
    """Run every method of a suite on the same seeded scenarios, side by side.

    A suite is a seed's table, acquisition or multi.  Writes table.csv
    (scenario,method,metric,mean,std,paper), table.md, results.jsonl (one line per
    run), for multi confusion.md (each scenario's class confusion matrix) and, for
    seed003, the seed's CSV logs of every run.
    """

    from dronetrack.experiments.compare.run_files import write_run_files
    from dronetrack.experiments.compare.runner import run_suite
    from dronetrack.experiments.compare.suites import get_suite
    from dronetrack.experiments.compare.tables import aggregate, write_tables
    from dronetrack.sinks.run_folder import check_run_dir, default_run_dir

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
    paths = [*write_tables(chosen, rows, out_dir, runs=runs, duration=duration, methods=ran)]
    paths += write_run_files(chosen, results, out_dir, runs=runs, duration=duration, methods=ran)
    print_markdown(out_dir / "table.md")
    for p in paths:
        typer.echo(str(p))
