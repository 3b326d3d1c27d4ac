"""Every object's track in the viewers: Foxglove (MCAP read back with rerun's MCAP
reader, which decodes the protobuf from the file's own schemas, and the ``mcap``
package for the JSON table), Rerun (its RRD reader) and ROS 2 (a loopback DDS
subscriber, decoded by rosbags' Humble typestore).

The frames go through ``ViewerFeed`` as the run loop hands them on: a scan frame
without a track layer, three tracks of three classes with the drone locked, two
(the bird gone, none locked), and a frame without a track layer again.  Every
expected value is computed from the tracks given, by the documented rules.
"""

from __future__ import annotations

import json
import math
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from dronetrack.geometry.transforms import make_pose
from dronetrack.sinks.view import (
    LOCKED_RGB,
    TRACK_RGB,
    TRACK_SIZE_M,
    ShownTracks,
    ViewerFeed,
    ViewerSink,
    track_size,
)
from dronetrack.types import TRACK_CLASSES, Frame, Sample, StepResult, Tracks
from foxglove_helpers import ws_messages
from ros2_helpers import loopback_dds

START = 1_700_000_000.0  # a replay's clock [s since the epoch]

# id, class, p_drone, position, velocity, position sigma [m] (drawn 1 m, 0.3 m, 10 m)
TRACKS = {
    3: ("drone", 0.93, (40.0, 5.0, 12.0), (-4.0, 1.0, 0.5), 0.5),
    7: ("bird", 0.04, (25.0, -8.0, 20.0), (6.0, 2.0, 0.0), 0.05),
    12: ("static", 0.01, (210.0, 30.0, 2.5), (0.0, 0.0, 0.0), 20.0),
}
LOCKED_ID = 3
SHOWN = [None, [3, 7, 12], [3, 12], None]  # the ids of each frame (None: no track layer)
LOCKED = [False, True, False, False]  # whether the frame's drone is locked


def _tracks(ids: list[int], locked: bool) -> Tracks:
    rows = [TRACKS[i] for i in ids]
    k = len(ids)
    cov = np.zeros((k, 6, 6))
    for j, row in enumerate(rows):
        cov[j] = np.diag([row[4] ** 2, (row[4] / 2) ** 2, (row[4] / 4) ** 2, 1.0, 1.0, 1.0])
    return Tracks(
        ids=np.array(ids, dtype=np.int64),
        positions=np.array([r[2] for r in rows]).reshape(k, 3),
        velocities=np.array([r[3] for r in rows]).reshape(k, 3),
        covariances=cov,
        born=np.zeros(k),
        updated=np.ones(k, dtype=bool),
        hovered=np.zeros(k, dtype=bool),
        locked=np.array([locked and i == LOCKED_ID for i in ids], dtype=bool),
        classes=np.array([TRACK_CLASSES.index(r[0]) for r in rows], dtype=np.int64),
        p_drone=np.array([r[1] for r in rows]),
    )


def _frame(stamp: float) -> Frame:
    pose = make_pose(np.eye(3), [0.0, 0.0, 1.0])
    points = np.array([[10.0, 0.0, 0.0], [12.0, 1.0, 0.5]])
    return Frame(
        stamp,
        0.1,
        points,
        np.full(2, stamp + 0.05),
        np.zeros(2, np.uint8),
        np.zeros(2, np.float32),
        np.array([stamp, stamp + 0.1]),
        np.stack([pose, pose]),
    )


def _feed(sinks: list[ViewerSink]) -> None:
    """The four frames, as the run loop hands them to the viewers."""
    feed = ViewerFeed(sinks)
    for i, ids in enumerate(SHOWN):
        frame = _frame(0.1 * i)
        result = StepResult(
            t=frame.end,
            phase="scan" if i == 0 else "track",
            estimate=None,
            n_points=0,
            n_returns=len(frame),
            command=None,
            step_ms=0.0,
            tracks=None if ids is None else _tracks(ids, LOCKED[i]),
        )
        feed.write(Sample(frame), result)


def _label(ident: int, p_drone: bool = True) -> str:
    """The documented label: ``<id> <class> p=<p_drone>``, `` locked`` on the locked one."""
    cls, p = TRACKS[ident][:2]
    text = f"{ident} {cls} p={p:.2f}" if p_drone else f"{ident} {cls}"
    return text + " locked" if ident == LOCKED_ID else text


