"""Open any recording by what it holds, not by what it is called.

A file is recognised by its first bytes:

- ``#ROSBAG V2.0``: a ROS 1 bag;
- ``\x89MCAP0\r\n``: MCAP (a ROS 2 bag, or any other MCAP);
- ``SQLite format 3``: a ROS 2 sqlite3 bag file (``.db3``);
- ``LASF``: LAS or LAZ;
- ``livox_tech``: a Livox Viewer recording, LVX or LVX2;
- a PCD header (``VERSION`` or ``FIELDS`` after any ``#`` comments): PCD.

A folder: a rosbag2 folder (``metadata.yaml``), split ROS 1 bags (``*.bag``), seed
003's CSV logs (``filtered_points.csv``) or ``.pcd`` files.  ``READERS`` maps each
kind to its reader in this package (``bag`` for ROS 1, MCAP and ``.db3`` bags,
``pcd``, ``las``, ``lvx``, ``field_logs``), each imported only when its kind of recording is opened.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Literal

from dronetrack.errors import RecordingError
from dronetrack.formats.magic import EXPECTED, check_mcap_end, sniff_file
from dronetrack.sources.recordings.recording import Recording, RecordingInfo, ReplayOptions

__all__ = ["READERS", "RecordingKind", "open_recording", "recording_info", "recording_kind"]

RecordingKind = Literal["bag", "pcd", "las", "lvx", "field-logs"]
Reader = Callable[[Path, ReplayOptions], Recording]


def _bag(path: Path, options: ReplayOptions) -> Recording:
    from dronetrack.sources.recordings.bag import BagRecording

    return BagRecording(path, options)


def _pcd(path: Path, options: ReplayOptions) -> Recording:
    from dronetrack.sources.recordings.pcd import PcdRecording

    return PcdRecording(path, options)


def _las(path: Path, options: ReplayOptions) -> Recording:
    from dronetrack.sources.recordings.las import LasRecording

    return LasRecording(path, options)


def _lvx(path: Path, options: ReplayOptions) -> Recording:
    from dronetrack.sources.recordings.lvx import LvxRecording

    return LvxRecording(path, options)


def _field_logs(path: Path, options: ReplayOptions) -> Recording:
    from dronetrack.sources.recordings.field_logs import FieldLogRecording

    return FieldLogRecording(path, options)


READERS: dict[RecordingKind, Reader] = {
    "bag": _bag,  # a ROS 1 bag (or split bags), MCAP, a .db3 file or a rosbag2 folder
    "pcd": _pcd,  # a .pcd file or a folder of them
    "las": _las,  # a .las or .laz file
    "lvx": _lvx,  # a Livox Viewer .lvx or .lvx2 file
    "field-logs": _field_logs,  # seed 003's CSV logs
}


# formats.magic.sniff_file's answer for a single file → the kind of recording
_FILE_KINDS: dict[str, RecordingKind] = {
    "ros1": "bag",
    "mcap": "bag",
    "sqlite3": "bag",
    "pcd": "pcd",
    "las": "las",
    "lvx": "lvx",
}


def recording_kind(path: Path) -> RecordingKind:
    """ "bag", "pcd", "las", "lvx" or "field-logs"; RecordingError when it is none of them."""
    if not path.exists():
        raise RecordingError(f"no such recording: {path}")
    if path.is_dir():
        if (path / "metadata.yaml").exists() or any(path.glob("*.bag")):
            return "bag"
        if (path / "filtered_points.csv").exists():
            return "field-logs"
        if any(f.suffix.lower() == ".pcd" for f in path.iterdir()):
            return "pcd"
        raise RecordingError(
            f"{path}: a folder with no bag (metadata.yaml, *.bag), .pcd files or "
            "filtered_points.csv"
        )
    if path.stat().st_size == 0:
        raise RecordingError(f"{path} is empty; expected {EXPECTED}")
    sniffed = sniff_file(path)
    if sniffed in _FILE_KINDS:
        return _FILE_KINDS[sniffed]
    with path.open("rb") as fh:
        start = fh.read(12)
    raise RecordingError(
        f"{path} is not a recording dronetrack reads: it starts with {start!r}, not "
        f"{EXPECTED} (a file cut off at its start cannot be read)"
    )


def recording_info(path: Path) -> RecordingInfo:
    """Topics, types, counts and duration; a bag need not have a LiDAR topic, and an
    MCAP file may have any profile (Foxglove's own files have none); an LVX file may
    hold several LiDARs."""
    kind = recording_kind(path)
    if kind == "lvx":
        from dronetrack.sources.recordings.lvx import LvxFile

        return LvxFile(path).info()
    if kind == "bag":
        from dronetrack.sources.recordings.bag_file import BagFile

        if path.is_file() and sniff_file(path) == "mcap":
            from dronetrack.sources.recordings.mcap_info import mcap_info, mcap_profile

            check_mcap_end(path)
            if mcap_profile(path) != "ros2":
                return mcap_info(path)
        return BagFile(path).info()
    return open_recording(path).info()


def open_recording(path: Path, options: ReplayOptions | None = None) -> Recording:
    """The reader for ``path``."""
    return READERS[recording_kind(path)](path, options or ReplayOptions())
