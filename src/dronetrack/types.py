"""The data passed between the stages: LiDAR frames, detections, track estimates and
turret commands.

Times are float64 seconds from the start of a run; lengths are metres; angles
are radians.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Literal, Protocol, get_args

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError
from dronetrack.geometry.transforms import FloatArray, interpolate_poses, transform_at_times

__all__ = [
    "OBJECT_KINDS",
    "TRACK_CLASSES",
    "Candidates",
    "Detections",
    "Frame",
    "ObjectKind",
    "ObjectTruth",
    "Phase",
    "Sample",
    "StepResult",
    "TrackEstimate",
    "Tracks",
    "Truth",
    "TurretCommand",
    "TurretState",
    "truth_objects",
]

Phase = Literal["scan", "track"]


@dataclass(frozen=True, slots=True)
class Frame:
    """One integration period of a LiDAR.

    points: (N, 3) returns in the sensor frame [m].
    t: (N,) time of each return [s].
    line: (N,) laser line / channel index.
    intensity: (N,) reflectivity in the Livox encoding (0-150 diffuse, >150 retro).
    pose_t, poses: world_T_sensor sampled during the frame, (K,) and (K, 4, 4).
        The sensor may move while it integrates (a turret or a moving observer);
        ``sensor_poses`` interpolates the pose at each point's time.
    """

    stamp: float
    duration: float
    points: FloatArray
    t: FloatArray
    line: NDArray[np.uint8]
    intensity: NDArray[np.float32]
    pose_t: FloatArray
    poses: FloatArray

    def __post_init__(self) -> None:
        n = len(self.points)
        if self.points.shape != (n, 3):
            raise InputError(f"frame points must be (N, 3), got {self.points.shape}")
        for name in ("t", "line", "intensity"):
            arr = getattr(self, name)
            if arr.shape != (n,):
                raise InputError(f"frame {name} must have shape ({n},), got {arr.shape}")
        if self.poses.shape != (len(self.pose_t), 4, 4) or len(self.pose_t) == 0:
            raise InputError(
                f"frame poses must be (K, 4, 4) with K = len(pose_t) >= 1, got {self.poses.shape}"
            )

    @property
    def end(self) -> float:
        """End of the integration period [s]."""
        return self.stamp + self.duration

    def __len__(self) -> int:
        return len(self.points)

    def sensor_poses(self) -> tuple[FloatArray, FloatArray]:
        """Rotation (N, 3, 3) and origin (N, 3) of the sensor at each point's time."""
        return interpolate_poses(self.pose_t, self.poses, self.t)

    def world_points(self) -> FloatArray:
        """Points (N, 3) in the world frame, each with the sensor pose at its time."""
        if len(self) == 0:
            return np.empty((0, 3))
        return transform_at_times(self.pose_t, self.poses, self.t, self.points)


def _frozen(a: NDArray[Any], dtype: type[np.generic], shape: tuple[int, ...]) -> NDArray[Any]:
    """A read-only copy of ``a`` as ``dtype`` (``a`` itself when it is one already, as a
    field handed on by ``dataclasses.replace`` is); InputError unless its shape is
    ``shape``."""
    if (
        isinstance(a, np.ndarray)
        and not a.flags.writeable
        and a.dtype == dtype
        and a.shape == shape
        and a.base is None
    ):
        return a
    out = np.array(a, dtype=dtype)
    if out.shape != shape:
        raise InputError(f"expected shape {shape}, got {out.shape}")
    out.flags.writeable = False
    return out


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
        object.__setattr__(self, "oversized", _frozen(big, np.float64, (len(big), 3)))
        for name, shape, dtype in (
            ("centroids", (k, 3), np.float64),
            ("counts", (k,), np.int64),
            ("extents", (k, 3), np.float64),
            ("covariances", (k, 3, 3), np.float64),
            ("planarity", (k,), np.float64),
            ("lows", (k,), np.float64),
        ):
            object.__setattr__(self, name, _frozen(getattr(self, name), dtype, shape))

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
            object.__setattr__(self, name, _frozen(getattr(self, name), dtype, shape))

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


# The classes a track can have (``classify``), in the order of their codes.
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
            object.__setattr__(self, name, _frozen(getattr(self, name), dtype, shape))

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


@dataclass(frozen=True, slots=True)
class TurretCommand:
    """A command to the pan-tilt unit, issued at ``stamp`` [s].

    mode "position": goal angles [rad]; mode "velocity": rates [rad/s].
    """

    stamp: float
    pan: float
    tilt: float
    mode: Literal["position", "velocity"] = "position"


@dataclass(frozen=True, slots=True)
class TurretState:
    """Measured turret joint state at ``stamp`` [s]: angles [rad], rates [rad/s]."""

    stamp: float
    pan: float
    tilt: float
    pan_rate: float = 0.0
    tilt_rate: float = 0.0


ObjectKind = Literal["drone", "bird", "walker", "vehicle", "static"]
OBJECT_KINDS: tuple[str, ...] = get_args(ObjectKind)


