"""open_recording: each kind of recording goes to its one reader in READERS."""

from __future__ import annotations

from pathlib import Path
from typing import get_args

import numpy as np
import pytest

from dronetrack.errors import RecordingError
from dronetrack.formats.magic import MCAP_MAGIC, ROSBAG1_MAGIC
from dronetrack.sources.recordings import opener as recordings
from dronetrack.sources.recordings.opener import (
    READERS,
    RecordingKind,
    open_recording,
    recording_kind,
)
from dronetrack.sources.recordings.recording import ReplayOptions, truth_overlap_warning
from dronetrack.sources.truth import GroundTruth


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


START = 1_767_225_600.0  # a recording made at 2026-01-01 00:00:00 UTC [Unix s]


def _truth(t: list[float]) -> GroundTruth:
    return GroundTruth(np.asarray(t), np.zeros((len(t), 3)))


@pytest.mark.parametrize(
    ("t", "looks_like"),
    [
        ([START + 0.1, START + 13.0], "absolute seconds (subtract the start, 1767225600.000 s)"),
        ([100.0, 13_000.0], "milliseconds from the start (divide by 1000)"),
        ([(START + 0.1) * 1e9, (START + 13.0) * 1e9], "absolute nanoseconds (divide by 1e+09"),
        ([20.0, 30.0], None),  # after the end, in no unit that would fit
    ],
)
def test_truth_outside_the_recording_is_named_with_both_spans(
    t: list[float], looks_like: str | None
) -> None:
    """Truth that never overlaps the frames (0 to 13 s from the start): the warning gives
    the recording's span from its start and as stamped, and the truth's as given."""
    text = truth_overlap_warning(_truth(t), 0.0, 13.0, START, Path("truth.csv"))
    assert text is not None
    assert text.startswith("no truth sample falls inside the recording's time span")
    assert (
        "0.000 to 13.000 s from its start (1767225600.000 to 1767225613.000 s as stamped)" in text
    )
    assert f"truth.csv's t spans {t[0]:.3f} to {t[-1]:.3f} s as given" in text
    if looks_like is None:
        assert "look like" not in text
    else:
        assert f"they look like {looks_like}" in text


def test_truth_that_touches_the_recording_gives_no_warning() -> None:
    """One sample inside the frames' span is enough, even at its very end."""
    assert truth_overlap_warning(_truth([13.0, 20.0]), 0.0, 13.0, START) is None
    assert truth_overlap_warning(_truth([-5.0, 0.0]), 0.0, 13.0, START) is None
    own = truth_overlap_warning(_truth([-60.0, -50.0]), 0.0, 13.0, START)
    assert own is not None  # the recording's own truth, on another clock
    assert "its ground truth spans -60.000 to -50.000 s from its start" in own