def _size(ident: int) -> float:
    """The documented drawn size: 2 sigma within 0.3-10 m."""
    return {3: 1.0, 7: 0.3, 12: 10.0}[ident]


# ---------------------------------------------------------------- shared rules


def test_every_class_has_its_own_colour_apart_from_the_lock() -> None:
    assert set(TRACK_RGB) == set(TRACK_CLASSES)
    colours = [*TRACK_RGB.values(), LOCKED_RGB]
    assert len(set(colours)) == len(colours)


@given(st.floats(min_value=0.0, max_value=1e6), st.floats(min_value=0.0, max_value=1e6))
def test_track_size_is_twice_sigma_clipped_and_monotone(a: float, b: float) -> None:
    low, high = TRACK_SIZE_M
    sa, sb = track_size(a), track_size(b)
    assert low <= sa <= high
    if a <= b:
        assert sa <= sb
    if low <= 2 * a <= high:
        assert sa == pytest.approx(2 * a)
    assert track_size(math.nan) == high
    assert track_size(math.inf) == high


def test_shown_tracks_start_with_the_track_layer_and_delete_the_gone() -> None:
    shown = ShownTracks()
    assert shown.update(None) is None  # no track layer yet: nothing shown, nothing deleted
    first = shown.update(_tracks([3, 7, 12], True))
    assert first is not None
    assert [t.id for t in first.tracks] == [3, 7, 12]
    assert first.gone == []
    assert [t.cls for t in first.tracks] == ["drone", "bird", "static"]
    assert [t.locked for t in first.tracks] == [True, False, False]
    assert [t.sigma for t in first.tracks] == pytest.approx([0.5, 0.05, 20.0])
    second = shown.update(_tracks([12, 3], False))
    assert second is not None
    assert second.gone == [7]
    last = shown.update(None)  # the layer gone: every shown track is deleted
    assert last is not None
    assert (last.tracks, last.gone) == ([], [3, 12])
    empty = shown.update(Tracks.empty())
    assert empty is not None
    assert (empty.tracks, empty.gone) == ([], [])


# ---------------------------------------------------------------- Foxglove


def _mcap_rows(path: Path) -> dict[str, list[dict[str, Any]]]:
    """Decoded messages per topic in log-time order (rerun's MCAP reader)."""
    import pyarrow as pa
    from rerun.chunk import McapReader

    rows: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for chunk in McapReader(path).stream():
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        cols = [c.cast(pa.int64()) if pa.types.is_temporal(c.type) else c for c in batch.columns]
        rows[chunk.entity_path].extend(
            pa.RecordBatch.from_arrays(cols, batch.schema.names).to_pylist()
        )
    for topic_rows in rows.values():
        topic_rows.sort(key=lambda row: row["message_log_time"])
    return rows


def _json_messages(path: Path, topic: str) -> list[tuple[int, str, dict[str, Any]]]:
    """(log time, schema name, message) of a JSON topic (Foxglove's ``mcap`` reader)."""
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        return [
            (msg.log_time, schema.name, json.loads(msg.data))
            for schema, channel, msg in make_reader(fh).iter_messages(topics=[topic])
            if channel.message_encoding == "json"
        ]


def _ns(i: int) -> int:
    """Frame ``i``'s log time: the run's start plus the frame's end [ns]."""
    return round((START + _frame(0.1 * i).end) * 1e9)


