"""One frame as a viewer shows it, the interface of the viewer writers, and what the
writers show the same way (the particle subsample, the estimate trail, the world
pose of every frame of the transform tree, and every object's track: its class
colour, size, label and the tracks shown before).

``simulate`` and ``track`` fill a ``ViewFrame`` per frame and hand it to every
open ``ViewerSink`` (``--foxglove FILE.mcap``, ``--rerun FILE.rrd``).
Everything is in the world frame [m], times in seconds from the run's start.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from dronetrack.errors import InputError
from dronetrack.geometry.mount import MountGeometry, turret_links
from dronetrack.geometry.transforms import FloatArray
from dronetrack.types import TRACK_CLASSES, Frame, Sample, StepResult, Tracks

__all__ = [
    "LOCKED_RGB",
    "MAX_PARTICLES",
    "TRACK_RGB",
    "TRAIL_LENGTH",
    "WORLD_FRAME",
    "EstimateTrail",
    "NamedTransform",
    "ShownTracks",
    "TrackUpdate",
    "TrackView",
    "ViewFrame",
    "ViewerFeed",
    "ViewerSink",
    "checked",
    "subsample_particles",
    "track_label",
    "track_size",
    "track_views",
    "view_frame",
    "world_poses",
    "xyz",
]

WORLD_FRAME = "world"
MAX_PARTICLES = 2000  # at most this many particles are drawn per frame
TRAIL_LENGTH = 50  # past estimates in the trail
# A track's colour by class (r, g, b in 0-255), apart from the points' grey, the
# foreground's red, the estimate's green and the truth's light blue.
TRACK_RGB: dict[str, tuple[int, int, int]] = {
    "unknown": (225, 225, 225),
    "drone": (235, 50, 200),
    "bird": (250, 200, 40),
    "static": (150, 105, 60),
}
LOCKED_RGB = (30, 220, 50)  # the mark of the track the turret's tracker holds
TRACK_SIZE_M = (0.3, 10.0)  # a track's drawn size (2 position sigma) is clipped to this [m]


@dataclass(frozen=True, slots=True)
class NamedTransform:
    """parent_T_child (4, 4), as a /tf edge."""

    parent: str
    child: str
    matrix: FloatArray


@dataclass(frozen=True, slots=True)
class ViewFrame:
    """What a viewer shows of one frame."""

    t: float  # frame end [s]
    points: FloatArray  # (N, 3) the frame's returns, world frame
    foreground: FloatArray  # (M, 3) the points the tracker was given
    estimate: FloatArray | None  # (3,) the tracker's position, None while scanning
    tracked: bool
    truth: FloatArray | None  # (3,) ground truth, None when unknown
    particles: FloatArray | None  # (P, 3) a particle filter's particles
    transforms: tuple[NamedTransform, ...]  # world → turret links → sensor, at the frame end
    tracks: Tracks | None = None  # every object's track; None without a track layer


class ViewerSink(Protocol):
    """A writer of a viewer file."""

    def log(self, frame: ViewFrame) -> None:
        """Add one frame."""
        ...

    def close(self) -> None:
        """Finish the file."""
        ...


def view_frame(
    frame: Frame,
    result: StepResult,
    truth: FloatArray | None,
    transforms: Sequence[NamedTransform],
) -> ViewFrame:
    """What a viewer shows of one frame."""
    est = result.estimate
    return ViewFrame(
        t=frame.end,
        points=result.world if len(result.world) == len(frame) else frame.world_points(),
        foreground=result.foreground,
        estimate=None if est is None else est.position,
        tracked=bool(est is not None and est.tracked),
        truth=truth if truth is not None and np.all(np.isfinite(truth)) else None,
        particles=None if est is None else est.particles,
        transforms=tuple(transforms),
        tracks=result.tracks,
    )


class ViewerFeed:
    """The run loop's sink for the viewer files: every frame (the background scan's
    too), with the turret's links when the source reports its joint angles and
    ``mount`` is given, else the sensor's pose alone."""

    def __init__(self, viewers: Sequence[ViewerSink], mount: MountGeometry | None = None) -> None:
        self.viewers = tuple(viewers)
        self.mount = mount

    def write(self, sample: Sample, result: StepResult) -> None:
        frame, turret = sample.frame, sample.turret
        if self.mount is not None and turret is not None:
            links = [
                NamedTransform(*link) for link in turret_links(turret.pan, turret.tilt, self.mount)
            ]
        else:
            links = [NamedTransform("world", "lidar", frame.poses[-1])]
        truth = None if sample.truth is None else sample.truth.target_position
        view = view_frame(frame, result, truth, links)
        for viewer in self.viewers:
            viewer.log(view)

    def close(self) -> None:
        """Close every viewer (for a feed that owns its viewers, as ``live``'s does)."""
        for viewer in self.viewers:
            viewer.close()


def xyz(points: FloatArray | None, what: str) -> FloatArray:
    """``points`` as a (N, 3) float64 array; None and any empty array give (0, 3)."""
    if points is None:
        return np.zeros((0, 3))
    a = np.asarray(points, dtype=np.float64)
    if a.size == 0:
        return np.zeros((0, 3))
    if a.ndim == 1 and a.shape[0] == 3:
        return a.reshape(1, 3)
    if a.ndim != 2 or a.shape[1] != 3:
        raise InputError(f"{what} must have shape (N, 3), got {a.shape}")
    return a


def _point(a: FloatArray | None, what: str) -> FloatArray | None:
    if a is None:
        return None
    p = xyz(a, what)
    if len(p) != 1:
        raise InputError(f"{what} must have shape (3,), got {np.shape(a)}")
    out: FloatArray = p[0]
    return out


