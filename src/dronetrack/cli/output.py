"""What the commands print: progress bars and the metrics table (rich).

Results go to standard output; progress and warnings to standard error.  While a
command runs, the log records of dronetrack's loggers (and those handed on to them,
such as foxglove-sdk's) from warnings up are one ``warning: …`` line each there
(``console_logging``).
"""

from __future__ import annotations

import logging
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import ProgressColumn

if TYPE_CHECKING:
    from rich.progress import Progress, TaskID

    from dronetrack.pipeline.kernels import CompileProgress, KernelWarmUp

__all__ = [
    "COMPILING",
    "compile_reporter",
    "console_logging",
    "err_console",
    "print_kernel_note",
    "print_markdown",
    "print_metrics",
    "progress_bar",
    "progress_columns",
]

COMPILING = "compiling kernels, first run only"

# No line of ours is wrapped at 80 columns in a pipe or a log file: a terminal wraps
# on screen (soft_wrap).
err_console = Console(stderr=True, soft_wrap=True)


class _WarningLines(logging.Handler):
    """A record as one ``warning: …`` line on standard error (above a progress bar)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = " ".join(record.getMessage().split())
            err_console.print(f"warning: {text}", markup=False, highlight=False, soft_wrap=True)
        except Exception:  # a log line must never end a command
            self.handleError(record)


@contextmanager
def console_logging(logger: str = "dronetrack") -> Iterator[None]:
    """While inside: ``logger``'s records from warnings up are ``warning: …`` lines."""
    handler = _WarningLines(logging.WARNING)
    target = logging.getLogger(logger)
    target.addHandler(handler)
    try:
        yield
    finally:
        target.removeHandler(handler)


def progress_columns() -> tuple[ProgressColumn, ...]:
    """A progress bar with percentage and time left."""
    from rich.progress import BarColumn, TextColumn, TimeRemainingColumn

    return (
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.percentage:>3.0f}%"),
        TimeRemainingColumn(),
    )


def progress_bar(*, transient: bool = True, columns: bool = True) -> Progress:
    """A rich progress bar on standard error, shown only on a terminal: elsewhere (CI,
    a pipe, a log file) it prints nothing, not even a blank line."""
    from rich.progress import Progress

    return Progress(
        *(progress_columns() if columns else ()),
        console=err_console,
        transient=transient,
        disable=not err_console.is_terminal,
    )


def compile_reporter(bar: Progress, task: TaskID) -> CompileProgress:
    """A ``compiling`` callback for the run functions: once a kernel is found missing
    from numba's cache, one line (``COMPILING``) above the bar, and the bar counts the
    warm-up steps; a warm cache shows nothing but the bar."""
    said = False

    def report(done: int, total: int, compiled: bool) -> None:
        nonlocal said
        if compiled and not said:
            bar.console.print(COMPILING)
            said = True
        bar.update(task, completed=done, total=total)

    return report


def print_kernel_note(kernels: KernelWarmUp) -> None:
    """After a run whose warm-up compiled kernels: how long that took, and that it is once."""
    if kernels.compiled:
        err_console.print(
            f"compiled {kernels.compiled} kernel signatures in {kernels.seconds:.1f} s "
            "before the run (not counted in its step times); later runs load them from "
            "numba's cache"
        )


def print_markdown(path: Path) -> None:
    """A Markdown file on standard output as it is written: no line is wrapped (a
    table row stays one row), so a pipe or a redirect gets the file itself, and a
    terminal wraps long lines on screen only."""
    text = path.read_text()
    sys.stdout.write(text if text.endswith("\n") else text + "\n")
    sys.stdout.flush()


def _reacquisitions(times: object) -> str:
    """``reacquire_s`` in a line: how many losses, the worst time, how many never ended."""
    if not isinstance(times, list) or not times:
        return "no losses"
    done = [t for t in times if t is not None]
    worst = f", worst {max(done):.1f} s" if done else ""
    missed = len(times) - len(done)
    return f"{len(times)} loss{'es' if len(times) > 1 else ''}{worst}" + (
        f", {missed} not re-acquired" if missed else ""
    )


def print_metrics(metrics: dict[str, object], out_dir: Path) -> None:
    from rich.table import Table

    def fmt(value: object, unit: str = "", digits: int = 3) -> str:
        if value is None:
            return "n/a"
        if isinstance(value, float):
            return f"{value:.{digits}f}{unit}"
        if isinstance(value, list):
            return "[" + ", ".join(fmt(v, "", digits) for v in value) + "]" + unit
        return f"{value}{unit}"

    table = Table(title=f"metrics ({out_dir})", show_header=False)
    rows = [
        ("frames", fmt(metrics.get("frames"))),
        ("coverage", fmt(metrics.get("coverage_pct"), " %", 1)),
        ("max tracking distance", fmt(metrics.get("max_tracking_distance_m"), " m", 1)),
        ("RMSE (from the first lock)", fmt(metrics.get("rmse_m"), " m")),
        ("RMSE 95 % interval", fmt(metrics.get("rmse_ci95_m"), " m")),
        ("RMSE x, y, z", fmt(metrics.get("rmse_xyz_m"), " m")),
        ("RMSE while tracked", fmt(metrics.get("rmse_tracked_m"), " m")),
        ("first lock", fmt(metrics.get("first_lock_s"), " s", 1)),
    ]
    if "lock_on_visible_pct" in metrics:
        rows.append(("acquired after first returns", fmt(metrics.get("acquire_s"), " s", 1)))
        if "acquire_in_reach_s" in metrics:
            within = fmt(metrics.get("acquire_in_reach_s"), " s", 1)
            rows.append(("acquired after returns within reach", within))
        rows += [
            ("re-acquisitions", _reacquisitions(metrics.get("reacquire_s"))),
            ("locked on while visible", fmt(metrics.get("lock_on_visible_pct"), " %", 1)),
        ]
    if "false_lock_pct" in metrics:
        rows.append(("false locks", fmt(metrics.get("false_lock_pct"), " %", 1)))
    if "lock_transfers" in metrics:
        rows.append(("locks carried off the drone", fmt(metrics.get("lock_transfers"))))
    rows += [
        (
            "step time mean / std / max",
            " / ".join(
                fmt(metrics.get(k), "", 2) for k in ("step_ms_mean", "step_ms_std", "step_ms_max")
            )
            + " ms",
        ),
        ("speed", fmt(metrics.get("realtime_factor"), "× real time", 1)),
    ]
    if "frames_dropped" in metrics:  # a live run
        rows += [
            (
                "latency p50 / p99",
                " / ".join(fmt(metrics.get(k), "", 1) for k in ("latency_ms_p50", "latency_ms_p99"))
                + " ms",
            ),
            ("frames dropped", fmt(metrics.get("frames_dropped"))),
            (
                "packets lost / malformed",
                f"{fmt(metrics.get('packets_lost'))} / {fmt(metrics.get('packets_malformed'))}",
            ),
        ]
    for name, value in rows:
        table.add_row(name, value)
    Console().print(table)
    bad = metrics.get("bad_frames")
    if isinstance(bad, dict) and bad:
        err_console.print("frames with problems: " + ", ".join(f"{k} {v}" for k, v in bad.items()))
