"""``--foxglove FILE.mcap``: a run as an MCAP file for Foxglove.

Needs the optional extra ``[foxglove]`` (foxglove-sdk).  Every message is
protobuf with a well-known Foxglove schema, so Foxglove's 3D panel shows it as
it is.  Topics (a user contract), one message each per frame unless said:

- ``/lidar/points`` (``foxglove.PointCloud``): the frame's returns, fields
  x, y, z float32;
- ``/lidar/foreground`` (``foxglove.PointCloud``): the points the tracker was
  given;
- ``/track/particles`` (``foxglove.PointCloud``): the particle filter's
  particles, every k-th so that at most 2,000 remain; empty without particles;
- ``/track/markers`` (``foxglove.SceneUpdate``): entity ``estimate``, a
  0.4 m sphere, green while tracked and orange otherwise; ``truth``, a blue
  0.3 m cube; ``trail``, a line through the last 50 estimates (a frame without
  an estimate restarts it).  An entity with nothing to show is deleted;
- ``/tf`` (``foxglove.FrameTransform``): one message per edge of the frame's
  transform tree, parent and child frame ids as given, translation and unit
  quaternion.
- ``/tracks/markers`` and ``/tracks``: every object's track, from the first frame
  with a track layer on (``sinks.foxglove.tracks``).
- ``/tracks/fix`` and ``/zones``: with a ``[site]``, every track's WGS-84 fix and the
  protected zones, for the Map panel (``sinks.foxglove.geo``).

Point clouds and markers are in frame ``world``.  Every message's log time and
header timestamp is ``start + frame.t`` in nanoseconds since the Unix epoch, so
a replayed recording keeps its real clock (a simulation starts at the epoch).

Each writer logs through its own ``foxglove.Context`` and channels, so two
writers in one process (or one test session) never see each other's messages.

The SDK's own log records (Python ``logging`` on the ``foxglove`` loggers, e.g. the
server's ``Dropping client …: handshake failed``) are handed on to this module's
logger, ``Foxglove SDK: `` before each, warnings and worse only
(``relay_sdk_log``): the application's logging shows them, as it shows ours.
"""

from __future__ import annotations

import importlib
import logging
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from dronetrack.errors import InputError, MissingExtraError
from dronetrack.geometry.transforms import FloatArray, matrix_to_quaternion
from dronetrack.sinks.foxglove.geo import (
    FIX_TOPIC,
    ZONES_EVERY_S,
    ZONES_TOPIC,
    SiteView,
    track_fixes,
    zones_geojson,
)
from dronetrack.sinks.foxglove.tracks import (
    MARKERS_TOPIC,
    table_channel,
    track_scene,
    track_table,
)
from dronetrack.sinks.view import (
    WORLD_FRAME,
    EstimateTrail,
    NamedTransform,
    ShownTracks,
    ViewFrame,
    checked,
    subsample_particles,
)

if TYPE_CHECKING:
    from foxglove.messages import (
        Color,
        FrameTransform,
        PointCloud,
        Pose,
        SceneEntity,
        SceneUpdate,
        Timestamp,
    )

__all__ = ["TOPICS", "FoxgloveChannels", "FoxgloveWriter", "relay_sdk_log", "require_foxglove"]

log = logging.getLogger(__name__)
SDK_LOGGER = "foxglove"  # the root of the SDK's loggers (its Rust modules' paths)

TOPICS = (
    "/lidar/points",
    "/lidar/foreground",
    "/track/particles",
    "/track/markers",
    "/tf",
)

_HINT = "--foxglove needs foxglove-sdk: pip install 'dronetrack[foxglove]'"
_TRACKED = (0.1, 0.85, 0.2, 0.9)  # r, g, b, a
_COASTING = (1.0, 0.55, 0.0, 0.9)
_TRUTH = (0.2, 0.45, 1.0, 0.8)
_TRAIL = (0.55, 1.0, 0.55, 0.8)
_ESTIMATE_DIAMETER = 0.4  # [m]
_TRUTH_SIZE = 0.3  # [m]
_TRAIL_WIDTH = 2.0  # [px]


def require_foxglove() -> None:
    """Raise ``MissingExtraError`` with the install hint unless foxglove-sdk imports."""
    try:
        importlib.import_module("foxglove")
    except ImportError as err:
        raise MissingExtraError(_HINT) from err


class _SdkRelay(logging.Handler):
    """Hands each of the SDK's records on to this module's logger."""

    def emit(self, record: logging.LogRecord) -> None:
        log.log(record.levelno, "Foxglove SDK: %s", record.getMessage())


def relay_sdk_log() -> None:
    """Route the SDK's log records (warnings and worse) through our logger instead of
    their own (which, with no handler anywhere, Python prints bare); idempotent."""
    sdk = logging.getLogger(SDK_LOGGER)
    if not any(isinstance(h, _SdkRelay) for h in sdk.handlers):
        sdk.addHandler(_SdkRelay())
    sdk.setLevel(logging.WARNING)
    sdk.propagate = False