def test_foxglove_shows_every_track_with_its_id_and_class(tmp_path: Path) -> None:
    pytest.importorskip("foxglove")
    pytest.importorskip("rerun")
    from dronetrack.sinks.foxglove.mcap_file import FoxgloveWriter

    path = tmp_path / "run.mcap"
    with FoxgloveWriter(path, start=START) as writer:
        _feed([writer])
    rows = _mcap_rows(path)
    scenes = [row["foxglove.SceneUpdate:message"][0] for row in rows["/tracks/markers"]]
    assert [row["message_log_time"] for row in rows["/tracks/markers"]] == [_ns(1), _ns(2), _ns(3)]
    assert len(rows["/track/markers"]) == len(SHOWN)  # the locked tracker's markers as before

    for scene, ids, locked in zip(scenes, SHOWN[1:], LOCKED[1:], strict=True):
        entities = scene["entities"] or []
        ids = ids or []
        assert len(entities) == len(ids)
        assert sorted(e["id"] for e in entities) == sorted(f"track/{i}" for i in ids)
        for entity in entities:
            ident = int(entity["id"].split("/")[1])
            cls, p, position = TRACKS[ident][:3]
            meta = {kv["key"]: kv["value"] for kv in entity["metadata"]}
            is_locked = locked and ident == LOCKED_ID
            assert meta == {
                "id": str(ident),
                "class": cls,
                "p_drone": f"{p:.3f}",
                "locked": str(is_locked).lower(),
            }
            [text] = entity["texts"]
            expected = _label(ident) if is_locked else _label(ident).removesuffix(" locked")
            assert text["text"] == expected
            sphere, *halo = entity["spheres"]
            assert len(halo) == int(is_locked)  # the locked one has its halo
            p0 = sphere["pose"]["position"]
            assert (p0["x"], p0["y"], p0["z"]) == position
            assert sphere["size"]["x"] == pytest.approx(_size(ident))
            colour = sphere["color"]
            got = tuple(round(colour[c] * 255) for c in "rgb")
            assert got == TRACK_RGB[cls]
            if is_locked:
                c = halo[0]["color"]
                assert tuple(round(c[k] * 255) for k in "rgb") == LOCKED_RGB
    deleted = [[d["id"] for d in scene["deletions"] or []] for scene in scenes]
    assert deleted == [[], ["track/7"], ["track/3", "track/12"]]

    table = _json_messages(path, "/tracks")
    assert [t for t, _, _ in table] == [_ns(1), _ns(2), _ns(3)]
    assert {name for _, name, _ in table} == {"dronetrack.Tracks"}
    first = table[0][2]
    assert first["frame_id"] == "world"
    assert first["timestamp"]["sec"] * 10**9 + first["timestamp"]["nsec"] == _ns(1)
    assert [row["id"] for row in first["tracks"]] == [3, 7, 12]
    for row in first["tracks"]:
        cls, p, position, velocity, sigma = TRACKS[row["id"]]
        assert row["class"] == cls
        assert row["p_drone"] == pytest.approx(p)
        assert tuple(row["position"][a] for a in "xyz") == position
        assert tuple(row["velocity"][a] for a in "xyz") == velocity
        assert row["pos_sigma_m"] == pytest.approx(sigma)
        assert row["locked"] is (row["id"] == LOCKED_ID)
    assert [row["id"] for row in table[1][2]["tracks"]] == [3, 12]
    assert not any(row["locked"] for row in table[1][2]["tracks"])
    assert table[2][2]["tracks"] == []


def test_foxglove_live_advertises_the_track_topics_with_the_first_tracks() -> None:
    """A WebSocket client sees the run's topics, and the track topics only once a frame
    has tracks."""
    pytest.importorskip("foxglove")
    from dronetrack.sinks.foxglove.live import FoxgloveServer
    from dronetrack.sinks.foxglove.mcap_file import TOPICS
    from dronetrack.sinks.foxglove.tracks import TRACK_TOPICS

    server = FoxgloveServer(0)
    messages = ws_messages(server.port, 5.0)
    schemas: dict[str, object] = {}

    def advertised(topics: tuple[str, ...]) -> None:
        for message in messages:
            if message.get("op") == "advertise":
                channels = message["channels"]
                assert isinstance(channels, list)
                schemas.update({c["topic"]: c["schemaName"] for c in channels})
            if set(schemas) >= set(topics):
                return

    try:
        advertised(TOPICS)
        assert set(schemas) == set(TOPICS)  # no track topics before a frame has tracks
        _feed([server])
        advertised(TRACK_TOPICS)
    finally:
        messages.close()
        server.close()
    assert schemas["/tracks/markers"] == "foxglove.SceneUpdate"
    assert schemas["/tracks"] == "dronetrack.Tracks"


# ---------------------------------------------------------------- Rerun


def _rgba32(rgb: tuple[int, int, int]) -> int:
    """rerun's packed colour: 0xRRGGBBAA, opaque."""
    r, g, b = rgb
    return (r << 24) | (g << 16) | (b << 8) | 0xFF


