"""Which positions and states of the track layer (``track.multi``) are of one object:
tracks that stay within the clustering's radius of each other, and a cluster that is
a piece of a moving track's object (its returns of one frame spread along its path).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray

__all__ = ["close_pairs", "one_object", "within_smear"]


def close_pairs(p: FloatArray, radius: float) -> NDArray[np.intp]:
    """(M, 2) the index pairs i < j of positions ``p`` (K, 3) within ``radius`` [m]."""
    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=2)
    i, j = np.nonzero(np.triu(d <= radius, k=1))
    return np.column_stack([i, j]).astype(np.intp)


def within_smear(
    points: FloatArray, x: FloatArray, period: float, radius: float
) -> NDArray[np.bool_]:
    """Which ``points`` (..., 3) lie within ``radius`` [m] of the path an object of
    state ``x`` (..., 6) = [p, v] sweeps over ±``period`` [s]: the capsule around the
    segment p ± v T, the ball of that radius at rest.  The two broadcast together.

    a = clip((c − p)·v̂, −|v| T, |v| T) is how far along its motion the point c lies,
    and it is within when |(c − p) − a v̂| ≤ ρ.
    """
    c = np.asarray(points, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    d = c - x[..., :3]  # c − p
    speed = np.linalg.norm(x[..., 3:], axis=-1, keepdims=True)  # |v|
    u = np.divide(x[..., 3:], speed, out=np.zeros_like(x[..., 3:]), where=speed > 0)  # v̂
    reach = speed * period  # |v| T
    a = np.clip(np.sum(d * u, axis=-1, keepdims=True), -reach, reach)
    return np.asarray(np.linalg.norm(d - a * u, axis=-1) <= radius)


def one_object(
    x_piece: FloatArray, x_track: FloatArray, period: float, radius: float
) -> NDArray[np.bool_]:
    """Which pieces of states ``x_piece`` (..., 6) are of the object of the tracks
    ``x_track`` (..., 6), the two broadcast together: each within the other's smear
    over ±``period`` (``within_smear``).

    A frame's returns of an object moving at v span its integration period T, and the
    clustering may part them along v: at 15 m/s the returns of a 0.1 s frame lie along
    1.5 m.  Both ways, so that a piece beside a fast track, or one moving across it, is
    another object.
    """
    pieces = np.asarray(x_piece, dtype=np.float64)
    tracks = np.asarray(x_track, dtype=np.float64)
    return within_smear(pieces[..., :3], tracks, period, radius) & within_smear(
        tracks[..., :3], pieces, period, radius
    )
