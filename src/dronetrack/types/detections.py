"""The detect stage's clusters and its confirmed candidates."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types._frozen import frozen

__all__ = ["Candidates", "Detections"]


@dataclass(frozen=True, slots=True)
class Detections:
    """The candidate targets the detector found in one frame's foreground, K of them.

    centroids: (K, 3) mean p̄ of each candidate's points, world frame [m].
    counts: (K,) points in each candidate.
    extents: (K, 3) lengths along the principal axes, the axis of largest variance first [m].
    covariances: (K, 3, 3) population covariance (1/n) Σᵢ (pᵢ − p̄)(pᵢ − p̄)ᵀ [m²].
    planarity: (K,) (λ₂ − λ₃) / λ₁ of the covariance eigenvalues λ₁ ≥ λ₂ ≥ λ₃ (0 if λ₁ = 0).
    lows: (K,) the lowest point's height z of each [m]; left out: the centroid's.
    oversized: (M, 3) the points of the frame's clusters that are no candidate, as they
        are larger than a drone (``detect.candidates``) [m]; left out: none.

    Candidates are in the detector's order (DBSCAN's labels); the arrays are read-only.
    The detector does not choose among them: the tracker does, with ``largest()`` or its
    own gate.
    """

    centroids: FloatArray
    counts: NDArray[np.int64]
    extents: FloatArray
    covariances: FloatArray
    planarity: FloatArray
    lows: FloatArray | None = None
    oversized: FloatArray = field(default_factory=lambda: np.empty((0, 3)))

    def __post_init__(self) -> None:
        k = len(self.centroids)
        if self.lows is None:
            object.__setattr__(self, "lows", np.asarray(self.centroids)[:, 2])
        big = self.oversized
        object.__setattr__(self, "oversized", frozen(big, np.float64, (len(big), 3)))
        for name, shape, dtype in (
            ("centroids", (k, 3), np.float64),
            ("counts", (k,), np.int64),
            ("extents", (k, 3), np.float64),
            ("covariances", (k, 3, 3), np.float64),
            ("planarity", (k,), np.float64),
            ("lows", (k,), np.float64),
        ):
            object.__setattr__(self, name, frozen(getattr(self, name), dtype, shape))

    @classmethod
    def empty(cls, oversized: FloatArray | None = None) -> Detections:
        """No candidates (but the points of ``oversized`` clusters, if given)."""
        counts = np.empty(0, dtype=np.int64)
        return cls(
            np.empty((0, 3)),
            counts,
            np.empty((0, 3)),
            np.empty((0, 3, 3)),
            np.empty(0),
            oversized=np.empty((0, 3)) if oversized is None else oversized,
        )

    def __len__(self) -> int:
        return len(self.centroids)

    def largest(self) -> int:
        """Index of the candidate with the most points (the first of equals)."""
        if len(self) == 0:
            raise InputError("no detections to choose the largest of")
        return int(np.argmax(self.counts))


@dataclass(frozen=True, slots=True)
class Candidates:
    """The detect stage's confirmed candidates at the end of a frame, K of them:
    tentative tracks of clusters that persisted over several frames with a plausible
    speed (``detect.tentative``), best first.

    positions: (K, 3) the latest centroid of each, world frame [m].
    velocities: (K, 3) its velocity estimated from the centroids' motion [m/s].
    hits: (K,) frames of the confirmation window in which it was detected.
    sizes: (K,) its largest principal extent in the latest frame [m].
    ids: (K,) a number that stays with a tentative track for its life.
    hovered: (K,) whether it has moved slower than a bird can fly for several frames in
        a row (``detect.tentative``); left out: none has.
    clusters: (K,) the index of this frame's cluster (``Detections``) each one is; −1
        where it is not one of them (a cue's predicted position); left out: none.
    """

    positions: FloatArray
    velocities: FloatArray
    hits: NDArray[np.int64]
    sizes: FloatArray
    ids: NDArray[np.int64]
    hovered: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    clusters: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def __post_init__(self) -> None:
        k = len(self.positions)
        if len(self.hovered) == 0:
            object.__setattr__(self, "hovered", np.zeros(k, dtype=bool))
        if len(self.clusters) == 0:
            object.__setattr__(self, "clusters", np.full(k, -1, dtype=np.int64))
        for name, shape, dtype in (
            ("positions", (k, 3), np.float64),
            ("velocities", (k, 3), np.float64),
            ("hits", (k,), np.int64),
            ("sizes", (k,), np.float64),
            ("ids", (k,), np.int64),
            ("hovered", (k,), np.bool_),
            ("clusters", (k,), np.int64),
        ):
            object.__setattr__(self, name, frozen(getattr(self, name), dtype, shape))

    @classmethod
    def empty(cls) -> Candidates:
        """No confirmed candidates."""
        ints = np.empty(0, dtype=np.int64)
        return cls(np.empty((0, 3)), np.empty((0, 3)), ints, np.empty(0), ints)

    def __len__(self) -> int:
        return len(self.positions)

    def take(self, idx: NDArray[np.intp]) -> Candidates:
        """The candidates at ``idx``, in that order."""
        return Candidates(
            self.positions[idx],
            self.velocities[idx],
            self.hits[idx],
            self.sizes[idx],
            self.ids[idx],
            self.hovered[idx],
            self.clusters[idx],
        )
