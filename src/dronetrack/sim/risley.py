"""Risley-prism scan patterns: the Livox Mid-40 and Avia rosettes.

Each pulse's beam passes a stack of rotating wedge prisms that refract it at
both faces (vector Snell's law); numba kernels trace the beams.  The prism
parameters are Helios++'s, with the Avia's third prism rate corrected so its
dense centre does not fade.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import SensorError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sim.pulses import Pulses, pulse_indices

__all__ = [
    "AVIA_INCIDENT",
    "AVIA_PRISMS",
    "MID40_PRISMS",
    "RisleyPattern",
    "avia_pattern",
    "mid40_pattern",
    "refract",
    "risley_directions",
]


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
        k = pulse_indices(t_start, t_end, self.rate_hz)
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
