"""What the commands print: progress bars and the metrics table (rich).

Results go to standard output; progress and warnings to standard error.
"""

from __future__ import annotations

from pathlib import Path

from rich.console import Console
from rich.progress import ProgressColumn

__all__ = ["err_console", "print_metrics", "progress_columns"]

err_console = Console(stderr=True)


def progress_columns() -> tuple[ProgressColumn, ...]:
    """A progress bar with percentage and time left."""
    from rich.progress import BarColumn, TextColumn, TimeRemainingColumn

    return (
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.percentage:>3.0f}%"),
        TimeRemainingColumn(),
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
        (
            "step time mean / std / max",
            " / ".join(
                fmt(metrics.get(k), "", 2) for k in ("step_ms_mean", "step_ms_std", "step_ms_max")
            )
            + " ms",
        ),
        ("speed", fmt(metrics.get("realtime_factor"), "× real time", 1)),
    ]
    for name, value in rows:
        table.add_row(name, value)
    Console().print(table)
    bad = metrics.get("bad_frames")
    if isinstance(bad, dict) and bad:
        err_console.print("frames with problems: " + ", ".join(f"{k} {v}" for k, v in bad.items()))
