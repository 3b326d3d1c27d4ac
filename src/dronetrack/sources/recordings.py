"""Open any recording by what it holds, not by what it is called.

A file is recognised by its first bytes:

- ``#ROSBAG V2.0``: a ROS 1 bag;
- ``\x89MCAP0\r\n``: MCAP (a ROS 2 bag, or any other MCAP);
- ``SQLite format 3``: a ROS 2 sqlite3 bag file (``.db3``);
- ``LASF``: LAS or LAZ;
- a PCD header (``VERSION`` or ``FIELDS`` after any ``#`` comments): PCD.

A folder: a rosbag2 folder (``metadata.yaml``), split ROS 1 bags (``*.bag``), seed
003's CSV logs (``filtered_points.csv``) or ``.pcd`` files.  The readers are
``io.bag``, ``io.pcd_folder``, ``io.las`` and ``io.field_logs``, each imported only
when its kind of recording is opened.
"""

from __future__ import annotations

from pathlib import Path

from dronetrack.errors import RecordingError
from dronetrack.formats.magic import EXPECTED, check_mcap_end, sniff_file
from dronetrack.sources.recording import Recording, RecordingInfo, ReplayOptions

__all__ = ["open_recording", "recording_info", "recording_kind"]


def recording_kind(path: Path) -> str:
    """ "bag", "pcd", "las" or "field-logs"; RecordingError when it is none of them."""
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
    kind = sniff_file(path)
    if kind in ("ros1", "mcap", "sqlite3"):
        return "bag"
    if kind is not None:
        return kind
    with path.open("rb") as fh:
        start = fh.read(12)
    raise RecordingError(
        f"{path} is not a recording dronetrack reads: it starts with {start!r}, not "
        f"{EXPECTED} (a file cut off at its start cannot be read)"
    )


def recording_info(path: Path) -> RecordingInfo:
    """Topics, types, counts and duration; a bag need not have a LiDAR topic, and an
    MCAP file may have any profile (Foxglove's own files have none)."""
    if recording_kind(path) == "bag":
        from dronetrack.sources.bag import BagFile

        if path.is_file() and sniff_file(path) == "mcap":
            from dronetrack.sources.mcap_info import mcap_info, mcap_profile

            check_mcap_end(path)
            if mcap_profile(path) != "ros2":
                return mcap_info(path)
        return BagFile(path).info()
    return open_recording(path).info()


def open_recording(path: Path, options: ReplayOptions | None = None) -> Recording:
    """The reader for ``path``."""
    options = options or ReplayOptions()
    kind = recording_kind(path)
    if kind == "bag":
        from dronetrack.sources.bag import BagRecording

        return BagRecording(path, options)
    if kind == "pcd":
        from dronetrack.sources.pcd_folder import PcdRecording

        return PcdRecording(path, options)
    if kind == "las":
        from dronetrack.sources.las import LasRecording

        return LasRecording(path, options)
    from dronetrack.sources.field_logs import FieldLogRecording

    return FieldLogRecording(path, options)
