"""Numpy decoding and encoding of ``sensor_msgs/PointCloud2`` point data.

Byte layout
-----------
A PointCloud2 carries ``height`` rows of ``width`` points in ``data``.  Each row
takes ``row_step`` bytes: ``width`` records of ``point_step`` bytes followed by
``row_step - width * point_step`` bytes of row padding, so
``len(data) == row_step * height``.  Inside a record, each ``PointField`` places
``count`` values of one primitive type (``datatype`` 1..8, see
:data:`POINTFIELD_TYPES`) at byte ``offset``; bytes not covered by any field
are padding.  ``is_bigendian`` gives the byte order of every multi-byte value.

:func:`decode_cloud` turns this into a numpy structured array with one named
field per PointField (a zero-copy view when rows carry no padding), and
:func:`cloud_points` extracts what the tracker needs in native float64 SI units.
Fields with ``count == 0`` hold no values; they are ignored rather than rejected.

Per-point time conventions (``t`` of :class:`CloudPoints` is always seconds
relative to the header stamp; the first field present in this order is used)
---------------------------------------------------------------------------------
- ``offset_time`` or ``t`` (uint32): nanoseconds after the header stamp
  (Livox driver PointCloud2 variant, Ouster).
- ``time`` (float32/float64): seconds relative to the header stamp, may be
  negative (Velodyne).
- ``timestamp`` (float64): absolute time, in nanoseconds when the largest finite
  magnitude of an evenly strided sample of at most 64 of the cloud's values
  exceeds 1e14, otherwise in seconds (livox_ros_driver2, Hesai).  Float64
  nanoseconds since 1970 resolve about 256 ns.

Intensity comes from ``intensity`` or ``reflectivity`` (zeros when absent); the
laser line from ``line`` or ``ring``, clipped to 0..255 (zeros when absent).

:func:`encode_cloud` writes the livox_ros_driver2 layout (``xfer_format=0``)
with explicit alignment padding (point_step 32 B):

====== ========= ======= ==========================================
offset field     type    meaning
====== ========= ======= ==========================================
0      x         float32 m, sensor frame
4      y         float32 m
8      z         float32 m
12     intensity float32 reflectivity 0..255
16     tag       uint8   Livox return tag (0 here)
17     line      uint8   laser line
18     (pad)     6 B     so that timestamp is 8-byte aligned
24     timestamp float64 absolute time of the point [ns]
====== ========= ======= ==========================================
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import pairwise

import numpy as np
from numpy.typing import ArrayLike, NDArray

from dronetrack.errors import DecodeError, InputError
from dronetrack.geometry.transforms import FloatArray

__all__ = [
    "ENCODED_POINT_STEP",
    "POINTFIELD_TYPES",
    "CloudPoints",
    "Field",
    "cloud_dtype",
    "cloud_points",
    "decode_cloud",
    "encode_cloud",
    "fields_from_msg",
    "has_point_times",
]

# sensor_msgs/PointField datatype constants -> numpy type codes (no byte order).
POINTFIELD_TYPES: dict[int, str] = {
    1: "i1",
    2: "u1",
    3: "i2",
    4: "u2",
    5: "i4",
    6: "u4",
    7: "f4",
    8: "f8",
}

# An absolute ``timestamp`` above this magnitude is in nanoseconds (1e14 s would
# be three million years; 1e14 ns is one day after 1970).
_NS_THRESHOLD = 1e14

# Time fields in order of preference: (name, seconds per unit, absolute?).
_TIME_FIELDS: tuple[tuple[str, float, bool], ...] = (
    ("offset_time", 1e-9, False),
    ("t", 1e-9, False),
    ("time", 1.0, False),
    ("timestamp", 0.0, True),  # unit chosen from the values
)
TIME_FIELD_NAMES = tuple(name for name, _, _ in _TIME_FIELDS)
_INTENSITY_FIELDS = ("intensity", "reflectivity")
_LINE_FIELDS = ("line", "ring")


@dataclass(frozen=True, slots=True)
class Field:
    """One ``sensor_msgs/PointField``: ``count`` values of ``datatype`` at byte ``offset``."""

    name: str
    offset: int
    datatype: int
    count: int = 1


@dataclass(frozen=True, slots=True)
class CloudPoints:
    """The tracker's view of one cloud.

    ``points`` (N, 3) [m]; ``t`` (N,) [s] relative to the header stamp, or None
    when the cloud has no time field; ``intensity`` (N,) float32; ``line`` (N,) uint8.
    """

    points: FloatArray
    t: FloatArray | None
    intensity: NDArray[np.float32]
    line: NDArray[np.uint8]


def has_point_times(fields: list[Field]) -> bool:
    """Whether clouds of these fields give every point its own time (``cloud_points``)."""
    return any(f.name in TIME_FIELD_NAMES and f.count > 0 for f in fields)


def fields_from_msg(msg: object) -> list[Field]:
    """The fields of a PointCloud2 message object (rosbags or rclpy), duck-typed."""
    raw_fields = getattr(msg, "fields", None)
    if raw_fields is None:
        raise DecodeError(f"{type(msg).__name__} has no 'fields' attribute")
    out: list[Field] = []
    for f in raw_fields:
        try:
            out.append(Field(str(f.name), int(f.offset), int(f.datatype), int(f.count)))
        except (AttributeError, TypeError, ValueError) as exc:
            raise DecodeError(f"PointField {f!r} is malformed: {exc}") from exc
    return out


def _field_format(field: Field, bigendian: bool) -> tuple[str, int]:
    """Numpy type code with byte order and the size of one value [B]."""
    code = POINTFIELD_TYPES.get(field.datatype)
    if code is None:
        raise DecodeError(
            f"PointField {field.name!r} has unknown datatype {field.datatype} (expected 1..8)"
        )
    size = int(code[1])
    order = "|" if size == 1 else (">" if bigendian else "<")
    return order + code, size


def cloud_dtype(fields: list[Field], point_step: int, bigendian: bool) -> np.dtype[np.void]:
    """Structured dtype of one point record: explicit offsets, itemsize ``point_step``.

    Raises DecodeError for an empty or duplicate name, unknown datatype, negative
    count or offset, a field running past ``point_step``, or overlapping fields.
    Fields with ``count == 0`` are skipped.
    """
    if point_step <= 0:
        raise DecodeError(f"PointCloud2 point_step must be > 0, got {point_step}")
    names: list[str] = []
    formats: list[str | tuple[str, int]] = []
    offsets: list[int] = []
    spans: list[tuple[int, int, str]] = []  # (start, end, name) in bytes
    for field in fields:
        if field.count < 0:
            raise DecodeError(f"PointField {field.name!r} has count {field.count} < 0")
        code, size = _field_format(field, bigendian)
        if field.count == 0:
            continue
        if not field.name:
            raise DecodeError("PointField with an empty name")
        if field.name in names:
            raise DecodeError(f"PointField name {field.name!r} appears twice")
        # The field covers bytes [offset, offset + size * count) of the record.
        end = field.offset + size * field.count
        if field.offset < 0 or end > point_step:
            raise DecodeError(
                f"PointField {field.name!r} spans bytes {field.offset}..{end} "
                f"outside point_step {point_step}"
            )
        names.append(field.name)
        formats.append(code if field.count == 1 else (code, field.count))
        offsets.append(field.offset)
        spans.append((field.offset, end, field.name))
    spans.sort()
    for (_, end_a, name_a), (start_b, _, name_b) in pairwise(spans):
        if start_b < end_a:
            raise DecodeError(f"PointFields {name_a!r} and {name_b!r} overlap")
    spec = {"names": names, "formats": formats, "offsets": offsets, "itemsize": point_step}
    try:
        return np.dtype(spec)  # type: ignore[call-overload, no-any-return]
    except (TypeError, ValueError) as exc:  # numpy's own checks, e.g. on odd names
        raise DecodeError(f"PointCloud2 fields do not form a record: {exc}") from exc


def _byte_buffer(data: bytes | bytearray | memoryview | NDArray[np.uint8]) -> NDArray[np.uint8]:
    """``data`` as a flat, contiguous uint8 array (a view when possible)."""
    if isinstance(data, np.ndarray):
        if data.dtype.itemsize != 1:
            raise DecodeError(f"PointCloud2 data must be bytes, got an array of {data.dtype}")
        return np.ascontiguousarray(data).reshape(-1).view(np.uint8)
    try:
        return np.frombuffer(data, dtype=np.uint8)
    except (TypeError, ValueError, BufferError) as exc:
        raise DecodeError(f"PointCloud2 data is not a byte buffer: {exc}") from exc


def decode_cloud(
    fields: list[Field],
    data: bytes | bytearray | memoryview | NDArray[np.uint8],
    width: int,
    height: int,
    point_step: int,
    row_step: int,
    bigendian: bool,
) -> NDArray[np.void]:
    """The ``width * height`` point records of a PointCloud2 as a structured array.

    A zero-copy (possibly read-only) view of ``data`` when rows carry no padding
    (``row_step == width * point_step``), else a copy without the row padding.
    Requires ``len(data) == row_step * height``.
    """
    dtype = cloud_dtype(fields, point_step, bigendian)
    if width < 0 or height < 0:
        raise DecodeError(f"PointCloud2 size {width}×{height} is negative")
    row_bytes = width * point_step  # bytes of point records per row
    if row_step < row_bytes:
        raise DecodeError(
            f"PointCloud2 row_step {row_step} < width {width} × point_step {point_step}"
        )
    buf = _byte_buffer(data)
    need = row_step * height
    if buf.size != need:
        raise DecodeError(
            f"point count {width}×{height} needs {need} bytes "
            f"(row_step {row_step}), message has {buf.size}"
        )
    n = width * height
    if n == 0:
        return np.zeros(0, dtype=dtype)
    if row_step == row_bytes:
        return buf.view(dtype)
    rows = buf.reshape(height, row_step)[:, :row_bytes]
    return np.ascontiguousarray(rows).reshape(-1).view(dtype)


def _scalar_column(arr: NDArray[np.void], name: str) -> NDArray[np.generic]:
    """Field ``name`` as a 1-D array; DecodeError when it holds several values per point."""
    col: NDArray[np.generic] = arr[name]
    if col.ndim != 1:
        raise DecodeError(f"PointCloud2 field {name!r} has count {col.shape[1:]} instead of 1")
    return col


def _first_present(names: tuple[str, ...], candidates: tuple[str, ...]) -> str | None:
    return next((c for c in candidates if c in names), None)


def _relative_time(
    arr: NDArray[np.void], names: tuple[str, ...], stamp: float
) -> FloatArray | None:
    """Per-point time [s] relative to the header stamp ``stamp`` [s], or None."""
    for name, unit, absolute in _TIME_FIELDS:
        if name not in names:
            continue
        values = _scalar_column(arr, name).astype(np.float64)
        if not absolute:
            # t_rel = value · unit
            return values * unit
        # The unit is the cloud's, so a strided sample of at most 64 values decides it.
        sample = values[:: max(1, len(values) // 64)]
        finite = sample[np.isfinite(sample)]
        if finite.size and float(np.max(np.abs(finite))) > _NS_THRESHOLD:
            # t_rel = (timestamp_ns − stamp·1e9) · 1e-9
            return (values - stamp * 1e9) * 1e-9
        # t_rel = timestamp_s − stamp
        return values - stamp
    return None


def _line_column(arr: NDArray[np.void], name: str) -> NDArray[np.uint8]:
    """Laser line clipped to 0..255; NaN becomes 0."""
    column = _scalar_column(arr, name)
    if column.dtype.kind == "u" and column.dtype.itemsize == 1:
        return column.astype(np.uint8)  # already in range
    if column.dtype.kind in "iu":
        clipped: NDArray[np.uint8] = np.clip(column, 0, 255).astype(np.uint8)
        return clipped
    values = np.nan_to_num(column.astype(np.float64), nan=0.0)
    return np.clip(values, 0.0, 255.0).astype(np.uint8)


def cloud_points(arr: NDArray[np.void], stamp: float) -> CloudPoints:
    """Positions, relative times, intensity and line of decoded records ``arr``.

    ``stamp`` is the header stamp in absolute seconds; values come out native-endian.
    """
    names: tuple[str, ...] = arr.dtype.names or ()
    if not all(axis in names for axis in ("x", "y", "z")):
        raise DecodeError(f"PointCloud2 has no x, y, z fields (it has: {', '.join(names)})")
    n = arr.shape[0]
    points = np.empty((n, 3), dtype=np.float64)
    # Corrupt bytes may hold signalling NaNs in any float column: a cast quiets them
    # and raises numpy's 'invalid' flag.  They stay NaN, and the pipeline counts them.
    with np.errstate(invalid="ignore"):
        for k, axis in enumerate(("x", "y", "z")):
            points[:, k] = _scalar_column(arr, axis)  # converts byte order and type
        intensity_name = _first_present(names, _INTENSITY_FIELDS)
        intensity = (
            np.zeros(n, dtype=np.float32)
            if intensity_name is None
            else _scalar_column(arr, intensity_name).astype(np.float32)
        )
        line_name = _first_present(names, _LINE_FIELDS)
        line = np.zeros(n, dtype=np.uint8) if line_name is None else _line_column(arr, line_name)
        t_rel = _relative_time(arr, names, stamp)
    return CloudPoints(points, t_rel, intensity, line)


# The livox_ros_driver2 PointCloud2 record written by encode_cloud (see the table above).
ENCODED_POINT_STEP = 32
_ENCODED_FIELDS: list[Field] = [
    Field("x", 0, 7),
    Field("y", 4, 7),
    Field("z", 8, 7),
    Field("intensity", 12, 7),
    Field("tag", 16, 2),
    Field("line", 17, 2),
    Field("timestamp", 24, 8),
]


def _column(values: ArrayLike, n: int, what: str) -> FloatArray:
    a = np.asarray(values, dtype=np.float64)
    if a.shape != (n,):
        raise InputError(f"{what} must have shape ({n},), got {a.shape}")
    return a


def encode_cloud(
    points: ArrayLike,
    t_rel: ArrayLike,
    intensity: ArrayLike,
    line: ArrayLike,
    stamp: float,
    *,
    bigendian: bool = False,
) -> tuple[list[Field], bytes, int]:
    """PointCloud2 ``fields``, ``data`` and ``point_step`` in the livox_ros_driver2 layout.

    ``points`` (N, 3) [m], ``t_rel`` (N,) [s] after the header ``stamp`` [s, absolute],
    ``intensity`` (N,), ``line`` (N,) in 0..255.  The cloud is one row:
    ``width = N``, ``height = 1``, ``row_step = N * point_step``.
    """
    p = np.asarray(points, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InputError(f"points must have shape (N, 3), got {p.shape}")
    n = p.shape[0]
    t = _column(t_rel, n, "t_rel")
    lines = _column(line, n, "line")
    if np.any(~np.isfinite(lines)) or np.any((lines < 0) | (lines > 255)):
        raise InputError("line values must lie in 0..255")
    dtype = cloud_dtype(_ENCODED_FIELDS, ENCODED_POINT_STEP, bigendian)
    rec = np.zeros(n, dtype=dtype)  # zeros: the padding bytes are deterministic
    rec["x"], rec["y"], rec["z"] = p[:, 0], p[:, 1], p[:, 2]
    rec["intensity"] = _column(intensity, n, "intensity")
    rec["line"] = lines.astype(np.uint8)
    # timestamp_ns = (stamp + t_rel) · 1e9, summed in ns to keep the sub-second part
    rec["timestamp"] = stamp * 1e9 + t * 1e9
    return list(_ENCODED_FIELDS), rec.tobytes(), ENCODED_POINT_STEP