def _time_ns(start: float, t: float) -> int:
    ns = round((start + t) * 1e9)
    if ns < 0:
        raise InputError(f"log time start + t = {start + t} s is before the Unix epoch")
    return ns


class FoxgloveChannels:
    """The topics above on their own ``foxglove.Context``, fed ``ViewFrame``s: what the
    MCAP writer and the live server (``sinks.foxglove.live``) share.  ``what`` names
    the output in errors."""

    def __init__(self, start: float, what: str) -> None:
        require_foxglove()
        relay_sdk_log()
        import foxglove
        from foxglove.channels import (
            FrameTransformChannel,
            PointCloudChannel,
            SceneUpdateChannel,
        )

        self.start = float(start)
        self.what = what
        self._context = foxglove.Context()
        ctx = self._context
        self._points = PointCloudChannel("/lidar/points", context=ctx)
        self._foreground = PointCloudChannel("/lidar/foreground", context=ctx)
        self._particles = PointCloudChannel("/track/particles", context=ctx)
        self._markers = SceneUpdateChannel("/track/markers", context=ctx)
        self._tf = FrameTransformChannel("/tf", context=ctx)
        self._trail = EstimateTrail()
        self._shown = ShownTracks()
        self._tracks: tuple[Any, Any] | None = None  # opened with the first tracks
        # The map's: the site and its zones (``show_site``), their channels, and when
        # the zones were last written
        self.geo: SiteView | None = None
        self._geo: tuple[Any, Any] | None = None
        self._zones_at = -math.inf
        self._closed = False

    def show_site(self, view: SiteView) -> None:
        """Put the tracks and the zones on Foxglove's Map panel too (``sinks.foxglove.geo``)."""
        self.geo = view

    def _close_channels(self) -> None:
        for channel in (self._points, self._foreground, self._particles, self._markers, self._tf):
            channel.close()
        for channel in self._tracks or ():
            channel.close()
        for channel in self._geo or ():
            channel.close()

    def _track_channels(self) -> tuple[Any, Any]:
        """The markers and table channels of the tracks, opened on first use."""
        if self._tracks is None:
            from foxglove.channels import SceneUpdateChannel

            markers = SceneUpdateChannel(MARKERS_TOPIC, context=self._context)
            self._tracks = (markers, table_channel(self._context))
        return self._tracks

    def log(self, frame: ViewFrame) -> None:
        """Add one frame: three point clouds, the markers, the transforms and the tracks.

        The frame is checked whole first (``InputError``), so a bad frame writes nothing.
        """
        if self._closed:
            raise ValueError(f"{self.what} is closed")
        from foxglove.messages import Timestamp

        frame = checked(frame)
        ns = _time_ns(self.start, frame.t)
        stamp = Timestamp(sec=ns // 1_000_000_000, nsec=ns % 1_000_000_000)
        clouds = [
            (self._points, _cloud(frame.points, stamp)),
            (self._foreground, _cloud(frame.foreground, stamp)),
            (self._particles, _cloud(subsample_particles(frame.particles), stamp)),
        ]
        transforms = [_frame_transform(tf, stamp) for tf in frame.transforms]
        scene = self._scene(frame, stamp)
        update = self._shown.update(frame.tracks)
        tracks = None
        if update is not None:
            tracks = (track_scene(update, stamp), track_table(update, stamp))
        for channel, cloud in clouds:
            channel.log(cloud, log_time=ns)
        self._markers.log(scene, log_time=ns)
        for transform in transforms:
            self._tf.log(transform, log_time=ns)
        if tracks is not None:
            for channel, message in zip(self._track_channels(), tracks, strict=True):
                channel.log(message, log_time=ns)
        if self.geo is not None:
            self._log_map(frame, stamp, ns)

    def _log_map(self, frame: ViewFrame, stamp: Timestamp, ns: int) -> None:
        """The tracks' fixes, and the zones now and then."""
        assert self.geo is not None
        if self._geo is None:
            from foxglove.channels import GeoJsonChannel, LocationFixChannel

            self._geo = (
                LocationFixChannel(FIX_TOPIC, context=self._context),
                GeoJsonChannel(ZONES_TOPIC, context=self._context),
            )
        fixes, zones = self._geo
        if self.geo.zones and frame.t - self._zones_at >= ZONES_EVERY_S:
            from foxglove.messages import GeoJson

            zones.log(GeoJson(geojson=zones_geojson(self.geo)), log_time=ns)
            self._zones_at = frame.t
        if frame.tracks is not None:
            for fix in track_fixes(frame.tracks, self.geo.site, stamp):
                fixes.log(fix, log_time=ns)

    def _scene(self, frame: ViewFrame, stamp: Timestamp) -> SceneUpdate:
        """The markers: what is known is drawn, what is not is deleted."""
        from foxglove.messages import SceneEntityDeletion, SceneEntityDeletionType, SceneUpdate

        trail = self._trail.update(frame.estimate)
        entities: list[SceneEntity] = []
        gone: list[str] = []
        if frame.estimate is None:
            gone.append("estimate")
        else:
            colour = _TRACKED if frame.tracked else _COASTING
            entities.append(_estimate_entity(frame.estimate, colour, stamp))
        if frame.truth is None:
            gone.append("truth")
        else:
            entities.append(_truth_entity(frame.truth, stamp))
        if len(trail) < 2:
            gone.append("trail")
        else:
            entities.append(_trail_entity(trail, stamp))
        deletions = [
            SceneEntityDeletion(timestamp=stamp, type=SceneEntityDeletionType.MatchingId, id=name)
            for name in gone
        ]
        return SceneUpdate(deletions=deletions, entities=entities)


class FoxgloveWriter(FoxgloveChannels):
    """Writes ``ViewFrame``s to an MCAP file.

    An existing file is overwritten and missing parent folders are created.  Use
    it as a context manager or call ``close``: only a closed file has its summary.
    """

    def __init__(self, path: Path, start: float = 0.0) -> None:
        super().__init__(start, str(path))
        import foxglove

        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        try:
            self._writer = foxglove.open_mcap(
                self.path, allow_overwrite=True, context=self._context
            )
        except BaseException:
            self._close_channels()
            raise

    def close(self) -> None:
        """Finish the file (summary and footer); closing twice does nothing."""
        if self._closed:
            return
        self._closed = True
        self._writer.close()
        self._close_channels()

    def __enter__(self) -> FoxgloveWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _cloud(points: FloatArray, stamp: Timestamp) -> PointCloud:
    """A ``foxglove.PointCloud`` of x, y, z float32 in the world frame."""
    from foxglove.messages import PackedElementField, PackedElementFieldNumericType, PointCloud

    f32 = PackedElementFieldNumericType.Float32
    fields = [PackedElementField(name=n, offset=4 * k, type=f32) for k, n in enumerate("xyz")]
    data = np.ascontiguousarray(points, dtype="<f4").tobytes()
    return PointCloud(
        timestamp=stamp,
        frame_id=WORLD_FRAME,
        pose=_pose(np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0])),
        point_stride=12,
        fields=fields,
        data=data,
    )


