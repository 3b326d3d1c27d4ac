"""A ``.pcd`` file or a folder of them as a recording (the format: ``formats.pcd``).

A folder is a recording with one frame per file.  The frame times come from
``ReplayOptions.timestamps`` if given, else from the file names (see
``folder_times``).  Points with a non-finite x, y or z (an organised cloud's
"no return") are dropped.  Per-point times are used when a field has them:

- ``offset_time`` or ``t``: nanoseconds after the file's time;
- ``time``: float seconds relative to the file's time;
- ``timestamp``: absolute time in seconds, or in nanoseconds if > 1e14.  When the
  file times are only indices, the times are taken relative to the frame's
  earliest ``timestamp`` instead.

intensity is read from ``intensity`` or ``reflectivity``, the laser line from
``line`` or ``ring`` (clipped to 0-255).
"""

from __future__ import annotations

import logging
import math
import re
from collections import Counter
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError, RecordingError
from dronetrack.formats.magic import sniff_file
from dronetrack.formats.pcd import PcdHeader, read_pcd, read_pcd_header
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sources.frames import fixed_pose_frame
from dronetrack.sources.recordings.recording import (
    DEFAULT_PERIOD_S,
    PointFileRecording,
    RecordingInfo,
    ReplayOptions,
    TopicInfo,
    frame_period,
    identity_pose_warning,
    sensor_pose,
)
from dronetrack.types import Frame

__all__ = [
    "FolderTimes",
    "PcdRecording",
    "cloud_frame",
    "cloud_times",
    "cloud_xyz",
    "folder_times",
]

log = logging.getLogger(__name__)

# An absolute ``timestamp`` above this magnitude is in nanoseconds (as in PointCloud2).
_NS_THRESHOLD = 1e14


# ---------------------------------------------------------------------------------------
# Times of the files in a folder

_NUMBER = re.compile(r"\d+(?:\.\d+)?")
_NS_PER_UNIT = (  # (upper bound of an integer, ns per unit) for integer times
    (10**11, 10**9),  # seconds
    (10**14, 10**6),  # milliseconds
    (10**17, 10**3),  # microseconds
)


def _integer_unit_ns(largest: int) -> int:
    """Nanoseconds per unit of integer times whose largest value is ``largest``."""
    for bound, ns in _NS_PER_UNIT:
        if largest < bound:
            return ns
    return 1


_DECIMAL = re.compile(r"(\d*)\.(\d*)")
_INTEGER = re.compile(r"-?\d+")


def _is_integer(token: str) -> bool:
    return _INTEGER.fullmatch(token) is not None


def _seconds_ns(token: str) -> int:
    """Integer nanoseconds of a time in seconds; exact for plain decimals ("12.345")."""
    m = _DECIMAL.fullmatch(token)
    if m:
        return int(m[1] or "0") * 10**9 + int((m[2] + "0" * 9)[:9])
    if _is_integer(token):
        return int(token) * 10**9
    value = float(token)  # e.g. "1.7e9", "-0.5"
    if not math.isfinite(value):
        raise ValueError(f"{token!r} is not a finite time")
    return round(value * 1e9)


def _times_ns(tokens: Sequence[str]) -> list[int]:
    """Absolute times [ns] of number tokens: if any is not an integer, all are seconds;
    else their unit is the one the largest value's decade implies (< 1e11 s, < 1e14 ms,
    < 1e17 µs, else ns)."""
    if not all(_is_integer(tok) for tok in tokens):
        return [_seconds_ns(tok) for tok in tokens]
    unit = _integer_unit_ns(max(abs(int(tok)) for tok in tokens))
    return [int(tok) * unit for tok in tokens]


def _is_time(token: str) -> bool:
    try:
        return math.isfinite(float(token))
    except ValueError:
        return False


