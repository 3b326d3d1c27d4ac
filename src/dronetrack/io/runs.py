"""Run folders: config.toml, frames.csv, metrics.json and plots."""

from __future__ import annotations

import csv
import json
import math
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.eval.log import EXTRA_COLUMNS, FRAME_COLUMNS, TrackLog

__all__ = ["default_run_dir", "json_safe", "write_frames_csv", "write_metrics", "write_plots"]


def default_run_dir(root: Path = Path("runs")) -> Path:
    """``runs/<timestamp>/``, with a suffix if that folder exists already."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    out = root / stamp
    k = 1
    while out.exists():
        out = root / f"{stamp}-{k}"
        k += 1
    return out


def write_frames_csv(log: TrackLog, path: Path) -> None:
    """One row per frame: the FRAME_COLUMNS contract, then ``flags``, then EXTRA_COLUMNS."""
    a = log.arrays()
    with path.open("w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow([*FRAME_COLUMNS, "flags", *EXTRA_COLUMNS])
        integer = ("tracked", "n_points", "n_target_points", "measured")
        for i in range(len(log)):
            row: list[Any] = []
            for col in (*FRAME_COLUMNS, "flags", *EXTRA_COLUMNS):
                v = a[col][i]
                if col == "flags":
                    row.append(v)
                elif col in integer:
                    row.append(int(v))
                else:
                    row.append(_number(float(v)))
            writer.writerow(row)


def _number(v: float) -> str:
    return (
        "nan"
        if math.isnan(v)
        else f"{v:.6g}"
        if abs(v) >= 1e5
        else f"{v:.6f}".rstrip("0").rstrip(".")
    )


def json_safe(value: Any) -> Any:
    """``value`` with numpy scalars as Python numbers and non-finite floats as None."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, float | np.floating):
        f = float(value)
        return f if math.isfinite(f) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def write_metrics(metrics: dict[str, Any], path: Path) -> None:
    """metrics.json (non-finite numbers become null)."""
    path.write_text(json.dumps(json_safe(metrics), indent=2) + "\n")


def write_plots(
    log: TrackLog, out_dir: Path, threshold: float, title: str, radius: float, kind: str
) -> list[Path]:
    """The seed-style figures: top view, error and spread, points against distance;
    ``radius``: an estimate this close to the truth is correct [m]; ``kind``: the
    tracker (config ``pipeline.tracker.kind``), which says what its spread is."""
    from dronetrack.eval.plots import (
        plot_error_and_spread,
        plot_points_vs_distance,
        plot_top_view,
        spread_label,
    )

    a = log.arrays()
    paths = [
        out_dir / "top_view.png",
        out_dir / "error_sigma.png",
        out_dir / "points_vs_distance.png",
    ]
    if len(log) == 0:
        return []
    plot_top_view(a, paths[0], f"{title}: truth, estimate and returned points", radius)
    plot_error_and_spread(
        a, threshold, paths[1], f"{title} ({kind}): error and {spread_label(kind)}", kind=kind
    )
    plot_points_vs_distance(a, paths[2], f"{title}: points on the target against range")
    return paths
