"""Recorded scan patterns: replaying a table of beam directions.

``load_pattern_table`` reads Livox's scan-pattern CSV (or an ``.npy`` array of
azimuth and elevation) and ``TablePattern`` fires its rows in turn at a fixed
point rate.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from dronetrack.errors import SensorError
from dronetrack.formats.tables import read_csv_columns
from dronetrack.geometry.transforms import FloatArray, direction_from_azimuth_elevation
from dronetrack.sim.pulses import Pulses, pulse_indices

__all__ = ["TablePattern", "load_pattern_table"]


@dataclass(frozen=True, slots=True)
class TablePattern:
    """Replays a recorded scan-pattern table: row k mod rows at t_k = k / rate."""

    azimuth: FloatArray  # (M,) [rad]
    elevation: FloatArray  # (M,) [rad]
    rate_hz: float
    n_lines: int = 1
    _dirs: FloatArray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if self.rate_hz <= 0:
            raise SensorError(f"pattern point rate must be positive, got {self.rate_hz:g}")
        if self.n_lines < 1:
            raise SensorError(f"pattern line count must be at least 1, got {self.n_lines}")
        object.__setattr__(
            self, "_dirs", direction_from_azimuth_elevation(self.azimuth, self.elevation)
        )

    def pulses(self, t_start: float, t_end: float) -> Pulses:
        k = pulse_indices(t_start, t_end, self.rate_hz)
        dirs = self._dirs[k % len(self._dirs)]
        line = (k % self.n_lines).astype(np.uint8)
        return Pulses(t=k / self.rate_hz, dirs=dirs, line=line, origins=np.zeros_like(dirs))


def load_pattern_table(path: Path) -> tuple[FloatArray, FloatArray]:
    """Azimuth and elevation [rad] from a scan-pattern file.

    Accepts the CSV of Livox's livox_laser_simulation (header
    ``Time/s,Azimuth/deg,Zenith/deg``; zenith is measured from +z, so elevation
    = 90° − zenith; the time column is ignored, as in the Livox plugin) or an
    (N, 2) ``.npy`` of azimuth and elevation in radians.
    """
    if not path.is_file():
        raise SensorError(f"scan-pattern file not found: {path}")
    if path.suffix.lower() == ".npy":
        try:
            table = np.load(path, allow_pickle=False)
        except (ValueError, OSError) as err:
            raise SensorError(f"cannot read scan-pattern array {path}: {err}") from err
        if table.ndim != 2 or table.shape[1] != 2 or len(table) == 0:
            raise SensorError(
                f"scan-pattern array {path} must have shape (N, 2), got {table.shape}"
            )
        if not np.issubdtype(table.dtype, np.number):
            raise SensorError(f"scan-pattern array {path} must hold numbers, got {table.dtype}")
        az, el = table[:, 0].astype(np.float64), table[:, 1].astype(np.float64)
    else:
        az, el = _read_livox_csv(path)
    if not (np.all(np.isfinite(az)) and np.all(np.isfinite(el))):
        raise SensorError(f"scan-pattern file {path} contains NaN or infinite angles")
    if np.any(np.abs(el) > np.pi / 2 + 1e-9):
        raise SensorError(f"scan-pattern file {path} has elevations beyond ±90°")
    return az, el


def _read_livox_csv(path: Path) -> tuple[FloatArray, FloatArray]:
    data = read_csv_columns(path, ("Azimuth/deg", "Zenith/deg"), SensorError, "scan-pattern CSV")
    return np.radians(data[:, 0]), np.radians(90.0 - data[:, 1])
