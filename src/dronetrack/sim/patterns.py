"""Scan patterns: when each pulse is fired and in which direction.

A pattern maps a time window to the pulses fired in it: times, unit directions
in the sensor frame (x forward, y left, z up), line/channel indices and the
beam origins in the sensor frame.  Patterns run continuously from t = 0, so the
pattern of a frame depends on its absolute time (Livox prisms never reset).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import SensorError
from dronetrack.geometry import FloatArray, direction_from_azimuth_elevation
from dronetrack.io.tables import read_csv_columns

__all__ = [
    "AVIA_PRISMS",
    "MID40_PRISMS",
    "MID360_PATTERN",
    "Pulses",
    "RisleyPattern",
    "ScanPattern",
    "SinusoidalSpinPattern",
    "SpinningPattern",
    "TablePattern",
    "avia_pattern",
    "load_pattern_table",
    "mid40_pattern",
    "refract",
    "risley_directions",
    "vlp16_pattern",
]


@dataclass(frozen=True, slots=True)
class Pulses:
    """Pulses fired in a time window."""

    t: FloatArray  # (N,) firing time [s]
    dirs: FloatArray  # (N, 3) unit directions, sensor frame
    line: NDArray[np.uint8]  # (N,) line / laser index
    origins: FloatArray  # (N, 3) beam origins, sensor frame [m]
    max_origin_offset: float = 0.0  # bound on |origins| [m]

    def __len__(self) -> int:
        return len(self.t)


class ScanPattern(Protocol):
    """Anything that fires pulses."""

    @property
    def n_lines(self) -> int:
        """Number of laser lines (channels)."""
        ...

    def pulses(self, t_start: float, t_end: float) -> Pulses:
        """All pulses with t_start ≤ t < t_end."""
        ...


def _pulse_indices(t_start: float, t_end: float, rate_hz: float) -> NDArray[np.int64]:
    """Indices k of pulses fired at t_k = k / rate in [t_start, t_end)."""
    # A small tolerance keeps frame boundaries such as 0.1 s · 240 kHz exact.
    k0 = math.ceil(t_start * rate_hz - 1e-6)
    k1 = math.ceil(t_end * rate_hz - 1e-6)
    return np.arange(max(k0, 0), max(k1, 0), dtype=np.int64)


# ---------------------------------------------------------------------------
# Risley prisms (Livox Mid-40, Avia)
# ---------------------------------------------------------------------------


@nb.njit(cache=True, fastmath=True)
def _refract(
    dx: float, dy: float, dz: float, nx: float, ny: float, nz: float, r: float
) -> tuple[float, float, float, bool]:
    """Vector Snell refraction of unit d at a surface with unit normal n.

    n points against d; r = n_a / n_b for a ray going from index n_a into n_b:
        cos θ_i = −n·d
        sin² θ_r = r² (1 − cos² θ_i)            (> 1: total internal reflection)
        d' = r d + (r cos θ_i − √(1 − sin² θ_r)) n
    d' is a unit vector when d and n are.  Returns d' and False on total
    internal reflection (d unchanged).
    """
    cos_i = -(dx * nx + dy * ny + dz * nz)
    sin2_r = r * r * (1.0 - cos_i * cos_i)
    if sin2_r > 1.0:
        return dx, dy, dz, False
    k = r * cos_i - np.sqrt(1.0 - sin2_r)
    return r * dx + k * nx, r * dy + k * ny, r * dz + k * nz, True


def refract(d: FloatArray, n: FloatArray, n_a: float, n_b: float) -> tuple[FloatArray, bool]:
    """``_refract`` on (3,) arrays: the refracted direction and whether it exists."""
    ox, oy, oz, ok = _refract(d[0], d[1], d[2], n[0], n[1], n[2], n_a / n_b)
    return np.array([ox, oy, oz]), bool(ok)


@nb.njit(cache=True, fastmath=True)
def _risley_kernel(
    k0: int,
    n: int,
    rate_hz: float,
    incident: FloatArray,
    wedge: FloatArray,
    freq: FloatArray,
    index: FloatArray,
    n_air: float,
) -> tuple[FloatArray, NDArray[np.bool_]]:
    n_prisms = wedge.shape[0]
    n_channels = incident.shape[0]
    # Prism i is at angle ω_i t_k with t_k = k / rate.  Consecutive pulses are one
    # fixed step apart, so (cos, sin) of the angle advance by a rotation
    # (complex multiplication) instead of two trig calls per prism and pulse.
    cw = np.empty(n_prisms)
    sw = np.empty(n_prisms)
    c_step = np.empty(n_prisms)
    s_step = np.empty(n_prisms)
    sa = np.empty(n_prisms)
    ca = np.empty(n_prisms)
    for p in range(n_prisms):
        w0 = 2.0 * np.pi * ((freq[p] * k0 / rate_hz) % 1.0)
        cw[p] = np.cos(w0)
        sw[p] = np.sin(w0)
        c_step[p] = np.cos(2.0 * np.pi * freq[p] / rate_hz)
        s_step[p] = np.sin(2.0 * np.pi * freq[p] / rate_hz)
        sa[p] = np.sin(abs(wedge[p]))
        ca[p] = np.cos(abs(wedge[p]))
    r_in = n_air / index  # index ratio entering the glass
    r_out = index / n_air  # and leaving it
    out = np.empty((n, 3))
    ok = np.ones(n, dtype=np.bool_)
    for i in range(n):
        c = (k0 + i) % n_channels
        dx, dy, dz = incident[c, 0], incident[c, 1], incident[c, 2]
        good = True
        for p in range(n_prisms):
            # A flat face has normal −f = (0, −1, 0), with f = +y forward.
            if wedge[p] > 0.0:
                # Wedge on the entry side: N1 = (sin ωt sin α, −cos α, cos ωt sin α), N2 = −f
                dx, dy, dz, ok1 = _refract(
                    dx, dy, dz, sw[p] * sa[p], -ca[p], cw[p] * sa[p], r_in[p]
                )
                dx, dy, dz, ok2 = _refract(dx, dy, dz, 0.0, -1.0, 0.0, r_out[p])
            else:
                # Wedge on the exit side: N1 = −f, N2 = (−sin ωt sin α, −cos α, −cos ωt sin α)
                dx, dy, dz, ok1 = _refract(dx, dy, dz, 0.0, -1.0, 0.0, r_in[p])
                dx, dy, dz, ok2 = _refract(
                    dx, dy, dz, -sw[p] * sa[p], -ca[p], -cw[p] * sa[p], r_out[p]
                )
            good = good and ok1 and ok2
            # (cos, sin)(w + Δw) = (cos w cos Δw − sin w sin Δw, sin w cos Δw + cos w sin Δw)
            cw[p], sw[p] = (
                cw[p] * c_step[p] - sw[p] * s_step[p],
                sw[p] * c_step[p] + cw[p] * s_step[p],
            )
        # Each refraction keeps |d| = 1 up to rounding; renormalise once at the end.
        norm = np.sqrt(dx * dx + dy * dy + dz * dz)
        # Prism frame (x, y = forward, z) to sensor frame (x forward, y left, z up):
        # (x, y, z)_sensor = (d_y, d_z, d_x).
        out[i, 0] = dy / norm
        out[i, 1] = dz / norm
        out[i, 2] = dx / norm
        ok[i] = good
    return out, ok


def risley_directions(
    k0: int,
    n: int,
    rate_hz: float,
    incident: FloatArray,
    prisms: FloatArray,
    n_air: float = 1.0,
) -> FloatArray:
    """Beam directions of pulses k0 … k0+n−1 after a stack of rotating wedge prisms.

    Model (Li, Liu & Sun, Opt. Express 25:7677, 2017): pulse k is fired at
    t_k = k / rate by laser k mod C along its incident direction (rows of
    ``incident`` (C, 3), prism frame with f = +y forward).  Prism i has wedge
    angle α_i (its sign says which face is inclined), rotation rate f_i [Hz] and
    index n_i, turns to ω_i t_k = 2π f_i t_k and refracts the beam at both faces
    (vector Snell's law, ``refract``).

    prisms: (P, 3) rows of (wedge angle [rad], rate [Hz], refractive index).
    Returns (n, 3) unit directions in the *sensor* frame (x forward, y left,
    z up), mapped from the prism frame by (x, y, z)_sensor = (d_y, d_z, d_x) so
    that the Avia's channel offsets lie along the sensor's vertical axis.
    """
    d, ok = _risley_kernel(
        int(k0),
        int(n),
        float(rate_hz),
        np.ascontiguousarray(incident, dtype=np.float64),
        np.ascontiguousarray(prisms[:, 0]),
        np.ascontiguousarray(prisms[:, 1]),
        np.ascontiguousarray(prisms[:, 2]),
        n_air,
    )
    if not np.all(ok):
        raise SensorError("Risley prism parameters cause total internal reflection")
    return d


def _prisms(rows: list[tuple[float, float, float]]) -> FloatArray:
    """Prism table from (wedge angle [deg], rate [Hz], refractive index) rows."""
    a = np.array(rows, dtype=np.float64)
    a[:, 0] = np.radians(a[:, 0])
    return a


# Helios++ parameter sets (scanners_tls.xml @ fd94d1ff; sensor_physics.md §1.3).
MID40_PRISMS = _prisms([(18.7481, -121.5657, 1.51), (17.9634, 77.7430, 1.51)])
# Avia: Helios lists f3 = 213.1611 Hz.  The rosette passes through the centre when
# the two large prisms cancel and the small one cancels their residue, which holds
# for every pass only when f3 = 2 f2 − f1 = 213.1527 Hz.  Helios' value misses that
# by 0.0084 Hz, so its centre empties and refills with a 119 s period (a few points
# per 0.5 s near the axis at t = 60 s against 1,350 at t = 0).  The Avia's dense
# centre, which seed 000 relies on, does not fade: we take f3 = 2 f2 − f1 (0.004 %).
_AVIA_F1, _AVIA_F2 = -131.5463, 40.8032
AVIA_PRISMS = _prisms(
    [
        (30.8856, _AVIA_F1, 1.51),
        (29.7735, _AVIA_F2, 1.51),
        (3.1351, 2.0 * _AVIA_F2 - _AVIA_F1, 1.51),
    ]
)
# Avia incident beams of its six lasers in the prism frame (x, y = forward, z).
AVIA_INCIDENT = np.array(
    [
        [-0.05216070, 0.99863870, 0.0],
        [-0.03237635, 0.99947575, 0.0],
        [-0.01079672, 0.99994171, 0.0],
        [+0.01079672, 0.99994171, 0.0],
        [+0.03237635, 0.99947575, 0.0],
        [+0.05300785, 0.99859410, 0.0],
    ]
)


@dataclass(frozen=True, slots=True)
class RisleyPattern:
    """A Livox rosette: pulse k at t_k = k / rate on line k mod n_lines."""

    prisms: FloatArray
    incident: FloatArray
    rate_hz: float

    @property
    def n_lines(self) -> int:
        return len(self.incident)

    def pulses(self, t_start: float, t_end: float) -> Pulses:
        k = _pulse_indices(t_start, t_end, self.rate_hz)
        k0 = int(k[0]) if len(k) else 0
        dirs = risley_directions(k0, len(k), self.rate_hz, self.incident, self.prisms)
        line = (k % self.n_lines).astype(np.uint8)
        return Pulses(t=k / self.rate_hz, dirs=dirs, line=line, origins=np.zeros_like(dirs))


def avia_pattern() -> RisleyPattern:
    """Livox Avia: three prisms, six lines, 240,000 points/s."""
    return RisleyPattern(prisms=AVIA_PRISMS, incident=AVIA_INCIDENT, rate_hz=240_000.0)


def mid40_pattern() -> RisleyPattern:
    """Livox Mid-40: two prisms, one line, 100,000 points/s."""
    return RisleyPattern(
        prisms=MID40_PRISMS, incident=np.array([[0.0, 1.0, 0.0]]), rate_hz=100_000.0
    )


# ---------------------------------------------------------------------------
# Spinning multi-laser sensors (Velodyne VLP-16)
# ---------------------------------------------------------------------------

VLP16_ELEVATION_DEG = (-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15)
VLP16_VERTICAL_OFFSET_MM = (
    11.2,
    -0.7,
    9.7,
    -2.2,
    8.1,
    -3.7,
    6.6,
    -5.1,
    5.1,
    -6.6,
    3.7,
    -8.1,
    2.2,
    -9.7,
    0.7,
    -11.2,
)


@dataclass(frozen=True, slots=True)
class SpinningPattern:
    """A spinning head firing its lasers in sequence.

    Laser c of firing sequence s fires at t = s·T_cycle + c·T_fire; the head
    turns clockwise seen from above, so the azimuth is az(t) = az0 − 2π (rpm/60) t.
    """

    elevation: FloatArray  # (C,) [rad], by laser id
    vertical_offset: FloatArray  # (C,) beam origin height above the sensor origin [m]
    firing_interval_s: float
    cycle_s: float
    rpm: float
    azimuth0: float = 0.0

    def __post_init__(self) -> None:
        if not 300.0 <= self.rpm <= 1200.0:
            raise SensorError(f"spin rate must be within 300-1200 rpm, got {self.rpm:g}")

    @property
    def n_lines(self) -> int:
        return len(self.elevation)

    @property
    def revolution_s(self) -> float:
        return 60.0 / self.rpm

    def pulses(self, t_start: float, t_end: float) -> Pulses:
        # Firing sequences with a laser in [t_start, t_end): s T_cycle + (C − 1) T_fire ≥ t_start.
        last_offset = (self.n_lines - 1) * self.firing_interval_s
        seq = _pulse_indices(t_start - last_offset, t_end, 1.0 / self.cycle_s)
        s0 = int(seq[0]) if len(seq) else 0
        t, dirs, origins, line = _spinning_kernel(
            s0,
            len(seq),
            t_start,
            t_end,
            self.cycle_s,
            self.firing_interval_s,
            2.0 * np.pi * self.rpm / 60.0,
            self.azimuth0,
            np.ascontiguousarray(self.elevation),
            np.ascontiguousarray(self.vertical_offset),
        )
        return Pulses(
            t=t,
            dirs=dirs,
            line=line,
            origins=origins,
            max_origin_offset=float(np.max(np.abs(self.vertical_offset))),
        )


@nb.njit(cache=True, fastmath=True)
def _spinning_kernel(
    s0: int,
    n_seq: int,
    t_start: float,
    t_end: float,
    cycle: float,
    interval: float,
    omega: float,
    az0: float,
    elevation: FloatArray,
    offset: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray, NDArray[np.uint8]]:
    n_lines = elevation.shape[0]
    n_max = n_seq * n_lines
    t = np.empty(n_max)
    dirs = np.empty((n_max, 3))
    origins = np.zeros((n_max, 3))
    line = np.empty(n_max, dtype=np.uint8)
    cos_el = np.cos(elevation)
    sin_el = np.sin(elevation)
    k = 0
    for s in range(s0, s0 + n_seq):
        for c in range(n_lines):
            # t = s T_cycle + c T_fire;  az(t) = az0 − ω t
            tk = s * cycle + c * interval
            if tk < t_start or tk >= t_end:
                continue
            az = az0 - omega * tk
            t[k] = tk
            dirs[k, 0] = cos_el[c] * np.cos(az)
            dirs[k, 1] = cos_el[c] * np.sin(az)
            dirs[k, 2] = sin_el[c]
            origins[k, 2] = offset[c]
            line[k] = c
            k += 1
    return t[:k], dirs[:k], origins[:k], line[:k]


def vlp16_pattern(rpm: float = 600.0) -> SpinningPattern:
    """Velodyne VLP-16: 16 lasers, 2.304 µs apart, 55.296 µs firing cycle."""
    return SpinningPattern(
        elevation=np.radians(np.array(VLP16_ELEVATION_DEG, dtype=np.float64)),
        vertical_offset=np.array(VLP16_VERTICAL_OFFSET_MM) * 1e-3,
        firing_interval_s=2.304e-6,
        cycle_s=55.296e-6,
        rpm=rpm,
    )


# ---------------------------------------------------------------------------
# Livox Mid-360 (approximate model) and scan-pattern tables
# ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class SinusoidalSpinPattern:
    """A 360° head whose lasers also sweep in elevation.

    Laser c: az(t) = 2π f_az t + 2π c / C,
             el(t) = el_mid + el_amp · sin(2π f_el t + 2π c / C).
    The two rates are incommensurate, so the pattern never repeats and fills the
    field of view over time.  An approximation of the Mid-360, whose prism
    parameters are not published; replay Livox's own table with ``TablePattern``
    where fidelity matters.
    """

    rate_hz: float
    n_lines: int
    azimuth_rate_hz: float
    elevation_rate_hz: float
    elevation_min: float
    elevation_max: float

    def pulses(self, t_start: float, t_end: float) -> Pulses:
        k = _pulse_indices(t_start, t_end, self.rate_hz)
        t = k / self.rate_hz
        c = k % self.n_lines
        phase = 2.0 * np.pi * c / self.n_lines
        az = 2.0 * np.pi * self.azimuth_rate_hz * t + phase
        mid = 0.5 * (self.elevation_max + self.elevation_min)
        amp = 0.5 * (self.elevation_max - self.elevation_min)
        el = mid + amp * np.sin(2.0 * np.pi * self.elevation_rate_hz * t + phase)
        dirs = direction_from_azimuth_elevation(az, el)
        return Pulses(t=t, dirs=dirs, line=c.astype(np.uint8), origins=np.zeros_like(dirs))


MID360_PATTERN = SinusoidalSpinPattern(
    rate_hz=200_000.0,
    n_lines=4,
    azimuth_rate_hz=10.0 * (1 + 5**0.5) / 3.236,  # ≈ 10 Hz, irrational
    elevation_rate_hz=193.7,
    elevation_min=np.radians(-7.0),
    elevation_max=np.radians(52.0),
)


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
        k = _pulse_indices(t_start, t_end, self.rate_hz)
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
