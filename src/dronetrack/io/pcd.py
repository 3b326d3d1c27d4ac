"""Point Cloud Data (``.pcd``) files, one file or a folder of them, as a recording.

The format (PCL's PCD v0.7) is an ASCII header, one ``KEY values`` line each,
``#`` comments allowed, ending with the ``DATA`` line; the points follow::

    VERSION 0.7
    FIELDS x y z intensity      names ("_" is PCL's padding; repeats get a suffix)
    SIZE 4 4 4 4                bytes per element: 1, 2, 4 or 8
    TYPE F F F F                I signed, U unsigned integer, F IEEE float (4 or 8)
    COUNT 1 1 1 1               elements per field (default 1)
    WIDTH 1000                  points per row (the count for an unorganised cloud)
    HEIGHT 1                    rows (default 1)
    VIEWPOINT 0 0 0 1 0 0 0     acquisition pose: translation, quaternion w x y z
    POINTS 1000                 WIDTH × HEIGHT
    DATA binary                 ascii | binary | binary_compressed

- ``ascii``: one point a line, the elements separated by white space;
- ``binary``: the points as packed little-endian records (no alignment);
- ``binary_compressed``: uint32 compressed size, uint32 uncompressed size, then
  an LZF stream that expands to the points stored field by field (all the x,
  then all the y, ...), not point by point.

``read_pcd`` returns the points as a structured numpy array with one field per
``FIELDS`` entry (a COUNT > 1 field is a sub-array); ``write_pcd`` writes one.

VIEWPOINT is read into the header but not applied: writers almost always leave
it at the identity, and the sensor pose of a recording is ``ReplayOptions.sensor_pose``.

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
import struct
from collections import Counter
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError, InputError, RecordingError
from dronetrack.geometry import FloatArray
from dronetrack.io.source import (
    PointFileRecording,
    RecordingInfo,
    ReplayOptions,
    TopicInfo,
    fixed_pose_frame,
)
from dronetrack.types import Frame

__all__ = [
    "ENCODINGS",
    "FolderTimes",
    "PcdHeader",
    "PcdRecording",
    "cloud_frame",
    "cloud_times",
    "cloud_xyz",
    "decode_pcd",
    "encode_pcd",
    "folder_times",
    "frame_period",
    "lzf_compress_literal",
    "lzf_decompress",
    "parse_pcd_header",
    "read_pcd",
    "read_pcd_header",
    "sensor_pose",
    "write_pcd",
]

log = logging.getLogger(__name__)

ENCODINGS = ("ascii", "binary", "binary_compressed")
DEFAULT_PERIOD_S = 0.1
_HEADER_KEYS = frozenset(
    ["VERSION", "FIELDS", "SIZE", "TYPE", "COUNT", "WIDTH", "HEIGHT", "VIEWPOINT", "POINTS", "DATA"]
)
_REQUIRED_KEYS = ("FIELDS", "SIZE", "TYPE", "WIDTH", "DATA")
_NUMPY_TYPES = {
    ("I", 1): "i1",
    ("I", 2): "<i2",
    ("I", 4): "<i4",
    ("I", 8): "<i8",
    ("U", 1): "u1",
    ("U", 2): "<u2",
    ("U", 4): "<u4",
    ("U", 8): "<u8",
    ("F", 4): "<f4",
    ("F", 8): "<f8",
}
_PCD_TYPES = {"i": "I", "u": "U", "f": "F"}
_HEADER_PROBE_BYTES = 1 << 16
# An absolute ``timestamp`` above this magnitude is in nanoseconds (as in PointCloud2).
_NS_THRESHOLD = 1e14
_LZF_MAX_RATIO = 90  # one 3-byte LZF instruction expands to at most 264 bytes
_IDENTITY_VIEWPOINT = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)


# ---------------------------------------------------------------------------------------
# LZF


@nb.njit(cache=True)
def _lzf_kernel(src: NDArray[np.uint8], dst: NDArray[np.uint8]) -> int:
    """Expand the LZF stream ``src`` into ``dst``; the bytes written, or a negative code:
    -1 the stream ends inside an instruction, -2 it expands beyond ``dst``,
    -3 a back reference points before the start of the output."""
    n_in = src.shape[0]
    n_out = dst.shape[0]
    ip = 0
    op = 0
    while ip < n_in:
        ctrl = int(src[ip])
        ip += 1
        if ctrl < 32:  # a literal run of ctrl + 1 bytes
            length = ctrl + 1
            if ip + length > n_in:
                return -1
            if op + length > n_out:
                return -2
            for k in range(length):
                dst[op + k] = src[ip + k]
            ip += length
            op += length
        else:  # a back reference: length in the top 3 bits, offset in 13 bits
            length = ctrl >> 5
            if length == 7:
                if ip >= n_in:
                    return -1
                length += int(src[ip])
                ip += 1
            if ip >= n_in:
                return -1
            ref = op - ((ctrl & 0x1F) << 8) - int(src[ip]) - 1
            ip += 1
            length += 2
            if ref < 0:
                return -3
            if op + length > n_out:
                return -2
            for k in range(length):  # byte by byte: the source may overlap the output
                dst[op + k] = dst[ref + k]
            op += length
    return op


_LZF_ERRORS = {
    -1: "the LZF stream ends inside an instruction",
    -2: "the LZF stream expands beyond its stated size",
    -3: "an LZF back reference points before the start of the data",
}


def lzf_decompress(data: bytes | NDArray[np.uint8], size: int) -> NDArray[np.uint8]:
    """Expand an LZF stream (liblzf's format) to exactly ``size`` bytes.

    Raises DecodeError if the stream is malformed or expands to another size.
    """
    src = np.frombuffer(data, dtype=np.uint8) if isinstance(data, bytes) else data
    dst = np.empty(size, dtype=np.uint8)
    written = int(_lzf_kernel(src, dst))
    if written < 0:
        raise DecodeError(_LZF_ERRORS[written])
    if written != size:
        raise DecodeError(f"the LZF stream expands to {written} bytes, the header says {size}")
    return dst


def lzf_compress_literal(data: bytes) -> bytes:
    """A valid LZF stream for ``data`` made of literal runs only (no compression):
    each run is a control byte ``n - 1`` followed by ``n`` ≤ 32 bytes."""
    out = bytearray()
    for i in range(0, len(data), 32):
        chunk = data[i : i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    return bytes(out)


# ---------------------------------------------------------------------------------------
# Header


@dataclass(frozen=True, slots=True)
class PcdHeader:
    """A parsed PCD header; ``data_offset`` is where the point data start in the file."""

    version: str
    fields: tuple[str, ...]
    sizes: tuple[int, ...]
    types: tuple[str, ...]
    counts: tuple[int, ...]
    width: int
    height: int
    viewpoint: tuple[float, ...]
    points: int
    data: str
    data_offset: int

    @property
    def dtype(self) -> np.dtype[np.void]:
        """The packed little-endian record of one point; repeated names get a suffix."""
        names = _unique_names(self.fields)
        items = []
        for name, size, kind, count in zip(names, self.sizes, self.types, self.counts, strict=True):
            base = _NUMPY_TYPES[(kind, size)]
            items.append((name, base) if count == 1 else (name, base, (count,)))
        return np.dtype(items)


def _unique_names(fields: Sequence[str]) -> list[str]:
    """The field names with repeats (e.g. PCL's "_" padding) made unique: "_", "__1", "__2", ..."""
    seen: set[str] = set()
    out = []
    for name in fields:
        unique, k = name, 0
        while unique in seen:
            k += 1
            unique = f"{name}_{k}"
        seen.add(unique)
        out.append(unique)
    return out


def _ints(key: str, values: Sequence[str], minimum: int) -> tuple[int, ...]:
    try:
        out = tuple(int(v) for v in values)
    except ValueError:
        raise DecodeError(f"PCD {key} must be integers, got {' '.join(values)!r}") from None
    if any(v < minimum for v in out):
        raise DecodeError(f"PCD {key} must be >= {minimum}, got {' '.join(values)!r}")
    return out


def _one_int(entries: dict[str, list[str]], key: str, default: int | None) -> int:
    if key not in entries:
        if default is None:
            raise DecodeError(f"PCD header has no {key} line")
        return default
    values = _ints(key, entries[key], 0)
    if len(values) != 1:
        raise DecodeError(f"PCD {key} must be one integer, got {' '.join(entries[key])!r}")
    return values[0]


def _viewpoint(entries: dict[str, list[str]]) -> tuple[float, ...]:
    if "VIEWPOINT" not in entries:
        return _IDENTITY_VIEWPOINT
    try:
        vp = tuple(float(v) for v in entries["VIEWPOINT"])
    except ValueError:
        vp = ()
    if len(vp) != 7:
        raise DecodeError(f"PCD VIEWPOINT must be 7 numbers, got {entries['VIEWPOINT']!r}")
    return vp


def _header_lines(buf: bytes) -> tuple[dict[str, list[str]], int]:
    """The header's entries by key and the offset just after the DATA line."""
    entries: dict[str, list[str]] = {}
    pos = 0
    while "DATA" not in entries:
        if pos >= len(buf):
            raise DecodeError("PCD header has no DATA line")
        end = buf.find(b"\n", pos)
        end = len(buf) if end < 0 else end
        raw, pos = buf[pos:end], end + 1
        try:
            text = raw.decode("ascii").strip()
        except UnicodeDecodeError:
            raise DecodeError("PCD header is not ASCII text") from None
        if not text or text.startswith("#"):
            continue
        key, *values = text.split()
        key = key.upper()
        if key not in _HEADER_KEYS:
            raise DecodeError(f"unknown PCD header line {text[:40]!r}")
        if key in entries:
            raise DecodeError(f"PCD header repeats {key}")
        entries[key] = values
    return entries, min(pos, len(buf))


def parse_pcd_header(buf: bytes) -> PcdHeader:
    """Parse the header at the start of a PCD file's bytes; DecodeError names the problem."""
    entries, offset = _header_lines(buf)
    for key in _REQUIRED_KEYS:
        if key not in entries:
            raise DecodeError(f"PCD header has no {key} line")
    fields = tuple(entries["FIELDS"])
    n = len(fields)
    sizes = _ints("SIZE", entries["SIZE"], 1)
    types = tuple(v.upper() for v in entries["TYPE"])
    counts = _ints("COUNT", entries["COUNT"], 1) if "COUNT" in entries else (1,) * n
    if n == 0 or not len(sizes) == len(types) == len(counts) == n:
        raise DecodeError(
            f"PCD header lists {n} FIELDS, {len(sizes)} SIZE, {len(types)} TYPE "
            f"and {len(counts)} COUNT values"
        )
    for name, size, kind in zip(fields, sizes, types, strict=True):
        if (kind, size) not in _NUMPY_TYPES:
            raise DecodeError(f"PCD field {name!r} has unsupported TYPE {kind} SIZE {size}")
    width = _one_int(entries, "WIDTH", None)
    height = _one_int(entries, "HEIGHT", 1)
    points = _one_int(entries, "POINTS", width * height)
    if points != width * height:
        raise DecodeError(f"PCD POINTS {points} != WIDTH {width} × HEIGHT {height}")
    data = " ".join(entries["DATA"]).lower()
    if data not in ENCODINGS:
        raise DecodeError(f"PCD DATA {data!r} is not one of {', '.join(ENCODINGS)}")
    version = " ".join(entries.get("VERSION", []))
    return PcdHeader(
        version, fields, sizes, types, counts, width, height, _viewpoint(entries), points, data,
        offset,
    )  # fmt: skip


def read_pcd_header(path: Path) -> PcdHeader:
    """The header of a PCD file, reading only its start (DecodeError, OSError)."""
    with path.open("rb") as fh:
        buf = fh.read(_HEADER_PROBE_BYTES)
        if len(buf) == _HEADER_PROBE_BYTES and b"\nDATA" not in buf.upper():
            buf += fh.read()
    return parse_pcd_header(buf)


# ---------------------------------------------------------------------------------------
# Data


def _parse_ascii_column(
    tokens: NDArray[np.str_], dtype: np.dtype[np.generic]
) -> NDArray[np.generic]:
    """Text to numbers of ``dtype``; integers may be written as integral floats ("3.0")."""
    try:
        if dtype.kind == "f":
            with np.errstate(over="ignore"):
                return tokens.astype(np.float64).astype(dtype)
        try:
            return tokens.astype(dtype)
        except ValueError:
            values = tokens.astype(np.float64)
            info = np.iinfo(dtype)  # type: ignore[type-var]
            ok = np.isfinite(values) & (values == np.round(values))
            if not np.all(ok & (values >= info.min) & (values <= info.max)):
                raise ValueError("not an integer in range") from None
            return values.astype(dtype)
    except (ValueError, OverflowError) as exc:
        raise DecodeError(f"PCD ascii value does not parse as {dtype}: {exc}") from None


def _decode_ascii(buf: bytes, header: PcdHeader, dtype: np.dtype[np.void]) -> NDArray[np.void]:
    try:
        tokens = buf[header.data_offset :].decode("ascii").split()
    except UnicodeDecodeError:
        raise DecodeError("PCD ascii data is not ASCII text") from None
    n, per_point = header.points, sum(header.counts)
    if len(tokens) != n * per_point:
        raise DecodeError(
            f"PCD ascii data has {len(tokens)} values, expected {n} points × {per_point}"
        )
    table = np.array(tokens, dtype=np.str_).reshape(n, per_point)
    out = np.empty(n, dtype=dtype)
    col = 0
    for name, count in zip(dtype.names or (), header.counts, strict=True):
        base = dtype.fields[name][0].base  # type: ignore[index]
        values = _parse_ascii_column(table[:, col : col + count], base)
        out[name] = values[:, 0] if count == 1 else values
        col += count
    return out


def _decode_binary(buf: bytes, header: PcdHeader, dtype: np.dtype[np.void]) -> NDArray[np.void]:
    n = header.points
    have = len(buf) - header.data_offset
    if have < n * dtype.itemsize:
        raise DecodeError(
            f"PCD binary data is truncated: {have} bytes for {n} points of {dtype.itemsize} bytes"
        )
    return np.frombuffer(buf, dtype=dtype, count=n, offset=header.data_offset).copy()


def _decode_compressed(buf: bytes, header: PcdHeader, dtype: np.dtype[np.void]) -> NDArray[np.void]:
    start = header.data_offset
    if len(buf) - start < 8:
        raise DecodeError("PCD binary_compressed data is missing its sizes")
    packed, unpacked = struct.unpack_from("<II", buf, start)
    n = header.points
    if unpacked != n * dtype.itemsize:
        raise DecodeError(
            f"PCD binary_compressed data expands to {unpacked} bytes, "
            f"expected {n} points of {dtype.itemsize} bytes"
        )
    if unpacked > _LZF_MAX_RATIO * packed + 32:
        raise DecodeError(
            f"PCD binary_compressed sizes are implausible: {packed} → {unpacked} bytes"
        )
    if len(buf) - start - 8 < packed:
        raise DecodeError(
            f"PCD binary_compressed data is truncated: {len(buf) - start - 8} of {packed} bytes"
        )
    raw = lzf_decompress(np.frombuffer(buf, np.uint8, count=packed, offset=start + 8), unpacked)
    out = np.empty(n, dtype=dtype)
    pos = 0
    for name in dtype.names or ():
        field = dtype.fields[name][0]  # type: ignore[index]
        count = math.prod(field.shape)
        column = np.frombuffer(raw, dtype=field.base, count=n * count, offset=pos)
        out[name] = column if count == 1 else column.reshape(n, count)
        pos += column.nbytes
    return out


def decode_pcd(buf: bytes) -> NDArray[np.void]:
    """The points of a PCD file's bytes as a structured array (DecodeError if malformed)."""
    header = parse_pcd_header(buf)
    dtype = header.dtype
    if header.data == "ascii":
        return _decode_ascii(buf, header, dtype)
    if header.data == "binary":
        return _decode_binary(buf, header, dtype)
    return _decode_compressed(buf, header, dtype)


def read_pcd(path: Path) -> NDArray[np.void]:
    """The points of a ``.pcd`` file as a structured array (DecodeError, OSError)."""
    return decode_pcd(Path(path).read_bytes())


# ---------------------------------------------------------------------------------------
# Writing


def _pcd_layout(dtype: np.dtype[np.void]) -> list[tuple[str, np.dtype[np.generic], int]]:
    """(name, little-endian base type, count) of each field; InputError if not writable."""
    if not dtype.names:
        raise InputError("write_pcd needs a structured array")
    layout = []
    for name in dtype.names:
        field = dtype.fields[name][0]  # type: ignore[index]
        base = field.base
        if not name or any(c.isspace() for c in name):
            raise InputError(f"PCD field names cannot be empty or contain spaces: {name!r}")
        if (
            base.kind not in _PCD_TYPES
            or (_PCD_TYPES[base.kind], base.itemsize) not in _NUMPY_TYPES
        ):
            raise InputError(f"PCD cannot store field {name!r} of type {base}")
        if len(field.shape) > 1:
            raise InputError(f"PCD fields are scalars or 1-D, {name!r} has shape {field.shape}")
        layout.append((name, base.newbyteorder("<"), math.prod(field.shape)))
    return layout


def _ascii_lines(
    arr: NDArray[np.void], layout: Sequence[tuple[str, np.dtype[np.generic], int]]
) -> str:
    n = len(arr)
    columns: list[list[str]] = []
    for name, base, count in layout:
        values = arr[name].reshape(n, count)
        fmt = repr if base.kind == "f" else str
        columns.extend([fmt(v) for v in values[:, c].tolist()] for c in range(count))
    return "".join(" ".join(row) + "\n" for row in zip(*columns, strict=True))


def encode_pcd(
    arr: NDArray[np.void],
    encoding: str = "binary",
    viewpoint: Sequence[float] = _IDENTITY_VIEWPOINT,
) -> bytes:
    """The bytes of an unorganised (HEIGHT 1) PCD file holding a structured array.

    ``binary_compressed`` stores the LZF stream as literal runs only: a valid,
    readable file that is about 3 % larger than ``binary``.
    """
    if encoding not in ENCODINGS:
        raise InputError(f"PCD encoding must be one of {', '.join(ENCODINGS)}, got {encoding!r}")
    if arr.ndim != 1:
        raise InputError(f"write_pcd needs a 1-D structured array, got shape {arr.shape}")
    if len(viewpoint) != 7:
        raise InputError(f"a PCD VIEWPOINT is 7 numbers, got {len(viewpoint)}")
    layout = _pcd_layout(arr.dtype)
    n = len(arr)
    header = (
        "# .PCD v0.7 - Point Cloud Data file format\n"
        "VERSION 0.7\n"
        f"FIELDS {' '.join(name for name, _, _ in layout)}\n"
        f"SIZE {' '.join(str(base.itemsize) for _, base, _ in layout)}\n"
        f"TYPE {' '.join(_PCD_TYPES[base.kind] for _, base, _ in layout)}\n"
        f"COUNT {' '.join(str(count) for _, _, count in layout)}\n"
        f"WIDTH {n}\nHEIGHT 1\n"
        f"VIEWPOINT {' '.join(repr(float(v)) for v in viewpoint)}\n"
        f"POINTS {n}\nDATA {encoding}\n"
    ).encode("ascii")
    if encoding == "ascii":
        body = _ascii_lines(arr, layout).encode("ascii")
    elif encoding == "binary":
        packed = np.empty(n, dtype=[(name, base, (count,)) for name, base, count in layout])
        for name, _, count in layout:
            packed[name] = arr[name].reshape(n, count)
        body = packed.tobytes()
    else:
        raw = b"".join(
            np.ascontiguousarray(arr[name], dtype=base).tobytes() for name, base, _ in layout
        )
        stream = lzf_compress_literal(raw)
        body = struct.pack("<II", len(stream), len(raw)) + stream
    return header + body


def write_pcd(
    path: Path,
    arr: NDArray[np.void],
    encoding: str = "binary",
    viewpoint: Sequence[float] = _IDENTITY_VIEWPOINT,
) -> None:
    """Write a structured array as a PCD file (see ``encode_pcd``)."""
    Path(path).write_bytes(encode_pcd(arr, encoding, viewpoint))


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


def cloud_xyz(cloud: NDArray[np.void]) -> FloatArray:
    """Points (N, 3) [m] from the x, y, z fields; DecodeError naming the fields found."""
    fields: Mapping[str, Any] = cloud.dtype.fields or {}
    if not all(k in fields and fields[k][0].shape == () for k in "xyz"):
        found = ", ".join(cloud.dtype.names or ()) or "none"
        raise DecodeError(f"the cloud has no scalar x, y, z fields (fields: {found})")
    return np.column_stack([cloud[k].astype(np.float64) for k in "xyz"])


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
        return stamp + rel.astype(np.float64) * 1e-9
    rel = _scalar_field(cloud, ("time",))
    if rel is not None:  # t = stamp + time
        return stamp + rel.astype(np.float64)
    ts = _scalar_field(cloud, ("timestamp",))
    if ts is None:
        return None
    seconds = ts.astype(np.float64)
    largest = _finite_extreme(seconds, largest=True)
    if largest is not None and largest > _NS_THRESHOLD:
        seconds = seconds * 1e-9
    if absolute:  # t = timestamp − origin
        return seconds - origin
    first = _finite_extreme(seconds, largest=False)  # t = stamp + timestamp − earliest
    return stamp + seconds - (first if first is not None else 0.0)


def _line_numbers(values: NDArray[np.generic]) -> NDArray[np.uint8]:
    """Laser line numbers clipped to 0..255, NaN as 0."""
    clean = np.nan_to_num(values.astype(np.float64), nan=0.0, posinf=255.0, neginf=0.0)
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
        intensity=None if intensity is None else intensity[keep].astype(np.float32),
        line=None if line is None else _line_numbers(line[keep]),
        pose=pose,
    )


# ---------------------------------------------------------------------------------------
# The recording


def _pcd_files(path: Path) -> list[Path]:
    if not path.exists():
        raise RecordingError(f"{path} does not exist")
    if path.is_file():
        if path.suffix.lower() != ".pcd":
            raise RecordingError(f"{path} is not a .pcd file")
        return [path]
    files = sorted(p for p in path.iterdir() if p.suffix.lower() == ".pcd" and p.is_file())
    if not files:
        raise RecordingError(f"{path} has no .pcd files")
    return files


def sensor_pose(options: ReplayOptions) -> FloatArray | None:
    """options.sensor_pose checked to be (4, 4) world_T_sensor, or None (identity)."""
    if options.sensor_pose is None:
        return None
    pose = np.asarray(options.sensor_pose, dtype=np.float64)
    if pose.shape != (4, 4):
        raise InputError(f"sensor_pose must be (4, 4), got {pose.shape}")
    return pose


def frame_period(options: ReplayOptions, t: FloatArray | None) -> float:
    """options.period_s, else the median step of ``t``, else 0.1 s."""
    if options.period_s is not None:
        if not options.period_s > 0:
            raise InputError(f"period_s must be > 0, got {options.period_s}")
        return float(options.period_s)
    if t is not None and len(t) > 1:
        step = float(np.median(np.diff(t)))
        if step > 0:
            return step
    return DEFAULT_PERIOD_S


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
