"""What the Livox SDK 1 and SDK 2 wire codecs share: decoded point and IMU batches,
per-firing point records read and written through numpy structured dtypes, and the
batch driver that groups same-layout packets into one 2-D byte array.

A point packet is a fixed header followed by ``n`` records of one firing each; a
firing holds one, two or three returns that share one time.  Coordinates are
either Cartesian integers (mm, or cm for the Mid-360's 16-bit type) or spherical:
depth u32 mm, ``theta`` the zenith angle in [0, 18000] and ``phi`` the azimuth in
[0, 36000), both in 0.01° (Livox-SDK ``livox_def.h`` LivoxSpherPoint), so

    x = r sin θ cos φ,   y = r sin θ sin φ,   z = r cos θ        (x forward)

A zero range (Cartesian 0, 0, 0 or depth 0) means no return; the decoders keep such
points and mark them (``hit`` False) so that the counts stay checkable.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import DecodeError, InputError
from dronetrack.geometry.transforms import FloatArray

__all__ = [
    "IMU_RECORD",
    "DecodedPackets",
    "GroupDecoder",
    "ImuSamples",
    "LivoxPoints",
    "RecordLayout",
    "cartesian_layout",
    "decode_batch",
    "decode_one",
    "packets_from_rows",
    "read_imu",
    "read_records",
    "spherical_layout",
    "write_imu",
    "write_records",
]

Bytes = bytes | bytearray | memoryview
I64 = NDArray[np.int64]
U8 = NDArray[np.uint8]

# IMU sample (both SDKs): gyro x, y, z [rad/s], acc x, y, z [g], float32
IMU_RECORD = np.dtype(
    [(n, "<f4") for n in ("gyro_x", "gyro_y", "gyro_z", "acc_x", "acc_y", "acc_z")]
)


@dataclass(frozen=True)
class LivoxPoints:
    """Decoded points in packet order, a firing's returns next to each other.

    ``points`` (N, 3) metres in the sensor frame (x forward); ``t_ns`` the point's
    absolute time; ``return_index`` 0, 1, 2 within its firing; ``hit`` False where
    the range is zero (no return), which a live source drops."""

    points: FloatArray
    reflectivity: U8
    tag: U8
    return_index: U8
    t_ns: I64
    hit: NDArray[np.bool_]

    def __len__(self) -> int:
        return int(self.t_ns.shape[0])

    @property
    def n_empty(self) -> int:
        """How many points have zero range."""
        return int(np.count_nonzero(~self.hit))

    def take(self, index: NDArray[np.intp] | NDArray[np.bool_]) -> LivoxPoints:
        return LivoxPoints(
            self.points[index],
            self.reflectivity[index],
            self.tag[index],
            self.return_index[index],
            self.t_ns[index],
            self.hit[index],
        )

    def hits(self) -> LivoxPoints:
        """Only the points with a return."""
        return self.take(self.hit)

    @staticmethod
    def empty() -> LivoxPoints:
        u8 = np.zeros(0, np.uint8)
        return LivoxPoints(np.zeros((0, 3)), u8, u8, u8, np.zeros(0, np.int64), np.zeros(0, bool))

    @staticmethod
    def concat(parts: Sequence[LivoxPoints]) -> LivoxPoints:
        if not parts:
            return LivoxPoints.empty()
        return LivoxPoints(
            *(
                np.concatenate([getattr(p, f) for p in parts])
                for f in LivoxPoints.__dataclass_fields__
            )
        )


@dataclass(frozen=True)
class ImuSamples:
    """IMU samples: ``t_ns`` (N,), ``gyro`` (N, 3) rad/s, ``acc`` (N, 3) in g."""

    t_ns: I64
    gyro: FloatArray
    acc: FloatArray

    def __len__(self) -> int:
        return int(self.t_ns.shape[0])

    def take(self, index: NDArray[np.intp]) -> ImuSamples:
        return ImuSamples(self.t_ns[index], self.gyro[index], self.acc[index])

    @staticmethod
    def empty() -> ImuSamples:
        return ImuSamples(np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((0, 3)))

    @staticmethod
    def concat(parts: Sequence[ImuSamples]) -> ImuSamples:
        if not parts:
            return ImuSamples.empty()
        return ImuSamples(
            *(np.concatenate([getattr(p, f) for p in parts]) for f in ("t_ns", "gyro", "acc"))
        )


@dataclass(frozen=True)
class DecodedPackets:
    """The points and IMU samples of a batch of packets, in packet order."""

    points: LivoxPoints
    imu: ImuSamples


@dataclass(frozen=True)
class RecordLayout:
    """One firing's record: its dtype, number of returns and coordinate kind.

    Field names follow the protocol documents: ``x y z reflectivity tag`` for one
    return, ``x1 … tag1, x2 …`` for several; spherical records name ``depth``."""

    dtype: np.dtype[np.void]
    returns: int
    spherical: bool
    unit_m: float  # metres per count of a Cartesian coordinate or of depth
    tagged: bool

    @property
    def suffixes(self) -> tuple[str, ...]:
        return ("",) if self.returns == 1 else tuple(str(k + 1) for k in range(self.returns))


def cartesian_layout(
    returns: int, tagged: bool, coord: str = "<i4", unit_m: float = 1e-3
) -> RecordLayout:
    """x, y, z (``coord`` integers of ``unit_m``), reflectivity u8 [, tag u8] per return."""
    sfx = ("",) if returns == 1 else tuple(str(k + 1) for k in range(returns))
    fields: list[tuple[str, str]] = []
    for s in sfx:
        fields += [(f"x{s}", coord), (f"y{s}", coord), (f"z{s}", coord), (f"reflectivity{s}", "u1")]
        fields += [(f"tag{s}", "u1")] if tagged else []
    return RecordLayout(np.dtype(fields), returns, False, unit_m, tagged)


def spherical_layout(returns: int, tagged: bool) -> RecordLayout:
    """Single return: depth u32, theta u16, phi u16, reflectivity [, tag]; several
    returns share one direction: theta, phi, then depth, reflectivity, tag per return."""
    if returns == 1:
        fields = [("depth", "<u4"), ("theta", "<u2"), ("phi", "<u2"), ("reflectivity", "u1")]
        fields += [("tag", "u1")] if tagged else []
    else:
        fields = [("theta", "<u2"), ("phi", "<u2")]
        for k in range(1, returns + 1):
            fields += [(f"depth{k}", "<u4"), (f"reflectivity{k}", "u1"), (f"tag{k}", "u1")]
    return RecordLayout(np.dtype(fields), returns, True, 1e-3, tagged)


def read_records(rec: NDArray[np.void], layout: RecordLayout, t_firing: I64) -> LivoxPoints:
    """Points of records ``rec`` (any shape S) fired at ``t_firing`` (shape S), flattened
    firing-major with each firing's returns next to each other."""
    R = layout.returns
    shape = (*rec.shape, R)
    xyz = np.empty((*shape, 3))
    refl = np.empty(shape, np.uint8)
    tag = np.zeros(shape, np.uint8)
    if layout.spherical:
        θ = np.deg2rad(rec["theta"] * 0.01)
        φ = np.deg2rad(rec["phi"] * 0.01)
        # unit direction from zenith θ and azimuth φ
        u = np.stack([np.sin(θ) * np.cos(φ), np.sin(θ) * np.sin(φ), np.cos(θ)], axis=-1)
    for k, s in enumerate(layout.suffixes):
        if layout.spherical:
            xyz[..., k, :] = rec[f"depth{s}"][..., None] * layout.unit_m * u
        else:
            for a, name in enumerate("xyz"):
                xyz[..., k, a] = rec[f"{name}{s}"] * layout.unit_m
        refl[..., k] = rec[f"reflectivity{s}"]
        if layout.tagged:
            tag[..., k] = rec[f"tag{s}"]
    n = int(np.prod(shape))
    xyz = xyz.reshape(n, 3)
    return LivoxPoints(
        points=xyz,
        reflectivity=refl.reshape(n),
        tag=tag.reshape(n),
        return_index=np.broadcast_to(np.arange(R, dtype=np.uint8), shape).reshape(n),
        t_ns=np.repeat(np.asarray(t_firing, np.int64).reshape(-1), R),
        hit=np.any(xyz != 0.0, axis=1),
    )


