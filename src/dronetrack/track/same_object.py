"""Which positions and states of the track layer (``track.multi``) are of one object:
tracks that stay within the clustering's radius of each other, and a cluster that is
a piece of a moving track's object (its returns of one frame spread along its path).

Two tracks whose positions have stayed within ``merge_m`` of each other for
``merge_s`` are one object, as the clustering joins any two returns closer than its ε
(``merge_m`` = ε in a run), so two objects that close give one cluster, never two.
Two tracks within ``share_m`` (3 m) for ``merge_s`` that were never both updated in
one frame meanwhile are one object too: they have taken its one cluster in turn (a
track lagging a drone in fast flight, and the one born on its cluster beside it),
where two objects would give two clusters.  Of the two, the one with fewer updates
ends (of equals, the younger), and the object keeps the identity it had longest.
(On ``outdoor-clutter`` a drone 60 m out, its cluster now and then split or missed,
kept two tracks 0.5-0.9 m apart for 20 s, which took its cluster in turn.)
``merge_s`` (1 s) keeps apart two objects that cross: at 2 m/s between them they are
within 1 m of each other for 1 s at most (``PairClocks``).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray

__all__ = ["PairClocks", "close_pairs", "one_object", "within_smear"]

Pair = tuple[int, int]  # two identities, the smaller first


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


class PairClocks:
    """Since when each pair of tracks has been one object's by its place (see the
    module docstring): within ``merge_m``, or within ``share_m`` without a frame in
    which both were updated; the clocks are kept from frame to frame."""

    def __init__(self) -> None:
        self.together: dict[Pair, float] = {}  # (id, id) → close since [s]
        self.sharing: dict[Pair, float] = {}  # (id, id) → one cluster since [s]

    def ending(
        self,
        t: float,
        ids: NDArray[np.int64],
        p: FloatArray,
        updated: NDArray[np.bool_],
        updates: NDArray[np.int64],
        merge: tuple[float, float, float],
    ) -> NDArray[np.bool_]:
        """(K,) the tracks (identities ``ids`` ascending, positions ``p`` (K, 3), whether
        each was updated this frame, their updates over their lives) that end as
        duplicates at ``t``: of each pair one object's for ``merge_s`` (``merge`` =
        (merge_m, share_m, merge_s)), the one with fewer updates, of equals the younger."""
        merge_m, share_m, merge_s = merge
        k = len(ids)
        out = np.zeros(k, dtype=bool)
        close = close_pairs(p, merge_m) if k > 1 else np.empty((0, 2), np.intp)
        near = close_pairs(p, share_m) if k > 1 and share_m > 0 else close[:0]
        now = {(int(ids[i]), int(ids[j])) for i, j in close}
        self.together = {key: self.together.get(key, t) for key in now}
        # a frame that updated both is evidence of two objects: the clock starts again
        both = {(int(ids[i]), int(ids[j])) for i, j in near if updated[i] and updated[j]}
        shared = {(int(ids[i]), int(ids[j])) for i, j in near} - both
        self.sharing = {key: self.sharing.get(key, t) for key in shared}
        if not now and not shared:
            return out
        row = {int(i): n for n, i in enumerate(ids)}
        clocks = {**self.sharing, **self.together}
        for (a, b), since in sorted(clocks.items()):
            if t - since < merge_s:
                continue
            i, j = row[a], row[b]
            if out[i] or out[j]:
                continue
            # a < b: on equal updates the younger, b, ends
            out[j if updates[i] >= updates[j] else i] = True
        return out
