"""A ``.las`` / ``.laz`` file (ASPRS LAS 1.0-1.4) as a recording.

A LAS file holds one table of point records after its header.  Every point
format stores integer X, Y, Z that the header's scale and offset turn into
metres (``x = X · scale + offset``), and a uint16 intensity; point formats 1
and 3-10 also store ``gps_time`` [s], either GPS week seconds or "adjusted
standard GPS time" (GPS seconds − 1e9), as the header's global encoding says.
LAZ is the same, compressed; reading it needs laspy's ``lazrs`` backend.

The reader keeps the scaled coordinates (float64), the intensity (float32, the
file's raw 0-65535 values) and the times.  With ``gps_time`` the points are
sorted by time and cut into frames of ``period`` seconds
(``ReplayOptions.period_s``, else 0.1 s) starting at the earliest time, which
is the recording's ``origin`` (in the file's GPS time, not Unix time); periods
without points give no frame, and points whose time is not finite are skipped
(``skipped["no_time"]``).  Without ``gps_time`` the whole file is one frame at
t = 0 (``origin`` 0).  LAS has no laser-line field, so ``line`` is zero.

The file is read in chunks when the recording is opened and its points kept in
memory (about 40 bytes a point).
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import MissingExtraError, RecordingError
from dronetrack.formats.magic import sniff_file
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sources.frames import fixed_pose_frame
from dronetrack.sources.recordings.recording import (
    PointFileRecording,
    RecordingInfo,
    ReplayOptions,
    TopicInfo,
    frame_period,
    identity_pose_warning,
    sensor_pose,
)
from dronetrack.types import Frame

__all__ = ["LasPoints", "LasRecording", "read_las"]

log = logging.getLogger(__name__)

_CHUNK_POINTS = 1_000_000


def _laspy() -> Any:
    """The laspy module, imported on first use."""
    try:
        import laspy  # type: ignore[import-untyped]
    except ImportError:
        raise MissingExtraError(
            "reading .las/.laz needs laspy: pip install 'dronetrack[las]'"
        ) from None
    return laspy


@dataclass(frozen=True, slots=True)
class LasPoints:
    """The points of a LAS file: positions (N, 3) [m], intensity (N,), GPS times (N,) [s]
    or None when the point format has none."""

    xyz: FloatArray
    intensity: NDArray[np.float32]
    gps_time: FloatArray | None
    point_format: int
    version: str


def read_las(path: Path, chunk_points: int = _CHUNK_POINTS) -> LasPoints:
    """Read a ``.las``/``.laz`` file's points; RecordingError if it does not read."""
    laspy = _laspy()
    xyz, intensity, gps_time = [], [], []
    has_time, point_format, version = False, -1, ""
    try:
        with laspy.open(path) as reader:
            header = reader.header
            point_format, version = int(header.point_format.id), str(header.version)
            has_time = "gps_time" in set(header.point_format.dimension_names)
            for chunk in reader.chunk_iterator(chunk_points):
                xyz.append(
                    np.column_stack([np.asarray(getattr(chunk, k), np.float64) for k in "xyz"])
                )
                intensity.append(np.asarray(chunk.intensity, np.float32))
                if has_time:
                    gps_time.append(np.asarray(chunk.gps_time, np.float64))
    except (laspy.LaspyException, OSError, ValueError, EOFError) as exc:
        raise RecordingError(f"cannot read {path}: {exc}") from None
    return LasPoints(
        xyz=np.concatenate(xyz) if xyz else np.empty((0, 3)),
        intensity=np.concatenate(intensity) if intensity else np.empty(0, np.float32),
        gps_time=(np.concatenate(gps_time) if gps_time else np.empty(0)) if has_time else None,
        point_format=point_format,
        version=version,
    )


BOUNDARY_TOL = 1e-6  # of a period


def _frame_bounds(t: FloatArray, period: float) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Frame index of each run of sorted times ``t`` (from 0) [s] and the runs' starts."""
    # A time a rounding error short of a frame boundary belongs to the next frame.
    index = np.floor(t / period + BOUNDARY_TOL).astype(np.int64)
    starts = np.flatnonzero(np.diff(index)) + 1
    if len(t):
        starts = np.concatenate([np.zeros(1, np.int64), starts])
    return index[starts], starts


class LasRecording(PointFileRecording):
    """A ``.las``/``.laz`` file cut into frames by GPS time (see the module docstring)."""

    def __init__(self, path: Path, options: ReplayOptions | None = None) -> None:
        super().__init__(path)
        options = options or ReplayOptions()
        if not self.path.is_file():
            raise RecordingError(f"{self.path} does not exist or is not a file")
        if sniff_file(self.path) != "las":
            raise RecordingError(f"{self.path} is not a LAS or LAZ file (no 'LASF' signature)")
        self._pose = sensor_pose(options)
        self.pose_warning = None if self._pose is not None else identity_pose_warning(self.path)
        self.period = frame_period(options, None)
        points = read_las(self.path)
        if not len(points.xyz):
            raise RecordingError(f"{self.path} has no points")
        self.point_format = points.point_format
        self.version = points.version
        self.has_time = points.gps_time is not None
        xyz, intensity, t = points.xyz, points.intensity, points.gps_time
        if t is None:
            self.origin = 0.0
            self._t: FloatArray = np.zeros(len(xyz))
        else:
            ok = np.isfinite(t)
            if not np.all(ok):
                self.skipped["no_time"] += int(np.count_nonzero(~ok))
                log.warning(
                    "skipping %d points of %s without a finite gps_time",
                    self.skipped["no_time"],
                    self.path.name,
                )
                xyz, intensity, t = xyz[ok], intensity[ok], t[ok]
            if not len(t):
                raise RecordingError(f"{self.path} has no points with a finite gps_time")
            order = np.argsort(t, kind="stable")
            xyz, intensity, t = xyz[order], intensity[order], t[order]
            self.origin = float(t[0])
            self._t = t - t[0]
        self._xyz = xyz
        self._intensity = intensity
        self._index, self._starts = _frame_bounds(self._t, self.period)

    def __len__(self) -> int:
        """The number of frames."""
        return len(self._starts)

    def frames(self) -> Iterator[Frame]:
        """The frames in time order; each point at its own time when the file has times."""
        ends = np.append(self._starts[1:], len(self._t))
        for k, a, b in zip(self._index.tolist(), self._starts.tolist(), ends.tolist(), strict=True):
            stamp = k * self.period
            yield fixed_pose_frame(
                stamp,
                self.period,
                self._xyz[a:b],
                t=self._t[a:b] if self.has_time else None,
                intensity=self._intensity[a:b],
                pose=self._pose,
            )

    def info(self) -> RecordingInfo:
        """One topic named after the file, counting the frames."""
        kind = self.path.suffix.lower().lstrip(".")
        topic = TopicInfo(self.path.name, f"{kind}/point-format-{self.point_format}", len(self))
        duration = float(self._t[-1] - self._t[0])
        return RecordingInfo(self.path, "las", self.origin, duration, (topic,))