def _matrix(tf: NamedTransform) -> NamedTransform:
    m = np.asarray(tf.matrix, dtype=np.float64)
    if m.shape != (4, 4):
        raise InputError(f"transform {tf.parent}->{tf.child} is {m.shape}, not (4, 4)")
    return NamedTransform(tf.parent, tf.child, m)


def checked(frame: ViewFrame) -> ViewFrame:
    """``frame`` with every array as float64 of the documented shape; ``InputError`` if not.

    Writers check a frame whole before they write any of it.  Points and
    particles come as (N, 3) (empty: (0, 3)), estimate and truth as (3,).
    """
    return dataclasses.replace(
        frame,
        points=xyz(frame.points, "points"),
        foreground=xyz(frame.foreground, "foreground"),
        estimate=_point(frame.estimate, "estimate"),
        truth=_point(frame.truth, "truth"),
        particles=None if frame.particles is None else xyz(frame.particles, "particles"),
        transforms=tuple(_matrix(tf) for tf in frame.transforms),
    )


def subsample_particles(particles: FloatArray | None, limit: int = MAX_PARTICLES) -> FloatArray:
    """Every k-th particle, k the smallest stride that keeps at most ``limit``."""
    p = xyz(particles, "particles")
    stride = max(1, math.ceil(len(p) / limit))
    out: FloatArray = p[::stride]
    return out


class EstimateTrail:
    """The last ``length`` estimates; a frame without an estimate ends the trail."""

    def __init__(self, length: int = TRAIL_LENGTH) -> None:
        self._points: deque[FloatArray] = deque(maxlen=length)

    def update(self, estimate: FloatArray | None) -> FloatArray:
        """Add this frame's estimate (or restart on None); the trail as (K, 3)."""
        if estimate is None:
            self._points.clear()
        else:
            self._points.append(np.array(estimate, dtype=np.float64).reshape(3))
        if not self._points:
            return np.zeros((0, 3))
        return np.stack(list(self._points))


def world_poses(
    transforms: Sequence[NamedTransform], root: str = WORLD_FRAME
) -> dict[str, FloatArray]:
    """root_T_child (4, 4) of every child in ``transforms``, composed along the tree.

    The edges may come in any order; an edge whose parent never connects to
    ``root`` raises ``InputError``.
    """
    poses: dict[str, FloatArray] = {root: np.eye(4)}
    pending = list(transforms)
    while pending:
        left: list[NamedTransform] = []
        for tf in pending:
            if tf.parent not in poses:
                left.append(tf)
            else:
                poses[tf.child] = poses[tf.parent] @ _matrix(tf).matrix
        if len(left) == len(pending):
            names = ", ".join(f"{tf.parent}->{tf.child}" for tf in left)
            raise InputError(f"transforms not connected to {root!r}: {names}")
        pending = left
    return {name: pose for name, pose in poses.items() if name != root}


@dataclass(frozen=True, slots=True)
class TrackView:
    """One track as the viewers show it (world frame, SI units)."""

    id: int
    cls: str  # its class, one of ``TRACK_CLASSES``
    p_drone: float
    position: tuple[float, float, float]  # [m]
    velocity: tuple[float, float, float]  # [m/s]
    sigma: float  # √ of its largest position variance [m]
    locked: bool

    @property
    def rgb(self) -> tuple[int, int, int]:
        """Its class colour."""
        return TRACK_RGB[self.cls]


def _triple(v: FloatArray) -> tuple[float, float, float]:
    x, y, z = (float(c) for c in v)
    return (x, y, z)


def track_views(tracks: Tracks | None) -> list[TrackView]:
    """Every track of ``tracks`` (none for None), in their order."""
    if tracks is None:
        return []
    sigma = tracks.position_sigma
    return [
        TrackView(
            id=int(tracks.ids[k]),
            cls=TRACK_CLASSES[int(tracks.classes[k])],
            p_drone=float(tracks.p_drone[k]),
            position=_triple(tracks.positions[k]),
            velocity=_triple(tracks.velocities[k]),
            sigma=float(sigma[k]),
            locked=bool(tracks.locked[k]),
        )
        for k in range(len(tracks))
    ]


def track_size(sigma: float) -> float:
    """A track's drawn diameter [m]: twice its position sigma within ``TRACK_SIZE_M``
    (the largest for a sigma that is not finite)."""
    low, high = TRACK_SIZE_M
    return float(np.clip(2.0 * sigma, low, high)) if math.isfinite(sigma) else high


def track_label(track: TrackView, p_drone: bool = True) -> str:
    """``"<id> <class> p=<p_drone>"`` (without p= when ``p_drone`` is False), with
    `` locked`` after it on the track the turret's tracker holds."""
    text = f"{track.id} {track.cls}"
    if p_drone:
        text += f" p={track.p_drone:.2f}"
    return text + " locked" if track.locked else text


@dataclass(frozen=True, slots=True)
class TrackUpdate:
    """What a viewer shows of the tracks this frame and which of its past ones to delete."""

    tracks: list[TrackView]
    gone: list[int]  # ids shown before and not now, ascending


class ShownTracks:
    """The track ids a viewer shows, frame to frame.

    ``update`` gives None until a frame has tracks (a run without a track layer, or
    its background scan, shows none and deletes none); from then on every frame's
    tracks (a frame with None has none) and the ids that are gone.
    """

    def __init__(self) -> None:
        self._ids: set[int] = set()
        self._active = False

    def update(self, tracks: Tracks | None) -> TrackUpdate | None:
        if tracks is None and not self._active:
            return None
        self._active = True
        views = track_views(tracks)
        ids = {t.id for t in views}
        gone = sorted(self._ids - ids)
        self._ids = ids
        return TrackUpdate(views, gone)
