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

A folder of them is read as a recording by ``sources.recordings.pcd``.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError, InputError
from dronetrack.formats.lzf import lzf_compress_literal, lzf_decompress

__all__ = [
    "ENCODINGS",
    "PcdHeader",
    "decode_pcd",
    "encode_pcd",
    "parse_pcd_header",
    "read_pcd",
    "read_pcd_header",
    "write_pcd",
]

ENCODINGS = ("ascii", "binary", "binary_compressed")
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
_LZF_MAX_RATIO = 90  # one 3-byte LZF instruction expands to at most 264 bytes
_IDENTITY_VIEWPOINT = (0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)


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