def test_rerun_shows_every_track_with_its_id_and_class(tmp_path: Path) -> None:
    pytest.importorskip("rerun")
    import pyarrow as pa
    from rerun.chunk import RrdReader

    from dronetrack.sinks.rerun_out import RerunWriter

    path = tmp_path / "run.rrd"
    with RerunWriter(path, start=START) as writer:
        _feed([writer])
    rows: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for chunk in RrdReader(path).store().stream():
        batch = chunk.to_record_batch()
        cols = [c.cast(pa.int64()) if pa.types.is_temporal(c.type) else c for c in batch.columns]
        rows[chunk.entity_path].extend(
            pa.RecordBatch.from_arrays(cols, batch.schema.names).to_pylist()
        )
    static = [r for r in rows["/world/tracks"] if "frame" not in r]
    frames = sorted((r for r in rows["/world/tracks"] if "frame" in r), key=lambda r: r["frame"])
    [context] = static  # the class names and colours
    [classes] = context["AnnotationContext:context"]
    infos = [c["class_description"]["info"] for c in classes]
    assert [(i["id"], i["label"]) for i in infos] == list(enumerate(TRACK_CLASSES))
    assert [i["color"] for i in infos] == [_rgba32(TRACK_RGB[c]) for c in TRACK_CLASSES]
    assert [r["frame"] for r in frames] == [1, 2, 3]

    for row, ids, locked in zip(frames, SHOWN[1:], LOCKED[1:], strict=True):
        ids = ids or []
        positions = row["Points3D:positions"]
        assert len(positions) == len(ids)
        # an empty frame carries no values: rerun refuses an empty AnyValues (a warning,
        # an error in strict mode)
        assert row.get("track_id", []) == ids
        expected = [
            _label(i, p_drone=False)
            if locked and i == LOCKED_ID
            else _label(i, p_drone=False).removesuffix(" locked")
            for i in ids
        ]
        assert row["Points3D:labels"] == expected
        assert row["Points3D:class_ids"] == [TRACK_CLASSES.index(TRACKS[i][0]) for i in ids]
        assert row["Points3D:colors"] == [_rgba32(TRACK_RGB[TRACKS[i][0]]) for i in ids]
        np.testing.assert_allclose(
            np.array(positions).reshape(-1, 3), np.array([TRACKS[i][2] for i in ids]).reshape(-1, 3)
        )
        assert row["Points3D:radii"] == pytest.approx([_size(i) / 2 for i in ids])
        assert row.get("p_drone", []) == pytest.approx([TRACKS[i][1] for i in ids])
        assert row.get("locked", []) == [locked and i == LOCKED_ID for i in ids]
    box = sorted(rows["/world/tracks/locked"], key=lambda r: r["frame"])
    assert [r.get("Clear:is_recursive") is not None for r in box] == [False, True, True]
    np.testing.assert_allclose(box[0]["Boxes3D:centers"], [TRACKS[LOCKED_ID][2]])
    counts = sorted(rows["/plots/n_tracks"], key=lambda r: r["frame"])
    assert [r["Scalars:scalars"] for r in counts] == [[3.0], [2.0], [0.0]]


# ---------------------------------------------------------------- ROS 2