@dataclass(frozen=True, slots=True)
class FolderTimes:
    """The files with times, sorted by time: ``t`` relative to ``origin`` [s].

    ``absolute`` is False when the times are only frame indices × period.
    """

    files: tuple[Path, ...]
    t: FloatArray
    origin: float
    absolute: bool
    unlisted: tuple[Path, ...] = ()  # files the timestamps file does not name


def _absolute_times(files: Sequence[Path], ns: Sequence[int]) -> FolderTimes:
    order = sorted(range(len(files)), key=lambda i: (ns[i], files[i].name))
    first = ns[order[0]]
    t = np.array([(ns[i] - first) * 1e-9 for i in order], dtype=np.float64)
    return FolderTimes(tuple(files[i] for i in order), t, first * 1e-9, True)


def _times_from_names(files: Sequence[Path], period: float) -> FolderTimes:
    numbers = [_NUMBER.findall(f.stem) for f in files]
    if not any(numbers):  # no numbers at all: name order
        t = np.arange(len(files), dtype=np.float64) * period
        return FolderTimes(tuple(files), t, 0.0, False)
    for f, found in zip(files, numbers, strict=True):
        if not found:
            raise RecordingError(f"{f.name} has no number in its name for a timestamp")
    tokens = [found[-1] for found in numbers]
    if all("." not in tok for tok in tokens) and max(int(tok) for tok in tokens) < 10**8:
        index = np.array([int(tok) for tok in tokens], dtype=np.int64)
        order = np.argsort(index, kind="stable")
        t = (index[order] - index[order[0]]) * period
        return FolderTimes(
            tuple(files[i] for i in order), t, float(index[order[0]]) * period, False
        )
    return _absolute_times(files, _times_ns(tokens))


