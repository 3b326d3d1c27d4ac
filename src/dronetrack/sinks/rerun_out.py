"""``--rerun FILE.rrd``: a run as a rerun recording file.

Needs the optional extra ``[rerun]`` (rerun-sdk).  Nothing is spawned or served:
the recording goes straight to the file, which ``rerun FILE.rrd`` opens.

Timelines: ``frame`` (sequence: 0, 1, … per logged frame) and ``time``
(duration: ``frame.t``, seconds from the run's start).  With ``start != 0`` (a
replayed recording) there is also ``timestamp``, the timestamp ``start + frame.t``.

Entity paths (a user contract), all in metres, z up:

- ``world``: ``ViewCoordinates.RIGHT_HAND_Z_UP``, static;
- ``world/lidar/points``: the frame's returns (grey ``Points3D``);
- ``world/lidar/foreground``: the points the tracker was given (red);
- ``world/track/particles``: the particle filter's particles, every k-th so that
  at most 2,000 remain (blue; empty without particles);
- ``world/track/estimate``: the estimate, green while tracked, orange otherwise;
- ``world/track/trail``: ``LineStrips3D`` through the last 50 estimates (a frame
  without an estimate restarts it);
- ``world/truth``: the ground truth (light blue);
- ``world/frames/<child>``: for every edge of the frame's transform tree, the
  child frame's pose in the world frame (composed along the tree from
  ``world``), as ``Transform3D`` drawn with 0.3 m axes;
- ``world/tracks``: every object's track, from the first frame with a track layer on
  (none before): ``Points3D`` at its position, radius its position sigma
  (0.15-5 m), in its class colour (``sinks.view.TRACK_RGB``), ``class_ids`` its class
  (index into ``TRACK_CLASSES``; a static ``AnnotationContext`` names them), label
  ``<id> <class>`` (`` locked`` after it on the track the turret's tracker holds),
  and ``AnyValues`` ``track_id``, ``p_drone``, ``pos_sigma_m`` and ``locked`` per
  instance;
- ``world/tracks/locked``: a green wireframe box around the locked track (cleared
  while none is);
- ``plots/error_m``: |estimate − truth| [m], on frames where both are known;
- ``plots/n_foreground``: the number of foreground points;
- ``plots/n_tracks``: the number of tracks (with a track layer).

An entity with nothing to show this frame (no estimate, no truth, a trail of
fewer than two points) is cleared, so the viewer never shows a stale marker.

Each writer has its own ``RecordingStream`` with a fresh recording id: two
writers in one process write two separate recordings, and neither becomes
rerun's global recording.

Privacy: writing a file this way opens no network connection and writes
nothing in the home folder (checked with strace on rerun-sdk 0.41); the usage
analytics that rerun collects belong to its viewer, and
``rerun analytics disable`` turns them off.  ``RERUN=off`` in the environment
makes the SDK drop everything silently, so the writer refuses to start then.
"""

from __future__ import annotations

import importlib
import uuid
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from dronetrack.errors import ConfigError, MissingExtraError
from dronetrack.geometry.transforms import FloatArray
from dronetrack.sinks.view import (
    LOCKED_RGB,
    TRACK_RGB,
    EstimateTrail,
    ShownTracks,
    TrackUpdate,
    ViewFrame,
    checked,
    subsample_particles,
    track_label,
    track_size,
    world_poses,
)
from dronetrack.types import TRACK_CLASSES

if TYPE_CHECKING:
    import rerun as rr

__all__ = ["ENTITY_PATHS", "TRACK_PATHS", "RerunWriter", "require_rerun"]

ENTITY_PATHS = (
    "world",
    "world/lidar/points",
    "world/lidar/foreground",
    "world/track/particles",
    "world/track/estimate",
    "world/track/trail",
    "world/truth",
    "plots/error_m",
    "plots/n_foreground",
)
TRACK_PATHS = ("world/tracks", "world/tracks/locked", "plots/n_tracks")

_HINT = "--rerun needs rerun-sdk: pip install 'dronetrack[rerun]'"
_GREY = (150, 150, 150)
_RED = (255, 70, 60)
_BLUE = (80, 120, 255)
_TRACKED = (30, 220, 50)
_COASTING = (255, 140, 0)
_TRUTH = (80, 200, 255)
_POINT_RADIUS = 0.03  # [m]
_FOREGROUND_RADIUS = 0.06  # [m]
_MARKER_RADIUS = 0.2  # [m]
_TRAIL_RADIUS = 0.03  # [m]
_AXIS_LENGTH = 0.3  # [m]
_LOCKED_BOX = 0.75  # the locked track's box half size against its diameter


def require_rerun() -> None:
    """Raise ``MissingExtraError`` with the install hint unless rerun-sdk imports."""
    try:
        importlib.import_module("rerun")
    except ImportError as err:
        raise MissingExtraError(_HINT) from err