def test_ros2_publishes_every_track_as_markers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    domain = loopback_dds(tmp_path, monkeypatch)
    from rosbags.typesys import Stores, get_typestore

    from dronetrack.sinks.ros2_out import TOPICS, Ros2Publisher
    from dronetrack.sources.ros2.dds import DdsDomain

    topic, msg_type = TOPICS["tracks"]
    sub = DdsDomain(domain)
    publisher = Ros2Publisher(domain)
    try:
        reader = sub.reader(topic, msg_type, "tf")  # reliable, depth 100
        end = time.monotonic() + 5.0
        while reader.matched() == 0 and time.monotonic() < end:
            time.sleep(0.02)
        _feed([publisher])
        raws: list[bytes] = []
        end = time.monotonic() + 3.0
        while len(raws) < 3 and time.monotonic() < end:
            raws.extend(reader.drain())
            time.sleep(0.02)
    finally:
        publisher.close()
        sub.close()
    ts = get_typestore(Stores.ROS2_HUMBLE)
    msgs = [ts.deserialize_cdr(raw, msg_type) for raw in raws]
    assert len(msgs) == 3  # none for the scan frame, one per frame from the first tracks
    marker = ts.types["visualization_msgs/msg/Marker"]

    def added(msg: Any, ns: str) -> dict[int, Any]:
        return {m.id: m for m in msg.markers if m.ns == ns and m.action == marker.ADD}

    def deleted(msg: Any, ns: str) -> list[int]:
        return sorted(m.id for m in msg.markers if m.ns == ns and m.action == marker.DELETE)

    for msg, ids, locked in zip(msgs, SHOWN[1:], LOCKED[1:], strict=True):
        ids = ids or []
        assert all(m.header.frame_id == "world" for m in msg.markers)
        spheres, labels = added(msg, "tracks"), added(msg, "track_labels")
        assert sorted(spheres) == sorted(ids)
        assert sorted(labels) == sorted(ids)
        for ident in ids:
            cls, _, position = TRACKS[ident][:3]
            s = spheres[ident]
            assert s.type == marker.SPHERE
            assert (s.pose.position.x, s.pose.position.y, s.pose.position.z) == position
            assert s.scale.x == pytest.approx(_size(ident))
            rgb = tuple(round(c * 255) for c in (s.color.r, s.color.g, s.color.b))
            assert rgb == TRACK_RGB[cls]
            text = labels[ident]
            assert text.type == marker.TEXT_VIEW_FACING
            is_locked = locked and ident == LOCKED_ID
            expected = _label(ident) if is_locked else _label(ident).removesuffix(" locked")
            assert text.text == expected
        halo = added(msg, "track_locked")
        if locked:
            p = halo[0].pose.position
            assert (p.x, p.y, p.z) == TRACKS[LOCKED_ID][2]
        else:
            assert halo == {}
            assert deleted(msg, "track_locked") == [0]
    assert [deleted(m, "tracks") for m in msgs] == [[], [7], [3, 12]]
    assert [deleted(m, "track_labels") for m in msgs] == [[], [7], [3, 12]]


def test_foxglove_puts_every_track_and_zone_on_the_map(tmp_path: Path) -> None:
    pytest.importorskip("foxglove")
    pytest.importorskip("rerun")
    import pymap3d

    from dronetrack.geometry.geodesy import SiteFrame
    from dronetrack.sinks.foxglove.geo import SiteView
    from dronetrack.sinks.foxglove.mcap_file import FoxgloveWriter
    from dronetrack.zones import circle

    # world x points north (heading 0°), the turret base 1 m up: ENU = (−y, x, z − 1)
    site = SiteFrame(47.4, 19.2, 120.0, 0.0, (0.0, 0.0, 1.0))
    path = tmp_path / "run.mcap"
    with FoxgloveWriter(path, start=START) as writer:
        writer.show_site(SiteView(site, (circle("depot", (50.0, 0.0), 20.0, margin_m=10.0),)))
        _feed([writer])
    rows = _mcap_rows(path)
    fixes = rows["/tracks/fix"]
    # frames 1 and 2 have 3 and 2 tracks; frame 3 none
    assert [row["message_log_time"] for row in fixes] == [_ns(1)] * 3 + [_ns(2)] * 2
    for row in fixes:
        ident = int(row["CoordinateFrame:frame"][0].split("/")[1])
        cls, _, (x, y, z) = TRACKS[ident][:3]
        lat, lon, _ = pymap3d.enu2geodetic(-y, x, z - 1.0, 47.4, 19.2, 120.0)
        [[got_lat, got_lon]] = row["GeoPoints:positions"]
        assert got_lat == pytest.approx(lat, abs=1e-9)
        assert got_lon == pytest.approx(lon, abs=1e-9)
        rgba = row["GeoPoints:colors"][0]
        assert ((rgba >> 24) & 255, (rgba >> 16) & 255, (rgba >> 8) & 255) == TRACK_RGB[cls]
    [zones] = rows["/zones"]  # once: the run is shorter than ZONES_EVERY_S
    collection = json.loads(zones["foxglove.GeoJSON:message"][0]["geojson"])
    kinds = [(f["properties"]["name"], f["properties"]["kind"]) for f in collection["features"]]
    assert kinds == [("depot", "zone"), ("depot", "margin")]
    ring = np.array(collection["features"][0]["geometry"]["coordinates"][0])  # [lon, lat]
    e, n, _ = pymap3d.geodetic2enu(ring[:, 1], ring[:, 0], 120.0, 47.4, 19.2, 120.0)
    # the circle about world (50, 0): 50 m north of the site, 20 m across
    np.testing.assert_allclose(np.hypot(e, n - 50.0), 20.0, atol=0.02)
