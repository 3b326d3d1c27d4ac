"""Velodyne VLP-16 data packets: the wire layout, its timing, and a numpy codec.

Source: Velodyne "VLP-16 User Manual" (63-9243 Rev D), chapter 9.  A data packet is
the 1206-byte payload of a UDP datagram to port 2368 (1248 bytes with the 42 bytes of
Ethernet, IP and UDP headers), little-endian::

    12 data blocks of 100 bytes:  flag FF EE | azimuth u16 [0.01°, 0-35999]
                                  | 32 data points: distance u16 [2 mm], reflectivity u8
    1200 timestamp u32 [µs past the hour] | 1204 return mode | 1205 product ID

A *firing sequence* fires the 16 lasers one after the other, 2.304 µs apart, then
recharges: 55.296 µs in all.  A data block holds two sequences (data points 0-15 the
first, 16-31 the second, each in laser-ID order), so a packet holds 24 and spans
24 × 55.296 µs = 1327.104 µs (753.5 packets/s).  The timestamp is the time of the
packet's first firing, and data point k of block b fired at (§9.4)

    single return:  t = timestamp + 55.296 µs · (2b + ⌊k/16⌋) + 2.304 µs · (k mod 16)
    dual return:    t = timestamp + 55.296 µs · (2⌊b/2⌋ + ⌊k/16⌋) + 2.304 µs · (k mod 16)

(in dual-return mode blocks 2i and 2i + 1 hold the last and the strongest return of
the same two sequences, so a packet spans 12 sequences).  The block's azimuth is the
head's at its first firing; it grows with time (the head turns clockwise seen from
above; the manual interpolates between blocks, §9.5).  A distance of 0 is no return.
The factory bytes (§9.3.1.7, Table 9-2) name the return mode (0x37 strongest, 0x38
last, 0x39 dual) and the product (0x22 VLP-16 and Puck LITE, 0x24 Puck Hi-Res, …).

The 16 lasers' elevations and vertical corrections (Table 9-1) are by laser ID; the
manual adds the correction to z "after computing X, Y, Z" (the laser's offset from
the sensor origin), so a return at range r along laser c's beam d is

    p = r · d + (0, 0, δ_c)          and conversely   r = |p − (0, 0, δ_c)|.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray

__all__ = [
    "BLOCKS",
    "CHANNELS",
    "DATA_PORT",
    "DUAL",
    "ELEVATION_DEG",
    "FIRING_CYCLE_NS",
    "FIRING_INTERVAL_NS",
    "HOUR_US",
    "LASERS",
    "LASER_OF_RING",
    "LAST",
    "PACKET",
    "PACKET_BYTES",
    "PRODUCTS",
    "RETURN_MODES",
    "STRONGEST",
    "VERTICAL_CORRECTION_MM",
    "VLP16",
    "Packets",
    "beam_range",
    "block_offsets_ns",
    "decode_packets",
    "encode_packets",
    "firing_offsets_ns",
    "packet_span_ns",
]

DATA_PORT = 2368  # the sensor's default destination port for data packets
PACKET_BYTES = 1206
BLOCKS, CHANNELS, LASERS = 12, 32, 16
BLOCK_FLAG = 0xEEFF  # the bytes FF EE read as a little-endian u16
FIRING_CYCLE_NS = 55_296  # one firing sequence: 16 firings and the recharge
FIRING_INTERVAL_NS = 2_304  # between two lasers' firings
DISTANCE_UNIT_M = 0.002
AZIMUTH_UNITS = 36_000  # hundredths of a degree in a turn
HOUR_US = 3_600_000_000
STRONGEST, LAST, DUAL = 0x37, 0x38, 0x39
RETURN_MODES = {STRONGEST: "strongest", LAST: "last", DUAL: "dual"}
VLP16 = 0x22
PRODUCTS = {
    0x21: "HDL-32E",
    VLP16: "VLP-16 or Puck LITE",
    0x24: "Puck Hi-Res",
    0x28: "VLP-32C",
    0x31: "Velarray",
    0x63: "VLS-128",
}

# Table 9-1, by laser ID (the firing order).
ELEVATION_DEG = (-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15)
VERTICAL_CORRECTION_MM = (
    11.2, -0.7, 9.7, -2.2, 8.1, -3.7, 6.6, -5.1, 5.1, -6.6, 3.7, -8.1, 2.2, -9.7, 0.7, -11.2,
)  # fmt: skip
# The laser ID of each ring, rings numbered by elevation from the lowest beam (the
# "ring" of the ROS drivers and velodyne-decoder): 0, 2, 4, …, 14, 1, 3, …, 15.
LASER_OF_RING = tuple(int(i) for i in np.argsort(ELEVATION_DEG, kind="stable"))

_POINT = np.dtype([("distance", "<u2"), ("reflectivity", "u1")])
_BLOCK = np.dtype([("flag", "<u2"), ("azimuth", "<u2"), ("points", _POINT, (CHANNELS,))])
PACKET = np.dtype(
    [("blocks", _BLOCK, (BLOCKS,)), ("stamp_us", "<u4"), ("return_mode", "u1"), ("product", "u1")]
)
assert PACKET.itemsize == PACKET_BYTES


def _mode_check(return_mode: int) -> bool:
    if return_mode not in RETURN_MODES:
        raise InputError(
            f"unknown Velodyne return mode 0x{return_mode:02X} "
            "(0x37 strongest, 0x38 last, 0x39 dual)"
        )
    return return_mode == DUAL


def firing_offsets_ns(return_mode: int = STRONGEST) -> NDArray[np.int64]:
    """(12, 32): each data point's firing time after the packet's timestamp [ns] (§9.4)."""
    dual = _mode_check(return_mode)
    b = np.arange(BLOCKS)[:, None]
    k = np.arange(CHANNELS)[None, :]
    block_seq = 2 * (b // 2) if dual else 2 * b
    seq = block_seq + k // LASERS
    return (seq * FIRING_CYCLE_NS + (k % LASERS) * FIRING_INTERVAL_NS).astype(np.int64)


def block_offsets_ns(return_mode: int = STRONGEST) -> NDArray[np.int64]:
    """(12,): each block's first firing after the packet's timestamp [ns]."""
    return firing_offsets_ns(return_mode)[:, 0].copy()


def packet_span_ns(return_mode: int = STRONGEST) -> int:
    """Time from one packet's first firing to the next's [ns]: 24 firing sequences
    (12 in dual-return mode)."""
    return (12 if _mode_check(return_mode) else 24) * FIRING_CYCLE_NS


@dataclass(frozen=True, slots=True)
class Packets:
    """Well-formed packets as arrays: ``azimuth`` (n, 12) [0.01°], ``distance`` (n, 12,
    32) [2 mm units, 0: no return], ``reflectivity`` (n, 12, 32), ``stamp_us`` (n,)
    [µs past the hour], ``return_mode`` and ``product`` (n,)."""

    azimuth: NDArray[np.uint16]
    distance: NDArray[np.uint16]
    reflectivity: NDArray[np.uint8]
    stamp_us: NDArray[np.int64]
    return_mode: NDArray[np.uint8]
    product: NDArray[np.uint8]

    def __len__(self) -> int:
        return len(self.stamp_us)


def decode_packets(packets: Sequence[bytes]) -> tuple[Packets, NDArray[np.bool_]]:
    """The well-formed ``packets`` as arrays, and which of them were well formed: 1206
    bytes, every block flagged FF EE with an azimuth below 36000, a known return mode."""
    ok = np.array([len(p) == PACKET_BYTES for p in packets], dtype=bool)
    raw = np.frombuffer(b"".join(p for p in packets if len(p) == PACKET_BYTES), PACKET)
    if len(raw):
        good = (
            np.all(raw["blocks"]["flag"] == BLOCK_FLAG, axis=1)
            & np.all(raw["blocks"]["azimuth"] < AZIMUTH_UNITS, axis=1)
            & np.isin(raw["return_mode"], list(RETURN_MODES))
        )
        ok[ok] = good
        raw = raw[good]
    blocks = raw["blocks"]
    return (
        Packets(
            azimuth=blocks["azimuth"].astype(np.uint16),
            distance=blocks["points"]["distance"].astype(np.uint16),
            reflectivity=blocks["points"]["reflectivity"].astype(np.uint8),
            stamp_us=raw["stamp_us"].astype(np.int64),
            return_mode=raw["return_mode"].astype(np.uint8),
            product=raw["product"].astype(np.uint8),
        ),
        ok,
    )


def encode_packets(
    distance_m: FloatArray,
    reflectivity: NDArray[np.uint8],
    azimuth_deg: FloatArray,
    stamp_us: NDArray[np.int64],
    *,
    return_mode: int = STRONGEST,
    product: int = VLP16,
) -> list[bytes]:
    """Packets of ``distance_m`` (n, 12, 32) [m] and ``reflectivity`` (n, 12, 32), block
    azimuths ``azimuth_deg`` (n, 12) and timestamps ``stamp_us`` (n,) [µs; taken modulo
    the hour].  Distances are rounded to 2 mm; a distance that is not finite, not above
    0 or beyond the field's 131.07 m is sent as 0, no return.  Azimuths are rounded to
    0.01° and taken modulo 360°."""
    _mode_check(return_mode)
    d = np.asarray(distance_m, np.float64)
    n = len(d)
    if (
        d.shape != (n, BLOCKS, CHANNELS)
        or np.shape(reflectivity) != d.shape
        or np.shape(azimuth_deg) != (n, BLOCKS)
        or np.shape(stamp_us) != (n,)
    ):
        raise InputError(
            "Velodyne packets need distances and reflectivities (n, 12, 32), azimuths "
            f"(n, 12) and n timestamps; got {d.shape}, {np.shape(reflectivity)}, "
            f"{np.shape(azimuth_deg)}, {np.shape(stamp_us)}"
        )
    units = np.rint(np.where(np.isfinite(d), d, 0.0) / DISTANCE_UNIT_M)
    units[(units < 1) | (units > 0xFFFF)] = 0
    out = np.zeros(n, PACKET)
    out["blocks"]["flag"] = BLOCK_FLAG
    az = np.rint(np.asarray(azimuth_deg, np.float64) * 100.0).astype(np.int64) % AZIMUTH_UNITS
    out["blocks"]["azimuth"] = az
    out["blocks"]["points"]["distance"] = units.astype(np.uint16)
    out["blocks"]["points"]["reflectivity"] = np.asarray(reflectivity, np.uint8)
    out["stamp_us"] = np.asarray(stamp_us, np.int64) % HOUR_US
    out["return_mode"] = return_mode
    out["product"] = product
    return [row.tobytes() for row in out]


def beam_range(xyz: FloatArray, laser: NDArray[np.intp]) -> FloatArray:
    """The range r = |p − (0, 0, δ_c)| [m] along laser c's beam of points ``xyz`` (…, 3)
    in the sensor's own frame, lasers ``laser`` (broadcast against xyz[..., 0])."""
    corr = np.asarray(VERTICAL_CORRECTION_MM, np.float64)[laser] * 1e-3
    p = np.asarray(xyz, np.float64)
    return np.sqrt(p[..., 0] ** 2 + p[..., 1] ** 2 + (p[..., 2] - corr) ** 2)
