"""``dronetrack bench``: the benchmark suite on one core, its table and bench.json.

Registered on the ``dronetrack`` app by ``cli``; it follows its conventions (one
``error:`` line and exit code 2 for anything the user can fix).  The measuring is
``dronetrack.experiments.bench``'s; this module pins the thread pools, shows progress on
standard error, prints the table on standard output and writes the file.

One core: ``dronetrack.experiments.bench.single_thread`` sets numba's thread count with
``numba.set_num_threads(1)`` and every loaded BLAS/OpenMP pool's with threadpoolctl,
and restores them afterwards.  The environment variables (NUMBA_NUM_THREADS, ...)
are deliberately left alone: numpy and numba are loaded by then, and numba re-reads
its environment at every compilation, so changing NUMBA_NUM_THREADS after its
threads have started makes the next compilation fail (on a fresh install, with an
empty kernel cache, that is the first measurement).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated, Any

import typer
from rich import box
from rich.console import Console
from rich.table import Table

from dronetrack.cli.app import app
from dronetrack.cli.options import RunDirOption
from dronetrack.cli.output import progress_bar

__all__ = ["bench", "bench_table"]


def _target_cells(targets: dict[str, Any], key: str) -> tuple[str, str]:
    """The target column and the verdict of the measurement ``key`` (none: blank)."""
    target = targets.get(key)
    if target is None:
        return "", ""
    verdict = "[green]met[/green]" if target["met"] else "[bold red]MISSED[/bold red]"
    return f"≤ {target['limit']:g}", verdict


def bench_table(results: dict[str, Any], path: Path) -> Table:
    """The table ``dronetrack bench`` prints: the machine in the title, then every
    measurement with its statistics [ms] and, where it has one, its target."""
    m = results["machine"]
    s = results["settings"]
    quick = " (quick: a smoke test, not a measurement)" if s["quick"] else ""
    table = Table(
        title=(
            f"dronetrack bench: {m['cpu']}, {m['cores']} cores; Python {m['python']}, "
            f"numpy {m['numpy']}, numba {m['numba']}; one thread"
        ),
        caption=(
            f"times in ms, replay in multiples of real time; best of {s['rounds']} round(s) "
            f"of {s['repeats']} timed steps{quick}; {path}"
        ),
        box=box.SIMPLE_HEAD,
        pad_edge=False,
    )
    table.add_column("measurement", no_wrap=True)
    for name in ("median", "mean", "std", "max", "target", ""):
        table.add_column(name, justify="right", no_wrap=True)
    targets = results["targets"]

    def add(label: str, row: dict[str, float], key: str) -> None:
        values = [f"{row[k]:.2f}" for k in ("median", "mean", "std", "max")]
        table.add_row(label, *values, *_target_cells(targets, key))

    for n, row in results["pf_step_ms"].items():
        add(f"pipeline, {int(n):,} particles", row, f"pf_step_ms.{n}.median")
    table.add_section()
    for kind, row in results["tracker_step_ms"].items():
        add(f"tracker, {kind}", row, "")
    table.add_section()
    for sensor, row in results["sim_frame_stats_ms"].items():
        add(f"sim frame, {sensor}", row, f"sim_frame_ms.{sensor}")
    table.add_section()
    for key, row in results["replay_formats"].items():
        table.add_row(f"replay, {key}", f"{row['x_realtime']:.1f}×")
    table.add_row("replay, the slower", f"{results['replay_x_realtime']:.1f}×")
    return table


@app.command()
def bench(
    out: RunDirOption = None,
    rounds: Annotated[
        int | None,
        typer.Option("--rounds", min=1, help="Rounds per measurement; the best counts [3]."),
    ] = None,
    repeats: Annotated[
        int | None,
        typer.Option(
            "--repeats",
            min=1,
            help="Timed steps or frames per round (a fifth at 100,000 particles) [200].",
        ),
    ] = None,
    replay_seconds: Annotated[
        float | None,
        typer.Option(
            "--replay-seconds", help="Length of the replayed recording, at least 5 s [30]."
        ),
    ] = None,
    quick: Annotated[
        bool,
        typer.Option(
            "--quick", help="A smoke test: 5 steps, 1 round, a 5 s recording, unless given."
        ),
    ] = False,
) -> None:
    """Time the pipeline, every tracker, the simulator and replay on one core.

    Writes bench.json (pf_step_ms, tracker_step_ms, sim_frame_ms, replay_x_realtime,
    machine, targets) and prints a table that marks each speed target met or missed.
    """

    from dronetrack.sinks.run_folder import check_run_dir, default_run_dir, prepare_run_dir

    out_dir = check_run_dir(out if out is not None else default_run_dir())
    from dronetrack.experiments.bench import bench as run_bench
    from dronetrack.experiments.bench import single_thread

    with (
        single_thread(),
        progress_bar() as bar,
    ):
        task = bar.add_task("benchmarks", total=None)

        def report(what: str, done: int, total: int) -> None:
            bar.update(task, description=what, completed=done, total=total)

        results = run_bench(
            repeats=repeats,
            rounds=rounds,
            quick=quick,
            replay_s=replay_seconds,
            progress=report,
        )
    prepare_run_dir(out_dir)
    path = out_dir / "bench.json"
    path.write_text(json.dumps(results, indent=2, allow_nan=False) + "\n")
    Console().print(bench_table(results, path))
    typer.echo(str(path))
