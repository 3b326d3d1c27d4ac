"""Every object's track for Foxglove (``sinks.foxglove.mcap_file``): its markers and a table
to plot.

Topics (a user contract), one message each per frame once the run has a track layer
(none before, so a run without one writes what it always wrote):

- ``/tracks/markers`` (``foxglove.SceneUpdate``): one entity per track, id
  ``track/<id>``: a sphere in its class colour (``sinks.view.TRACK_RGB``) as wide as
  twice its position sigma (0.3-10 m), a label ``<id> <class> p=<p_drone>`` above it
  (`` locked`` after it on the track the turret's tracker holds, which also has a
  green halo), and metadata ``id``, ``class``, ``p_drone``, ``locked``.  A track that
  is gone is deleted;
- ``/tracks`` (JSON, schema ``dronetrack.Tracks``): ``timestamp`` (sec, nsec),
  ``frame_id`` and ``tracks``, each with ``id``, ``class``, ``p_drone``, ``position``
  and ``velocity`` (x, y, z [m], [m/s]), ``pos_sigma_m`` and ``locked``, as in
  ``tracks.csv``.  Foxglove's Plot panel draws, say, ``/tracks.tracks[:]{id==3}.p_drone``.
"""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

from dronetrack.sinks.view import LOCKED_RGB, WORLD_FRAME, TrackUpdate, track_label, track_size
from dronetrack.types import TRACK_CLASSES

if TYPE_CHECKING:
    from foxglove.messages import Color, Pose, SceneEntity, SceneUpdate, Timestamp

    from dronetrack.sinks.view import TrackView

__all__ = [
    "MARKERS_TOPIC",
    "TABLE_SCHEMA",
    "TABLE_TOPIC",
    "TRACK_TOPICS",
    "track_scene",
    "track_table",
]

MARKERS_TOPIC = "/tracks/markers"
TABLE_TOPIC = "/tracks"
TRACK_TOPICS = (MARKERS_TOPIC, TABLE_TOPIC)

_ALPHA = 0.6
_HALO_ALPHA = 0.3
_HALO_SCALE = 1.8  # the locked track's halo against its sphere
_FONT_PX = 14.0
_LABEL_RISE = 0.3  # [m] above the sphere's top

_VECTOR = {
    "type": "object",
    "properties": {axis: {"type": "number"} for axis in "xyz"},
}
TABLE_SCHEMA: dict[str, Any] = {
    "title": "dronetrack.Tracks",
    "description": "Every object's track after a frame, world frame, SI units",
    "type": "object",
    "properties": {
        "timestamp": {
            "type": "object",
            "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
        },
        "frame_id": {"type": "string"},
        "tracks": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "id": {"type": "integer"},
                    "class": {"type": "string", "enum": list(TRACK_CLASSES)},
                    "p_drone": {"type": "number"},
                    "position": _VECTOR,
                    "velocity": _VECTOR,
                    "pos_sigma_m": {"type": "number"},
                    "locked": {"type": "boolean"},
                },
            },
        },
    },
}


def table_channel(context: Any) -> Any:
    """The ``/tracks`` channel on ``context`` (JSON with the schema above)."""
    import foxglove

    schema = foxglove.Schema(
        name="dronetrack.Tracks",
        encoding="jsonschema",
        data=json.dumps(TABLE_SCHEMA).encode(),
    )
    return foxglove.Channel(TABLE_TOPIC, schema=schema, message_encoding="json", context=context)


def _xyz(v: tuple[float, float, float]) -> dict[str, float]:
    return dict(zip("xyz", v, strict=True))


def track_table(update: TrackUpdate, stamp: Timestamp) -> dict[str, Any]:
    """The ``/tracks`` message of one frame."""
    return {
        "timestamp": {"sec": stamp.sec, "nsec": stamp.nsec},
        "frame_id": WORLD_FRAME,
        "tracks": [
            {
                "id": t.id,
                "class": t.cls,
                "p_drone": t.p_drone,
                "position": _xyz(t.position),
                "velocity": _xyz(t.velocity),
                "pos_sigma_m": t.sigma,
                "locked": t.locked,
            }
            for t in update.tracks
        ],
    }


def _color(rgb: tuple[int, int, int], alpha: float) -> Color:
    from foxglove.messages import Color

    r, g, b = (c / 255.0 for c in rgb)
    return Color(r=r, g=g, b=b, a=alpha)


def _pose(x: float, y: float, z: float) -> Pose:
    from foxglove.messages import Pose, Quaternion, Vector3

    return Pose(position=Vector3(x=x, y=y, z=z), orientation=Quaternion(x=0, y=0, z=0, w=1))


def _entity(track: TrackView, stamp: Timestamp) -> SceneEntity:
    from foxglove.messages import (
        KeyValuePair,
        SceneEntity,
        SpherePrimitive,
        TextPrimitive,
        Vector3,
    )

    x, y, z = track.position
    d = track_size(track.sigma)
    spheres = [
        SpherePrimitive(
            pose=_pose(x, y, z), size=Vector3(x=d, y=d, z=d), color=_color(track.rgb, _ALPHA)
        )
    ]
    if track.locked:
        h = _HALO_SCALE * d
        halo = SpherePrimitive(
            pose=_pose(x, y, z), size=Vector3(x=h, y=h, z=h), color=_color(LOCKED_RGB, _HALO_ALPHA)
        )
        spheres.append(halo)
    label = TextPrimitive(
        pose=_pose(x, y, z + d / 2 + _LABEL_RISE),
        billboard=True,
        font_size=_FONT_PX,
        scale_invariant=True,
        color=_color(track.rgb, 1.0),
        text=track_label(track),
    )
    metadata = [
        KeyValuePair(key="id", value=str(track.id)),
        KeyValuePair(key="class", value=track.cls),
        KeyValuePair(key="p_drone", value=f"{track.p_drone:.3f}"),
        KeyValuePair(key="locked", value=str(track.locked).lower()),
    ]
    return SceneEntity(
        timestamp=stamp,
        frame_id=WORLD_FRAME,
        id=f"track/{track.id}",
        metadata=metadata,
        spheres=spheres,
        texts=[label],
    )


def track_scene(update: TrackUpdate, stamp: Timestamp) -> SceneUpdate:
    """The ``/tracks/markers`` message of one frame: every track, and the gone deleted."""
    from foxglove.messages import SceneEntityDeletion, SceneEntityDeletionType, SceneUpdate

    deletions = [
        SceneEntityDeletion(
            timestamp=stamp, type=SceneEntityDeletionType.MatchingId, id=f"track/{ident}"
        )
        for ident in update.gone
    ]
    return SceneUpdate(deletions=deletions, entities=[_entity(t, stamp) for t in update.tracks])
