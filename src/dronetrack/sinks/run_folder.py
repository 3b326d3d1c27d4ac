"""Run folders: config.toml, frames.csv, tracks.csv, metrics.json and plots."""

from __future__ import annotations

import csv
import json
import math
from datetime import datetime
from pathlib import Path
from typing import Any

import numpy as np

from dronetrack.errors import ConfigError
from dronetrack.eval.log import EXTRA_COLUMNS, FRAME_COLUMNS, TrackLog
from dronetrack.eval.tracks import TRACK_COLUMNS, TracksLog
from dronetrack.geometry.geodesy import SiteFrame
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TRACK_CLASSES

__all__ = [
    "FRAMES_CSV_COLUMNS",
    "GEO_COLUMNS",
    "STATE_COLUMNS",
    "FramesCsvWriter",
    "TracksCsvWriter",
    "check_run_dir",
    "default_run_dir",
    "frame_row",
    "geo_columns",
    "json_safe",
    "prepare_output_file",
    "prepare_run_dir",
    "write_metrics",
    "write_plots",
]


def default_run_dir(root: Path = Path("runs")) -> Path:
    """``runs/<timestamp>/``, with a suffix if that folder exists already."""
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S")
    out = root / stamp
    k = 1
    while out.exists():
        out = root / f"{stamp}-{k}"
        k += 1
    return out


FRAMES_CSV_COLUMNS = (*FRAME_COLUMNS, "flags", *EXTRA_COLUMNS)
# tracks.csv's columns after TRACK_COLUMNS: where each track is on the Earth (with a
# [site]) and from the turret.
GEO_COLUMNS = ("lat_deg", "lon_deg", "alt_m", "azimuth_deg", "elevation_deg", "range_m")
# ... and then whether a cluster of the frame updated the track (0: it coasted on its
# prediction) and whether it was in the sensor's field of view.
STATE_COLUMNS = ("updated", "in_view")


def frame_row(log: TrackLog, i: int) -> list[str]:
    """Row ``i`` of ``log`` as frames.csv writes it, in FRAMES_CSV_COLUMNS order."""
    r = log.row(i)
    gt, est = r["gt"], r["est"]
    numbers = (r["t"], gt[0], gt[1], gt[2], est[0], est[1], est[2])
    return [
        *(_number(float(v)) for v in numbers),
        str(int(r["tracked"])),
        _number(float(r["sigma"])),
        str(int(r["n_points"])),
        str(int(r["n_target_points"])),
        _number(float(r["range_m"])),
        _number(float(r["pan"])),
        _number(float(r["tilt"])),
        _number(float(r["step_ms"])),
        str(r["flags"]),
        _number(float(r["pos_var"])),
        _number(float(r["vel_var"])),
        str(int(r["measured"])),
        _number(float(r["meas_error"])),
        str(int(r["n_candidates"])),
        str(int(r["n_confirmed"])),
        _number(float(r["latency_ms"])),
    ]


