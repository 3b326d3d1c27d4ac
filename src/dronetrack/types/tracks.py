"""Every object's track (``track.multi``) and a single-target tracker's estimate."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from dronetrack.geometry.transforms import FloatArray
from dronetrack.types._frozen import frozen

__all__ = ["TRACK_CLASSES", "TrackEstimate", "Tracks"]


TRACK_CLASSES = ("unknown", "drone", "bird", "static")


@dataclass(frozen=True, slots=True)
class Tracks:
    """Every object's track after a frame, K of them (``track.multi``).

    ids: (K,) a track's identity, an integer from 1 that stays with it for its life.
    positions, velocities: (K, 3) its state [m], [m/s], world frame.
    covariances: (K, 6, 6) of [p, v].
    born: (K,) when it began [s].
    updated: (K,) whether this frame's clusters updated it (else it coasts).
    hovered: (K,) whether it moved slower than a bird can fly for a while
        (``detect.tentative``): one-way.
    locked: (K,) the one the turret's tracker holds (at most one).
    classes: (K,) index into ``TRACK_CLASSES``; p_drone: (K,) its probability of being
        a drone (``classify``); left out: unknown, 0.5.
    clusters: (K,) the index of the frame's cluster (``Detections``) that updated it,
        −1 when none did; left out: none.
    last_seen: (K,) the time of its last update [s]; left out: its birth.
    open_air: (K,) whether its life says it is in the open air, neither standing on
        the ground nor part of a structure by its evidence (``classify.rules``'s
        ``in_open_air``); left out: True.
    missed_s: (K,) how long it has been in the sensor's field of view without an
        update since its last one [s]: a track out of view is not missed; left out: 0.
    in_view: (K,) whether the sensor saw where it is this frame: in its field of view at
        the frame's end, or updated by one of the frame's clusters; left out: True.
    """

    ids: NDArray[np.int64]
    positions: FloatArray
    velocities: FloatArray
    covariances: FloatArray
    born: FloatArray
    updated: NDArray[np.bool_]
    hovered: NDArray[np.bool_]
    locked: NDArray[np.bool_]
    classes: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    p_drone: FloatArray = field(default_factory=lambda: np.zeros(0))
    clusters: NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    last_seen: FloatArray = field(default_factory=lambda: np.zeros(0))
    open_air: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))
    missed_s: FloatArray = field(default_factory=lambda: np.zeros(0))
    in_view: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def __post_init__(self) -> None:
        k = len(self.ids)
        if len(self.clusters) == 0 and k:
            object.__setattr__(self, "clusters", np.full(k, -1, dtype=np.int64))
        if len(self.last_seen) == 0 and k:
            object.__setattr__(self, "last_seen", np.asarray(self.born, dtype=np.float64))
        if len(self.classes) == 0 and k:
            object.__setattr__(self, "classes", np.zeros(k, dtype=np.int64))
        if len(self.p_drone) == 0 and k:
            object.__setattr__(self, "p_drone", np.full(k, 0.5))
        if len(self.open_air) == 0 and k:
            object.__setattr__(self, "open_air", np.ones(k, dtype=bool))
        if len(self.missed_s) == 0 and k:
            object.__setattr__(self, "missed_s", np.zeros(k))
        if len(self.in_view) == 0 and k:
            object.__setattr__(self, "in_view", np.ones(k, dtype=bool))
        for name, shape, dtype in (
            ("ids", (k,), np.int64),
            ("positions", (k, 3), np.float64),
            ("velocities", (k, 3), np.float64),
            ("covariances", (k, 6, 6), np.float64),
            ("born", (k,), np.float64),
            ("updated", (k,), np.bool_),
            ("hovered", (k,), np.bool_),
            ("locked", (k,), np.bool_),
            ("classes", (k,), np.int64),
            ("p_drone", (k,), np.float64),
            ("clusters", (k,), np.int64),
            ("last_seen", (k,), np.float64),
            ("open_air", (k,), np.bool_),
            ("missed_s", (k,), np.float64),
            ("in_view", (k,), np.bool_),
        ):
            object.__setattr__(self, name, frozen(getattr(self, name), dtype, shape))

    @classmethod
    def empty(cls) -> Tracks:
        """No tracks."""
        ints, flags = np.empty(0, dtype=np.int64), np.empty(0, dtype=bool)
        return cls(
            ints,
            np.empty((0, 3)),
            np.empty((0, 3)),
            np.empty((0, 6, 6)),
            np.empty(0),
            flags,
            flags,
            flags,
        )

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def position_sigma(self) -> FloatArray:
        """√ of each track's largest position variance (K,) [m]."""
        if len(self) == 0:
            return np.empty(0)
        diag = np.diagonal(self.covariances[:, :3, :3], axis1=1, axis2=2)
        sigma: FloatArray = np.sqrt(np.max(diag, axis=1))
        return sigma

    def with_locked(self, estimate: TrackEstimate, within: float) -> Tracks:
        """These tracks with ``locked`` marking the one nearest a locked ``estimate``
        within ``within`` [m] (none when the estimate is not locked)."""
        locked = np.zeros(len(self), dtype=bool)
        if estimate.tracked and len(self):
            gap = np.linalg.norm(self.positions - estimate.position, axis=1)
            k = int(np.argmin(gap))
            locked[k] = bool(gap[k] <= within)
        return replace(self, locked=locked)

    @property
    def class_names(self) -> list[str]:
        """Each track's class by name."""
        return [TRACK_CLASSES[c] for c in self.classes]


@dataclass(frozen=True, slots=True)
class TrackEstimate:
    """A tracker's belief after a frame."""

    t: float  # [s]
    position: FloatArray  # (3,) world [m]
    velocity: FloatArray  # (3,) world [m/s]
    tracked: bool
    spread: float  # σ_particles for a particle filter, √max position variance for a Kalman one [m]
    particles: FloatArray | None = None  # (N, 3) positions, for display
    # diag of the position and velocity covariance (6,) [m², (m/s)²]
    variance: FloatArray | None = None
    measurement: FloatArray | None = None  # (3,) z of this frame's update or (re)start [m]