@dataclass(frozen=True, slots=True)
class ObjectTruth:
    """Every object a source knows of during a frame, K of them, and which object each
    of the frame's N returns came from (the simulator fills it; sinks and evaluation read
    it through ``truth_objects``).

    ids: (K,) a number that stays with an object for the whole run.  The simulator
        numbers its drones 0..D−1 in target order (0: the ``[drone]`` and
        ``[trajectory]`` target, then the ``[[targets]]`` entries), its birds after them,
        then its walkers and its vehicles (``[[walkers]]``, ``[[vehicles]]``, in order).
    kinds: (K,) each object's kind, one of ``OBJECT_KINDS``.
    positions: (K, 3) world position at the frame's end [m]; NaN while not present.
    velocities: (K, 3) world velocity at the frame's end [m/s]; NaN while not present.
    present: (K,) whether the object is in the world at the frame's end (a drone
        enters at its start time, a vehicle as it starts to drive in).
    object_index: (N,) per return of the frame, the index into these K arrays of the
        object it came from; −1 for anything else (the scene, a false alarm).

    The same objects, in the same order, describe every frame of a run.  The arrays
    are read-only.
    """

    ids: NDArray[np.int64]
    kinds: NDArray[np.str_]
    positions: FloatArray
    velocities: FloatArray
    present: NDArray[np.bool_]
    object_index: NDArray[np.int64]

    def __post_init__(self) -> None:
        k = len(self.ids)
        n = len(self.object_index)
        for name, shape, dtype in (
            ("ids", (k,), np.int64),
            ("kinds", (k,), np.str_),
            ("positions", (k, 3), np.float64),
            ("velocities", (k, 3), np.float64),
            ("present", (k,), np.bool_),
            ("object_index", (n,), np.int64),
        ):
            out = np.array(getattr(self, name), dtype=dtype)
            if out.shape != shape:
                raise InputError(f"object truth {name}: expected shape {shape}, got {out.shape}")
            out.flags.writeable = False
            object.__setattr__(self, name, out)
        unknown = sorted(set(self.kinds.tolist()) - set(OBJECT_KINDS))
        if unknown:
            raise InputError(
                f"object truth: unknown kind {unknown[0]!r}; one of {', '.join(OBJECT_KINDS)}"
            )
        if n and (self.object_index.min() < -1 or self.object_index.max() >= k):
            raise InputError(f"object truth: object_index must lie in [-1, {k}), one does not")

    def __len__(self) -> int:
        return len(self.ids)

    def returns(self) -> NDArray[np.int64]:
        """(K,) how many of the frame's returns came from each object."""
        hit = self.object_index[self.object_index >= 0]
        counts: NDArray[np.int64] = np.bincount(hit, minlength=len(self)).astype(np.int64)
        return counts

    def of_kind(self, kind: str) -> NDArray[np.bool_]:
        """(K,) which objects are of ``kind``."""
        mask: NDArray[np.bool_] = self.kinds == kind
        return mask


class Truth(Protocol):
    """What a source knows of the target during a frame (the simulator, or a
    recording's ground truth); the pipeline never sees it, only the sinks do.

    A source that knows of more than the target adds an ``objects`` member, an
    ``ObjectTruth``; read it with ``truth_objects``, which gives None for a truth
    without one.
    """

    @property
    def target_position(self) -> FloatArray:
        """(3,) world position at the frame's end [m]; NaN where unknown."""
        ...

    def target_returns(self, frame: Frame, world: FloatArray) -> int:
        """How many of the frame's returns hit the target, given the returns in the world
        frame (``world`` (N, 3), empty if the pipeline could not place them); -1 unknown."""
        ...


def truth_objects(truth: Truth | None) -> ObjectTruth | None:
    """The truth's every object (its ``objects`` member), None if it has none."""
    objects = getattr(truth, "objects", None)
    return objects if isinstance(objects, ObjectTruth) else None


@dataclass(frozen=True, slots=True)
class Sample:
    """One frame as a source delivers it, with what the source knows besides the points.

    turret: the turret's measured joint state at the frame's end, if the source knows it
        (a recording knows only the sensor pose, which is in the frame).
    received: a live source's ``time.perf_counter()`` when the frame's last point
        arrived, from which the run loop measures the latency to the turret command.
    """

    frame: Frame
    truth: Truth | None = None
    turret: TurretState | None = None
    received: float | None = None


@dataclass(frozen=True, slots=True)
class StepResult:
    """What the pipeline made of one frame."""

    t: float  # frame end [s]
    phase: Phase
    estimate: TrackEstimate | None  # None while scanning
    n_points: int  # points left after background subtraction and outlier removal
    n_returns: int  # points in the frame
    command: TurretCommand | None
    step_ms: float  # wall time spent in step()
    flags: tuple[str, ...] = ()
    foreground: FloatArray = field(default_factory=lambda: np.empty((0, 3)))
    periods: int = 0  # filter periods this frame advanced (0: repeated or older)
    # (N, 3) every point of the frame in the world frame; empty if it could not be placed
    world: FloatArray = field(default_factory=lambda: np.empty((0, 3)))
    # The detect stage's clusters in the foreground, and the confirmed candidates
    # among its tentative tracks (None when acquisition is off, and while scanning)
    detections: Detections | None = None
    candidates: Candidates | None = None
    # A live frame's time from its last point's arrival to its turret command being
    # sent [ms] (``pipeline.run``); NaN for sources that are not live.
    latency_ms: float = math.nan
    # Every object's track (``track.multi``; None when acquisition is off, and while
    # scanning)
    tracks: Tracks | None = None
