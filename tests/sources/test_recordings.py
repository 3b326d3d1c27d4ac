"""open_recording: each kind of recording goes to its one reader in READERS."""

from __future__ import annotations

from pathlib import Path
from typing import get_args

import pytest

from dronetrack.errors import RecordingError
from dronetrack.formats.magic import MCAP_MAGIC, ROSBAG1_MAGIC
from dronetrack.sources import recordings
from dronetrack.sources.recording import ReplayOptions
from dronetrack.sources.recordings import READERS, RecordingKind, open_recording, recording_kind


def test_every_kind_has_exactly_one_reader() -> None:
    assert tuple(READERS) == get_args(RecordingKind)


def _recordings(root: Path) -> dict[str, tuple[Path, RecordingKind]]:
    """A file or folder of each shape, by the kind its first bytes or contents make it."""
    made: dict[str, tuple[Path, RecordingKind]] = {}

    def file(name: str, data: bytes, kind: RecordingKind) -> None:
        (root / name).write_bytes(data)
        made[name] = (root / name, kind)

    def folder(name: str, entry: str, kind: RecordingKind) -> None:
        (root / name).mkdir()
        (root / name / entry).write_text("x\n")
        made[name] = (root / name, kind)

    # Named against their contents on purpose: the bytes decide, not the suffix.
    file("ros1.pcd", ROSBAG1_MAGIC + b"\0" * 8, "bag")
    file("mcap.las", MCAP_MAGIC + b"\0" * 8, "bag")
    file("sqlite.bag", b"SQLite format 3\x00" + b"\0" * 8, "bag")
    file("cloud.db3", b"# a comment\nVERSION 0.7\nFIELDS x y z\n", "pcd")
    file("survey.mcap", b"LASF" + b"\0" * 8, "las")
    folder("rosbag2", "metadata.yaml", "bag")
    folder("split", "a.bag", "bag")
    folder("field", "filtered_points.csv", "field-logs")
    folder("clouds", "0001.PCD", "pcd")
    return made


def test_the_kind_comes_from_the_contents_and_picks_that_reader(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    opened: list[tuple[str, Path, ReplayOptions]] = []
    for kind in get_args(RecordingKind):

        def reader(path: Path, options: ReplayOptions, kind: str = kind) -> object:
            opened.append((kind, path, options))
            return kind

        monkeypatch.setitem(recordings.READERS, kind, reader)
    options = ReplayOptions(period_s=0.05)
    for path, kind in _recordings(tmp_path).values():
        assert recording_kind(path) == kind, path.name
        assert open_recording(path, options) == kind
        assert opened[-1] == (kind, path, options)
    assert open_recording(path) == kind
    assert opened[-1][2] == ReplayOptions()  # the default options


@pytest.mark.parametrize(
    ("name", "data", "message"),
    [
        ("missing.bag", None, "no such recording"),
        ("empty.bag", b"", "is empty"),
        ("notes.bag", b"hello, world", "is not a recording dronetrack reads"),
    ],
)
def test_what_is_no_recording_is_one_error(
    tmp_path: Path, name: str, data: bytes | None, message: str
) -> None:
    path = tmp_path / name
    if data is not None:
        path.write_bytes(data)
    with pytest.raises(RecordingError, match=message):
        open_recording(path)


def test_a_folder_of_nothing_readable_is_one_error(tmp_path: Path) -> None:
    (tmp_path / "notes.txt").write_text("x\n")
    with pytest.raises(RecordingError, match="a folder with no bag"):
        open_recording(tmp_path)