def _pose(position: FloatArray, q_wxyz: FloatArray) -> Pose:
    from foxglove.messages import Pose, Quaternion, Vector3

    x, y, z = (float(v) for v in position)
    qw, qx, qy, qz = (float(v) for v in q_wxyz)
    return Pose(
        position=Vector3(x=x, y=y, z=z),
        orientation=Quaternion(x=qx, y=qy, z=qz, w=qw),
    )


def _color(rgba: tuple[float, float, float, float]) -> Color:
    from foxglove.messages import Color

    r, g, b, a = rgba
    return Color(r=r, g=g, b=b, a=a)


def _entity(name: str, stamp: Timestamp, **primitives: Any) -> SceneEntity:
    from foxglove.messages import SceneEntity

    return SceneEntity(timestamp=stamp, frame_id=WORLD_FRAME, id=name, **primitives)


def _estimate_entity(
    position: FloatArray, rgba: tuple[float, float, float, float], stamp: Timestamp
) -> SceneEntity:
    from foxglove.messages import SpherePrimitive, Vector3

    d = _ESTIMATE_DIAMETER
    sphere = SpherePrimitive(
        pose=_pose(position, np.array([1.0, 0.0, 0.0, 0.0])),
        size=Vector3(x=d, y=d, z=d),
        color=_color(rgba),
    )
    return _entity("estimate", stamp, spheres=[sphere])


def _truth_entity(position: FloatArray, stamp: Timestamp) -> SceneEntity:
    from foxglove.messages import CubePrimitive, Vector3

    s = _TRUTH_SIZE
    cube = CubePrimitive(
        pose=_pose(position, np.array([1.0, 0.0, 0.0, 0.0])),
        size=Vector3(x=s, y=s, z=s),
        color=_color(_TRUTH),
    )
    return _entity("truth", stamp, cubes=[cube])


def _trail_entity(trail: FloatArray, stamp: Timestamp) -> SceneEntity:
    from foxglove.messages import LinePrimitive, LinePrimitiveLineType, Point3

    line = LinePrimitive(
        type=LinePrimitiveLineType.LineStrip,
        thickness=_TRAIL_WIDTH,
        scale_invariant=True,
        points=[Point3(x=float(x), y=float(y), z=float(z)) for x, y, z in trail],
        color=_color(_TRAIL),
    )
    return _entity("trail", stamp, lines=[line])


def _frame_transform(tf: NamedTransform, stamp: Timestamp) -> FrameTransform:
    """One /tf edge (a checked 4 × 4 parent_T_child) as translation and unit quaternion."""
    from foxglove.messages import FrameTransform, Quaternion, Vector3

    m = tf.matrix
    x, y, z = (float(v) for v in m[:3, 3])
    qw, qx, qy, qz = (float(v) for v in matrix_to_quaternion(m[:3, :3]))
    return FrameTransform(
        timestamp=stamp,
        parent_frame_id=tf.parent,
        child_frame_id=tf.child,
        translation=Vector3(x=x, y=y, z=z),
        rotation=Quaternion(x=qx, y=qy, z=qz, w=qw),
    )