def _read_timestamps_file(path: Path) -> list[tuple[str | None, str]]:
    """(file name or None, time token) of each line of a timestamps file."""
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"cannot read timestamps file {path}: {exc}") from None
    rows: list[tuple[str | None, str]] = []
    for k, line in enumerate(lines, start=1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        parts = [p for p in re.split(r"[,\s]+", text) if p]
        if len(parts) > 2:
            raise RecordingError(f"{path.name} line {k}: expected 'time' or 'name,time': {text!r}")
        token = parts[-1]
        if not _is_time(token):
            if not rows:  # a header line such as "file,time"
                continue
            raise RecordingError(f"{path.name} line {k}: {token!r} is not a time")
        rows.append((parts[0] if len(parts) == 2 else None, token))
    if not rows:
        raise RecordingError(f"timestamps file {path} has no times")
    if len({name is None for name, _ in rows}) > 1:
        raise RecordingError(f"{path.name} mixes 'time' and 'name,time' lines")
    return rows


def _times_from_file(files: Sequence[Path], path: Path) -> FolderTimes:
    rows = _read_timestamps_file(path)
    if rows[0][0] is None:
        if len(rows) != len(files):
            raise RecordingError(f"{path.name} has {len(rows)} times for {len(files)} .pcd files")
        return _absolute_times(files, _times_ns([tok for _, tok in rows]))
    by_name = {name: tok for name, tok in rows}
    listed, tokens, unlisted = [], [], []
    for f in files:
        tok = by_name.get(f.name, by_name.get(f.stem))
        if tok is None:
            unlisted.append(f)
        else:
            listed.append(f)
            tokens.append(tok)
    if not listed:
        raise RecordingError(f"{path.name} names none of the .pcd files")
    times = _absolute_times(listed, _times_ns(tokens))
    return FolderTimes(times.files, times.t, times.origin, True, tuple(unlisted))


def folder_times(files: Sequence[Path], timestamps: Path | None, period: float) -> FolderTimes:
    """Time each file and sort the files by time (ties by name).

    From ``timestamps`` (a text file) when given: either one time per line for the
    files in sorted-name order, or ``name,time`` lines (name with or without
    ``.pcd``; files it does not name are returned in ``unlisted``).  Else from the
    last number in each file name:

    - a decimal number is seconds (``1700000000.123456.pcd``);
    - an integer below 1e8 is a frame index (``000123.pcd``): t = index × ``period``;
    - a larger integer's unit comes from the decade of the largest one in the folder:
      below 1e11 seconds, below 1e14 milliseconds, below 1e17 microseconds
      (``1700000000123456.pcd``), else nanoseconds (``1700000000123456789.pcd``).

    Names without any number are frames in name order.  Times in a timestamps file
    follow the same rules, except that integers below 1e8 are seconds.
    """
    if timestamps is not None:
        return _times_from_file(files, timestamps)
    return _times_from_names(files, period)


# ---------------------------------------------------------------------------------------
# Points to frames


def _scalar_field(cloud: NDArray[np.void], names: Sequence[str]) -> NDArray[np.generic] | None:
    """The first of ``names`` that is a one-element field of the cloud."""
    fields: Mapping[str, Any] = cloud.dtype.fields or {}
    for name in names:
        if name in fields and fields[name][0].shape == ():
            return np.asarray(cloud[name])
    return None


def _as_float64(values: NDArray[np.generic]) -> FloatArray:
    """``values`` as float64; a signalling NaN from corrupt bytes becomes a quiet NaN."""
    with np.errstate(invalid="ignore"):  # the cast quiets it and raises the 'invalid' flag
        return values.astype(np.float64)


def cloud_xyz(cloud: NDArray[np.void]) -> FloatArray:
    """Points (N, 3) [m] from the x, y, z fields; DecodeError naming the fields found."""
    fields: Mapping[str, Any] = cloud.dtype.fields or {}
    if not all(k in fields and fields[k][0].shape == () for k in "xyz"):
        found = ", ".join(cloud.dtype.names or ()) or "none"
        raise DecodeError(f"the cloud has no scalar x, y, z fields (fields: {found})")
    return np.column_stack([_as_float64(cloud[k]) for k in "xyz"])


def _finite_extreme(values: FloatArray, largest: bool) -> float | None:
    finite = values[np.isfinite(values)]
    if not finite.size:
        return None
    return float(np.max(np.abs(finite)) if largest else np.min(finite))


def cloud_times(
    cloud: NDArray[np.void], stamp: float, origin: float, absolute: bool
) -> FloatArray | None:
    """Per-point times [s relative to ``origin``] from a time field, or None; ``stamp`` is the
    file's time relative to ``origin``, ``absolute`` whether ``origin`` is a real time."""
    rel = _scalar_field(cloud, ("offset_time", "t"))
    if rel is not None:  # t = stamp + offset · 1e-9
        return stamp + _as_float64(rel) * 1e-9
    rel = _scalar_field(cloud, ("time",))
    if rel is not None:  # t = stamp + time
        return stamp + _as_float64(rel)
    ts = _scalar_field(cloud, ("timestamp",))
    if ts is None:
        return None
    seconds = _as_float64(ts)
    largest = _finite_extreme(seconds, largest=True)
    if largest is not None and largest > _NS_THRESHOLD:
        seconds = seconds * 1e-9
    if absolute:  # t = timestamp − origin
        return seconds - origin
    first = _finite_extreme(seconds, largest=False)  # t = stamp + timestamp − earliest
    return stamp + seconds - (first if first is not None else 0.0)


def _line_numbers(values: NDArray[np.generic]) -> NDArray[np.uint8]:
    """Laser line numbers clipped to 0..255, NaN as 0."""
    clean = np.nan_to_num(_as_float64(values), nan=0.0, posinf=255.0, neginf=0.0)
    return np.clip(clean, 0.0, 255.0).astype(np.uint8)


def cloud_frame(
    cloud: NDArray[np.void],
    stamp: float,
    duration: float,
    *,
    origin: float = 0.0,
    absolute: bool = True,
    pose: FloatArray | None = None,
) -> Frame:
    """A frame from a decoded cloud at ``stamp`` (relative to ``origin``) [s]; points with a
    non-finite coordinate are dropped."""
    xyz = cloud_xyz(cloud)
    keep = np.isfinite(xyz).all(axis=1)
    t = cloud_times(cloud, stamp, origin, absolute)
    intensity = _scalar_field(cloud, ("intensity", "reflectivity"))
    line = _scalar_field(cloud, ("line", "ring"))
    return fixed_pose_frame(
        stamp,
        duration,
        xyz[keep],
        t=None if t is None else t[keep],
        intensity=None if intensity is None else _as_float64(intensity[keep]).astype(np.float32),
        line=None if line is None else _line_numbers(line[keep]),
        pose=pose,
    )


# ---------------------------------------------------------------------------------------
# The recording


def _pcd_files(path: Path) -> list[Path]:
    if not path.exists():
        raise RecordingError(f"{path} does not exist")
    if path.is_file():
        if sniff_file(path) != "pcd":
            raise RecordingError(f"{path} is not a PCD file (no PCD header)")
        return [path]
    files = sorted(p for p in path.iterdir() if p.suffix.lower() == ".pcd" and p.is_file())
    if not files:
        raise RecordingError(f"{path} has no .pcd files")
    return files


class PcdRecording(PointFileRecording):
    """A folder of ``.pcd`` files (or one file), one frame each, read lazily.

    Every file's header is read when the recording is opened: files whose header
    does not parse are skipped (``skipped["bad_pcd"]``) and so are files whose data
    do not decode while the frames are read.  With a ``name,time`` timestamps file,
    files it does not name are skipped as ``skipped["no_timestamp"]``.  Every skip is
    logged as a warning; the counts accumulate if the frames are read again.
    """

    def __init__(self, path: Path, options: ReplayOptions | None = None) -> None:
        super().__init__(path)
        options = options or ReplayOptions()
        self._pose = sensor_pose(options)
        self.pose_warning = None if self._pose is not None else identity_pose_warning(self.path)
        files = _pcd_files(self.path)
        fallback = options.period_s if options.period_s is not None else DEFAULT_PERIOD_S
        times = folder_times(files, options.timestamps, fallback)
        for f in times.unlisted:
            self._skip("no_timestamp", f, "the timestamps file does not name it")
        self.headers: dict[Path, PcdHeader] = {}
        keep = []
        last_error = ""
        for k, f in enumerate(times.files):
            try:
                self.headers[f] = read_pcd_header(f)
                keep.append(k)
            except (DecodeError, OSError) as exc:
                last_error = str(exc)
                self._skip("bad_pcd", f, last_error)
        if not keep:
            raise RecordingError(f"no readable .pcd file in {self.path}: {last_error}")
        self.files = tuple(times.files[k] for k in keep)
        t = times.t[keep]
        self.origin = times.origin + float(t[0])
        self.times: FloatArray = t - t[0]
        self._absolute = times.absolute
        self.period = frame_period(options, self.times if times.absolute else None)

    def _skip(self, reason: str, path: Path, why: str) -> None:
        self.skipped[reason] += 1
        log.warning("skipping %s (%s): %s", path.name, reason, why)

    def frames(self) -> Iterator[Frame]:
        """One frame per readable file, in time order."""
        for f, stamp in zip(self.files, self.times.tolist(), strict=True):
            try:
                cloud = read_pcd(f)
                frame = cloud_frame(
                    cloud,
                    stamp,
                    self.period,
                    origin=self.origin,
                    absolute=self._absolute,
                    pose=self._pose,
                )
            except (DecodeError, OSError) as exc:
                self._skip("bad_pcd", f, str(exc))
                continue
            yield frame

    def info(self) -> RecordingInfo:
        """One topic per data encoding, named after the folder, counting the files."""
        encodings = Counter(self.headers[f].data for f in self.files)
        topics = tuple(
            TopicInfo(self.path.name, f"pcd/{enc}", count)
            for enc, count in sorted(encodings.items())
        )
        duration = float(self.times[-1] - self.times[0])
        return RecordingInfo(self.path, "pcd", self.origin, duration, topics)
