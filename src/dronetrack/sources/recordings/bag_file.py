"""A bag's container, ROS 1 or ROS 2 (sqlite3 or MCAP storage) or a bare ``.mcap``
file, opened with rosbags: its listing for ``dronetrack info``, and its raw messages,
with every way a corrupt file fails turned into one ``RecordingError`` line.  The
frames, poses and ground truth of a replay are read from it in ``sources/recordings/bag.py``.
"""

from __future__ import annotations

import logging
import shutil
import struct
import tempfile
import weakref
from collections import Counter
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rosbags.highlevel import AnyReader, AnyReaderError
from rosbags.rosbag1 import ReaderError as Reader1Error
from rosbags.rosbag2 import ReaderError as Reader2Error

from dronetrack.errors import DecodeError, RecordingError
from dronetrack.formats.magic import EXPECTED, check_mcap_end, ros1_damage, sniff_file
from dronetrack.formats.ros.livox_msg import livox_typestore
from dronetrack.sources.recordings.mcap_info import check_ros2_profile
from dronetrack.sources.recordings.recording import RecordingInfo, TopicInfo

__all__ = ["BAD_DATA", "BagFile", "bag_paths"]

log = logging.getLogger(__name__)

_MAX_WARNINGS = 5  # per reason; later skips are only counted


_SUFFIX = {"ros1": ".bag", "mcap": ".mcap", "sqlite3": ".db3"}


def bag_paths(path: Path) -> list[Path]:
    """What to hand to rosbags: split ROS 1 bags in a folder, else the path itself."""
    if path.is_dir() and not (path / "metadata.yaml").exists():
        return sorted(path.glob("*.bag"))
    return [path]


def _kind(path: Path) -> str:
    """The container, as ``dronetrack info`` names it."""
    if path.is_dir():
        if any(path.glob("*.bag")) and not (path / "metadata.yaml").exists():
            return "ros1"
        return "ros2-sqlite3" if any(path.glob("*.db3")) else "ros2-mcap"
    return {"ros1": "ros1", "mcap": "mcap", "sqlite3": "ros2-sqlite3"}.get(
        sniff_file(path) or "", "unknown"
    )


def _open_error(path: Path, exc: Exception) -> RecordingError:
    """One line on why the bag ``path`` does not open, and what can be done about it."""
    damage = ros1_damage(path) if path.is_file() and sniff_file(path) == "ros1" else None
    if damage is not None:
        return RecordingError(f"{path}: {damage}")
    if isinstance(exc, UnicodeDecodeError):
        return RecordingError(
            f"{path}: cannot open the recording: it is corrupt (a header field that should "
            "be text is not UTF-8)"
        )
    return RecordingError(f"{path}: cannot open the recording: {exc}")


def _rosbags_paths(path: Path) -> tuple[list[Path], Path | None]:
    """The paths to hand to rosbags, which tells the containers apart by suffix, and a
    temporary folder to remove afterwards: a bag file whose suffix does not say what it
    holds (``record --out flight`` writes one) is handed over as a link named right."""
    paths = bag_paths(path)
    if path.is_dir():
        for inner in path.glob("*.mcap"):
            check_mcap_end(inner)
        return paths, None
    kind = sniff_file(path)
    if kind == "mcap":
        check_mcap_end(path)
        check_ros2_profile(path)
    suffix = _SUFFIX.get(kind or "")
    if suffix is None:
        raise RecordingError(f"{path} is not a bag: it starts with none of {EXPECTED}")
    if path.suffix == suffix:
        return paths, None
    alias = Path(tempfile.mkdtemp(prefix="dronetrack-bag-"))
    link = alias / f"{path.stem or 'recording'}{suffix}"
    link.symlink_to(path.resolve())
    return [link], alias


# What a corrupt message or container can raise from rosbags or our decoders.
BAD_DATA = (
    AnyReaderError,
    Reader1Error,
    Reader2Error,
    EOFError,
    OverflowError,
    DecodeError,
    ValueError,
    IndexError,
    KeyError,
    struct.error,
    UnicodeDecodeError,
    # rosbags' ROS 1 reader checks a chunk's message against its index entry with an
    # assert (the two times must agree), so a flipped byte there raises AssertionError
    AssertionError,
)


class BagFile:
    """A bag's container: open it, list it, iterate its raw messages."""

    def __init__(self, path: Path, *, check: bool = True) -> None:
        self.path = path
        self.skipped: Counter[str] = Counter()
        self._warned: Counter[str] = Counter()
        self._paths: list[Path] | None = None
        if check:
            with self._reader():
                pass  # fail now, with one line, if it cannot be opened

    def info(self) -> RecordingInfo:
        """Topics, types, message counts and duration."""
        with self._reader() as reader:
            counts: Counter[tuple[str, str]] = Counter()
            for c in reader.connections:
                counts[(c.topic, c.msgtype)] += int(c.msgcount)
            start, end = int(reader.start_time), int(reader.end_time)
        topics = tuple(TopicInfo(t, m, n) for (t, m), n in sorted(counts.items()))
        return RecordingInfo(
            self.path, _kind(self.path), start * 1e-9, (end - start) * 1e-9, topics
        )

    def _rosbags_paths(self) -> list[Path]:
        if self._paths is None:
            if not self.path.exists():
                raise RecordingError(f"{self.path}: no such recording")
            self._paths, alias = _rosbags_paths(self.path)
            if alias is not None:
                weakref.finalize(self, shutil.rmtree, alias, ignore_errors=True)
        return self._paths

    @contextmanager
    def _reader(self) -> Iterator[Any]:
        paths = self._rosbags_paths()
        if not paths or not all(p.exists() for p in paths):
            raise RecordingError(f"{self.path}: no such recording")
        try:
            reader = AnyReader(paths, default_typestore=livox_typestore(ros1=False))
            reader.open()
        except (OSError, *BAD_DATA) as exc:
            raise _open_error(self.path, exc) from None
        try:
            yield reader
        except (AnyReaderError, OSError) as exc:
            raise RecordingError(f"{self.path}: the recording is corrupt: {exc}") from None
        finally:
            reader.close()

    def _skip(self, reason: str, detail: object) -> None:
        self.skipped[reason] += 1
        self._warned[reason] += 1
        if self._warned[reason] <= _MAX_WARNINGS:
            log.warning("%s: skipped a message (%s): %s", self.path.name, reason, detail)

    def _messages(self, reader: Any, conns: Sequence[Any]) -> Iterator[tuple[Any, int, bytes]]:
        """(connection, log time, raw bytes); a corrupt container ends with a RecordingError."""
        # Connections belong to the reader that listed them: find this reader's own.
        wanted = {(c.topic, c.msgtype) for c in conns}
        own = [c for c in reader.connections if (c.topic, c.msgtype) in wanted]
        if not own:  # rosbags reads every connection when given none
            return
        it = reader.messages(connections=own)
        while True:
            try:
                item = next(it)
            except StopIteration:
                return
            except BAD_DATA as exc:
                raise RecordingError(f"{self.path}: the recording is corrupt: {exc}") from None
            yield item

    def _deserialize(self, reader: Any, raw: bytes, msgtype: str, reason: str) -> Any | None:
        try:
            return reader.deserialize(raw, msgtype)
        except BAD_DATA as exc:
            self._skip(reason, exc)
            return None