class RerunWriter:
    """Writes ``ViewFrame``s to a ``.rrd`` file.

    An existing file is overwritten and missing parent folders are created.  Use
    it as a context manager or call ``close``, which flushes and writes the footer.
    """

    def __init__(self, path: Path, start: float = 0.0) -> None:
        require_rerun()
        import rerun as rr

        self.path = Path(path)
        self.start = float(start)
        self._rec: rr.RecordingStream = rr.RecordingStream("dronetrack", recording_id=uuid.uuid4())
        if not rr.is_enabled(self._rec):
            raise ConfigError(
                f"rerun-sdk is disabled (RERUN=off in the environment?), so {self.path} "
                "would stay empty: unset RERUN"
            )
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._rec.save(self.path)
        self._rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
        self._trail = EstimateTrail()
        self._shown = ShownTracks()
        self._tracks_named = False  # the class annotation is logged with the first tracks
        self._index = 0
        self._closed = False

    def log(self, frame: ViewFrame) -> None:
        """Add one frame at the next ``frame`` index.

        The frame is checked whole first (``InputError``), so a bad frame writes nothing.
        """
        if self._closed:
            raise ValueError(f"{self.path} is closed")
        frame = checked(frame)
        poses = world_poses(frame.transforms)
        self._set_time(frame.t)
        self._log_clouds(frame)
        self._log_track(frame)
        self._log_frames(poses)
        self._log_plots(frame)
        update = self._shown.update(frame.tracks)
        if update is not None:
            self._log_tracks(update)
        self._index += 1

    def close(self) -> None:
        """Flush and finish the file (with its footer); closing twice does nothing."""
        if self._closed:
            return
        self._closed = True
        self._rec.flush()
        self._rec.disconnect()

    def __enter__(self) -> RerunWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _set_time(self, t: float) -> None:
        self._rec.set_time("frame", sequence=self._index)
        self._rec.set_time("time", duration=float(t))
        if self.start != 0.0:
            self._rec.set_time("timestamp", timestamp=self.start + float(t))

    def _log_clouds(self, frame: ViewFrame) -> None:
        import rerun as rr

        clouds = (
            ("world/lidar/points", frame.points, _GREY, _POINT_RADIUS),
            ("world/lidar/foreground", frame.foreground, _RED, _FOREGROUND_RADIUS),
            ("world/track/particles", subsample_particles(frame.particles), _BLUE, _POINT_RADIUS),
        )
        for path, points, colour, radius in clouds:
            self._rec.log(path, rr.Points3D(points, colors=[colour], radii=[radius]))

    def _log_track(self, frame: ViewFrame) -> None:
        import rerun as rr

        if frame.estimate is None:
            self._rec.log("world/track/estimate", rr.Clear(recursive=False))
        else:
            colour = _TRACKED if frame.tracked else _COASTING
            self._log_marker("world/track/estimate", frame.estimate, colour)
        if frame.truth is None:
            self._rec.log("world/truth", rr.Clear(recursive=False))
        else:
            self._log_marker("world/truth", frame.truth, _TRUTH)
        trail = self._trail.update(frame.estimate)
        if len(trail) < 2:
            self._rec.log("world/track/trail", rr.Clear(recursive=False))
        else:
            strip = rr.LineStrips3D([trail], colors=[_TRACKED], radii=[_TRAIL_RADIUS])
            self._rec.log("world/track/trail", strip)

    def _log_marker(self, path: str, position: FloatArray, colour: tuple[int, int, int]) -> None:
        import rerun as rr

        marker = rr.Points3D(position.reshape(1, 3), colors=[colour], radii=[_MARKER_RADIUS])
        self._rec.log(path, marker)

    def _log_frames(self, poses: dict[str, FloatArray]) -> None:
        import rerun as rr

        for child, pose in poses.items():
            transform = rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3])
            path = f"world/frames/{rr.escape_entity_path_part(child)}"
            self._rec.log(path, transform, rr.TransformAxes3D(_AXIS_LENGTH))

    def _log_plots(self, frame: ViewFrame) -> None:
        import rerun as rr

        self._rec.log("plots/n_foreground", rr.Scalars(float(len(frame.foreground))))
        if frame.estimate is not None and frame.truth is not None:
            error = np.linalg.norm(frame.estimate - frame.truth)
            self._rec.log("plots/error_m", rr.Scalars(float(error)))

    def _log_tracks(self, update: TrackUpdate) -> None:
        import rerun as rr

        tracks = update.tracks
        if not self._tracks_named:
            classes = [
                rr.AnnotationInfo(id=k, label=name, color=TRACK_RGB[name])
                for k, name in enumerate(TRACK_CLASSES)
            ]
            self._rec.log("world/tracks", rr.AnnotationContext(classes), static=True)
            self._tracks_named = True
        points = rr.Points3D(
            np.array([t.position for t in tracks]).reshape(-1, 3),
            radii=[track_size(t.sigma) / 2 for t in tracks],
            colors=[t.rgb for t in tracks],
            labels=[track_label(t, p_drone=False) for t in tracks],
            class_ids=[TRACK_CLASSES.index(t.cls) for t in tracks],
            show_labels=True,
        )
        values = rr.AnyValues(
            track_id=np.array([t.id for t in tracks], dtype=np.int64),
            p_drone=np.array([t.p_drone for t in tracks], dtype=np.float64),
            pos_sigma_m=np.array([t.sigma for t in tracks], dtype=np.float64),
            locked=np.array([t.locked for t in tracks], dtype=bool),
        )
        self._rec.log("world/tracks", points, values)
        locked = [t for t in tracks if t.locked]
        if locked:
            t = locked[0]
            half = _LOCKED_BOX * track_size(t.sigma)
            box = rr.Boxes3D(
                centers=[t.position],
                half_sizes=[(half, half, half)],
                colors=[LOCKED_RGB],
                labels=[f"locked {t.id}"],
            )
            self._rec.log("world/tracks/locked", box)
        else:
            self._rec.log("world/tracks/locked", rr.Clear(recursive=False))
        self._rec.log("plots/n_tracks", rr.Scalars(float(len(tracks))))