def _quantise(values: FloatArray, unit: float, dtype: str, what: str) -> NDArray[np.generic]:
    q = np.rint(np.asarray(values, np.float64) / unit)
    info = np.iinfo(np.dtype(dtype))
    if q.size and not (np.all(np.isfinite(q)) and q.min() >= info.min and q.max() <= info.max):
        raise InputError(f"{what} out of range for {np.dtype(dtype)} in units of {unit} m")
    return q.astype(dtype)


def write_records(
    points: FloatArray, reflectivity: U8, tag: U8 | None, layout: RecordLayout
) -> NDArray[np.void]:
    """Records of firings from ``points`` (F·R, 3) metres, firing-major as read_records
    gives them.  Spherical multi-return records share one direction: that of the
    firing's farthest return."""
    R = layout.returns
    p = np.asarray(points, np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or p.shape[0] % R:
        raise InputError(f"points must be (F·{R}, 3), got {p.shape}")
    F = p.shape[0] // R
    p = p.reshape(F, R, 3)
    refl = np.asarray(reflectivity, np.uint8).reshape(F, R)
    tags = np.zeros((F, R), np.uint8) if tag is None else np.asarray(tag, np.uint8).reshape(F, R)
    rec = np.zeros(F, layout.dtype)
    if layout.spherical:
        r = np.linalg.norm(p, axis=2)  # (F, R)
        far = p[np.arange(F), np.argmax(r, axis=1)]
        ρ = np.maximum(np.linalg.norm(far, axis=1), 1e-300)
        θ = np.arccos(np.clip(far[:, 2] / ρ, -1.0, 1.0))  # zenith
        φ = np.mod(np.arctan2(far[:, 1], far[:, 0]), 2 * np.pi)  # azimuth in [0, 2π)
        rec["theta"] = np.rint(np.rad2deg(θ) * 100.0)
        rec["phi"] = np.mod(np.rint(np.rad2deg(φ) * 100.0), 36000)
    for k, s in enumerate(layout.suffixes):
        if layout.spherical:
            rec[f"depth{s}"] = _quantise(r[:, k], layout.unit_m, "<u4", "depth")
        else:
            coord = layout.dtype[f"x{s}"].str
            for a, name in enumerate("xyz"):
                rec[f"{name}{s}"] = _quantise(p[:, k, a], layout.unit_m, coord, name)
        rec[f"reflectivity{s}"] = refl[:, k]
        if layout.tagged:
            rec[f"tag{s}"] = tags[:, k]
    return rec


def read_imu(rec: NDArray[np.void], t_ns: I64) -> ImuSamples:
    """IMU samples of records ``rec`` (any shape) at ``t_ns`` (same shape)."""
    flat = rec.reshape(-1)
    gyro = np.stack([flat[f"gyro_{a}"] for a in "xyz"], axis=1).astype(np.float64)
    acc = np.stack([flat[f"acc_{a}"] for a in "xyz"], axis=1).astype(np.float64)
    return ImuSamples(np.asarray(t_ns, np.int64).reshape(-1), gyro, acc)


def write_imu(gyro: FloatArray, acc: FloatArray) -> NDArray[np.void]:
    g, a = np.asarray(gyro, np.float64), np.asarray(acc, np.float64)
    if g.ndim != 2 or g.shape[1] != 3 or a.shape != g.shape:
        raise InputError(f"gyro and acc must both be (N, 3), got {g.shape} and {a.shape}")
    rec = np.zeros(g.shape[0], IMU_RECORD)
    for i, axis in enumerate("xyz"):
        rec[f"gyro_{axis}"], rec[f"acc_{axis}"] = g[:, i], a[:, i]
    return rec


def packets_from_rows(header: NDArray[np.void], records: NDArray[np.void]) -> list[bytes]:
    """Packets of header rows (K,) followed by record rows (K, n)."""
    K = header.shape[0]
    rows = np.concatenate(
        [header.view(np.uint8).reshape(K, -1), records.reshape(K, -1).view(np.uint8)], axis=1
    )
    return [row.tobytes() for row in rows]


# (points, imu) of one group of same-layout packets, given their stacked bytes (P, L)
# and per-packet facts from the inspection
GroupDecoder = Callable[
    [int, NDArray[np.uint8], list[object]], tuple[LivoxPoints | None, ImuSamples | None]
]


def decode_batch(
    packets: Sequence[Bytes],
    inspect: Callable[[bytes], tuple[int, object] | str],
    decode_group: GroupDecoder,
) -> tuple[DecodedPackets, int]:
    """Decode many packets, grouping those of one layout (``inspect`` → (key, facts), or a
    problem string for a malformed packet) into one 2-D uint8 array each; the output
    keeps packet order.  Returns (decoded, number of malformed packets)."""
    groups: dict[int, tuple[list[int], list[object]]] = {}
    bad = 0
    raw = [bytes(p) for p in packets]
    for i, buf in enumerate(raw):
        found = inspect(buf)
        if isinstance(found, str):
            bad += 1
            continue
        key, facts = found
        idx, infos = groups.setdefault(key, ([], []))
        idx.append(i)
        infos.append(facts)
    point_parts: list[tuple[I64, LivoxPoints]] = []
    imu_parts: list[tuple[I64, ImuSamples]] = []
    for key, (idx, infos) in groups.items():
        rows = np.frombuffer(b"".join(raw[i] for i in idx), np.uint8).reshape(len(idx), -1)
        pts, imu = decode_group(key, rows, infos)
        if pts is not None:
            point_parts.append((np.repeat(np.array(idx, np.int64), len(pts) // len(idx)), pts))
        if imu is not None:
            imu_parts.append((np.repeat(np.array(idx, np.int64), len(imu) // len(idx)), imu))
    points = LivoxPoints.concat([p for _, p in point_parts])
    imu = ImuSamples.concat([s for _, s in imu_parts])
    if len(point_parts) > 1:  # restore packet order across groups
        points = points.take(np.argsort(np.concatenate([i for i, _ in point_parts]), kind="stable"))
    if len(imu_parts) > 1:
        imu = imu.take(np.argsort(np.concatenate([i for i, _ in imu_parts]), kind="stable"))
    return DecodedPackets(points, imu), bad


def decode_one(
    buf: Bytes,
    inspect: Callable[[bytes], tuple[int, object] | str],
    decode_group: GroupDecoder,
    what: str,
) -> DecodedPackets:
    """One packet through the batch path; DecodeError naming the problem if malformed."""
    found = inspect(bytes(buf))
    if isinstance(found, str):
        raise DecodeError(f"{what}: {found}")
    decoded, _ = decode_batch([buf], inspect, decode_group)
    return decoded