class FramesCsvWriter:
    """frames.csv written as the run goes: the header at once, then each new row of
    the log, flushed, so an interrupted run keeps every frame it finished."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._fh = path.open("w", newline="")
        self._csv = csv.writer(self._fh)
        self._csv.writerow(FRAMES_CSV_COLUMNS)
        self._fh.flush()
        self.rows = 0

    def write(self, log: TrackLog) -> None:
        """Append the rows of ``log`` not written yet."""
        for i in range(self.rows, len(log)):
            self._csv.writerow(frame_row(log, i))
        self.rows = len(log)
        self._fh.flush()

    def close(self) -> None:
        self._fh.close()


class TracksCsvWriter:
    """tracks.csv written as the run goes (``TRACK_COLUMNS``: one row per track per
    tracking frame, then ``GEO_COLUMNS`` and ``STATE_COLUMNS``), flushed after each
    frame's rows.

    ``site`` places the world frame on the Earth: each row then has the track's WGS-84
    latitude, longitude and altitude and its azimuth from true north; without it those
    are nan.  Elevation and range are from the turret base (``base``, world) either way.
    """

    def __init__(
        self,
        path: Path,
        site: SiteFrame | None = None,
        base: tuple[float, float, float] = (0.0, 0.0, 0.0),
    ) -> None:
        self.path = path
        self.site = site
        self.base = site.base if site is not None else base
        self._fh = path.open("w", newline="")
        self._csv = csv.writer(self._fh)
        self._csv.writerow((*TRACK_COLUMNS, *GEO_COLUMNS, *STATE_COLUMNS))
        self._fh.flush()
        self.rows = 0

    def write(self, tracks: TracksLog) -> None:
        """Append the rows of ``tracks`` not written yet."""
        if len(tracks) == self.rows:
            return
        rows = tracks.rows[self.rows :]
        geo = geo_columns(rows["position"], self.site, self.base)
        for r, g in zip(rows, geo, strict=True):
            p, v = r["position"], r["velocity"]
            self._csv.writerow(
                [
                    _number(float(r["t"])),
                    str(int(r["id"])),
                    TRACK_CLASSES[int(r["cls"])],
                    _number(float(r["p_drone"])),
                    *(_number(float(a)) for a in (*p, *v)),
                    _number(float(r["pos_sigma"])),
                    str(int(r["locked"])),
                    *(_degrees(float(a)) for a in g[:2]),
                    *(_number(float(a)) for a in g[2:]),
                    str(int(r["updated"])),
                    str(int(r["in_view"])),
                ]
            )
        self.rows = len(tracks)
        self._fh.flush()

    def close(self) -> None:
        self._fh.close()


def geo_columns(
    positions: FloatArray, site: SiteFrame | None, base: tuple[float, float, float]
) -> FloatArray:
    """(N, 6) ``GEO_COLUMNS`` of world positions (N, 3): latitude, longitude [°],
    altitude [m], azimuth from true north, elevation [°] and range [m] from the turret
    base; the first four nan without a site."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    out = np.full((len(p), 6), np.nan)
    if site is not None:
        out[:, 0], out[:, 1], out[:, 2] = site.geodetic(p)
        out[:, 3], out[:, 4], out[:, 5] = site.aer(p)
    else:
        d = p - np.asarray(base)
        # el = atan2(d_z, √(d_x² + d_y²)),  r = ‖d‖
        out[:, 4] = np.degrees(np.arctan2(d[:, 2], np.hypot(d[:, 0], d[:, 1])))
        out[:, 5] = np.linalg.norm(d, axis=1)
    return out


def check_run_dir(path: Path, option: str = "--out") -> Path:
    """``path`` if the output folder can be created there (or exists); a one-line
    ``ConfigError`` when it, or one of its parents, is a file."""
    if path.exists() and not path.is_dir():
        raise ConfigError(f"{option} {path} is a file; give a folder (it is created if missing)")
    for parent in path.parents:
        if parent.exists():
            if not parent.is_dir():
                raise ConfigError(
                    f"{option} {path}: {parent} is a file, so the folder cannot be created"
                )
            break
    return path


def prepare_run_dir(path: Path, option: str = "--out") -> Path:
    """Create the output folder ``path`` (and its parents); a one-line ``ConfigError``
    when it is a file or cannot be created."""
    check_run_dir(path, option)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ConfigError(f"{option} {path}: cannot create the folder ({err.strerror})") from None
    return path


def prepare_output_file(path: Path, option: str) -> Path:
    """Check that the file ``path`` can be written: create its missing parent folders and
    open it for writing once; a one-line ``ConfigError`` naming the path if not."""
    if path.is_dir():
        raise ConfigError(f"{option} {path} is a folder; give a file name")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("ab"):
            pass
    except FileExistsError:
        raise ConfigError(
            f"{option} {path}: a parent of it is a file, so the file cannot be written"
        ) from None
    except OSError as err:
        raise ConfigError(f"{option} {path}: cannot write it ({err.strerror})") from None
    return path


def _degrees(v: float) -> str:
    """A latitude or longitude: 9 decimals, 0.1 mm on the ground."""
    return "nan" if math.isnan(v) else f"{v:.9f}"


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
