"""The channels, schemas and message counts of any MCAP file, whatever its profile.

rosbags reads MCAP files of the ``ros2`` profile only; Foxglove's own files
(``dronetrack simulate --foxglove``: protobuf schemas, no profile) and those of
other tools are listed with Foxglove's ``mcap`` reader instead.  The counts come
from the file's summary section; a file without one is read through once.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path
from typing import Any

from dronetrack.errors import RecordingError
from dronetrack.sources.recordings.recording import RecordingInfo, TopicInfo

__all__ = ["check_ros2_profile", "mcap_info", "mcap_profile"]

_NS = 1e-9


def mcap_profile(path: Path) -> str:
    """The profile in the file's header ("ros2", "" for none, ...)."""
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        try:
            return str(make_reader(fh).get_header().profile)
        except Exception as err:  # mcap raises its own classes, and struct/EOF errors
            raise RecordingError(f"{path}: cannot read the MCAP header: {err}") from None


def check_ros2_profile(path: Path) -> None:
    """rosbags replays MCAP files of the ``ros2`` profile; a ``RecordingError`` for any
    other, which ``info`` can still list."""
    profile = mcap_profile(path)
    if profile != "ros2":
        raise RecordingError(
            f"{path}: an MCAP file of profile {profile or 'none'!r}, not a ROS 2 bag, so it "
            "cannot be replayed (`dronetrack info` lists its channels); Foxglove's own files "
            "(simulate --foxglove) are for viewing"
        )


def mcap_info(path: Path) -> RecordingInfo:
    """``dronetrack info`` of an MCAP file: one row per channel, its schema (with the
    schema's encoding) and its message count."""
    from mcap.reader import make_reader

    with path.open("rb") as fh:
        try:
            reader = make_reader(fh)
            header = reader.get_header()
            summary = reader.get_summary()
            if summary is not None and summary.statistics is not None:
                stats = summary.statistics
                channels, schemas = summary.channels, summary.schemas
                counts: dict[int, int] = dict(stats.channel_message_counts)
                start, end = stats.message_start_time, stats.message_end_time
            else:
                channels, schemas, counts, start, end = _read_through(reader)
        except RecordingError:
            raise
        except Exception as err:  # mcap raises its own classes, and struct/EOF errors
            raise RecordingError(f"{path}: cannot read the MCAP file: {err}") from None
    topics = []
    for cid, channel in sorted(channels.items()):
        schema = schemas.get(channel.schema_id)
        if schema is None:
            kind = f"(no schema), {channel.message_encoding}"
        else:
            kind = f"{schema.name} ({schema.encoding or channel.message_encoding})"
        topics.append(TopicInfo(channel.topic, kind, int(counts.get(cid, 0))))
    profile = header.profile or "no profile"
    kind = f"mcap, {profile}, written by {header.library or 'an unnamed library'}"
    n = sum(t.count for t in topics)
    duration = (end - start) * _NS if n else 0.0
    return RecordingInfo(path, kind, start * _NS if n else 0.0, duration, tuple(topics))


def _read_through(
    reader: Any,
) -> tuple[dict[int, Any], dict[int, Any], dict[int, int], int, int]:
    """Channels, schemas, counts and time span from every message (no summary)."""
    channels: dict[int, Any] = {}
    schemas: dict[int, Any] = {}
    counts: Counter[int] = Counter()
    start, end = 2**63, 0
    for schema, channel, message in reader.iter_messages():
        channels[channel.id] = channel
        if schema is not None:
            schemas[schema.id] = schema
        counts[channel.id] += 1
        start = min(start, message.log_time)
        end = max(end, message.log_time)
    return channels, schemas, dict(counts), start, end
