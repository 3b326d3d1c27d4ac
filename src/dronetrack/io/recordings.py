"""Open any recording by what its path looks like.

- ``.bag`` (ROS 1), a folder of split ``.bag`` files, a rosbag2 folder
  (``metadata.yaml``), a bare ``.mcap`` or ``.db3`` file: ``io.bag``;
- a ``.pcd`` file or a folder of them: ``io.pcd_folder``;
- a ``.las``/``.laz`` file: ``io.las``;
- a folder with seed 003's ``filtered_points.csv``: ``io.field_logs``.

Each reader is imported only when its kind of recording is opened.
"""

from __future__ import annotations

from pathlib import Path

from dronetrack.errors import RecordingError
from dronetrack.io.source import Recording, RecordingInfo, ReplayOptions

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
    suffix = path.suffix.lower()
    if suffix in (".bag", ".mcap", ".db3"):
        return "bag"
    if suffix in (".las", ".laz"):
        return "las"
    if suffix == ".pcd":
        return "pcd"
    raise RecordingError(
        f"{path}: unknown recording type {suffix or '(no suffix)'!r}; expected .bag, .mcap, "
        ".db3, .pcd, .las, .laz or a folder"
    )


def recording_info(path: Path) -> RecordingInfo:
    """Topics, types, counts and duration; a bag need not have a LiDAR topic."""
    if recording_kind(path) == "bag":
        from dronetrack.io.bag import BagFile

        return BagFile(path).info()
    return open_recording(path).info()


def open_recording(path: Path, options: ReplayOptions | None = None) -> Recording:
    """The reader for ``path``."""
    options = options or ReplayOptions()
    kind = recording_kind(path)
    if kind == "bag":
        from dronetrack.io.bag import BagRecording

        return BagRecording(path, options)
    if kind == "pcd":
        from dronetrack.io.pcd_folder import PcdRecording

        return PcdRecording(path, options)
    if kind == "las":
        from dronetrack.io.las import LasRecording

        return LasRecording(path, options)
    from dronetrack.io.field_logs import FieldLogRecording

    return FieldLogRecording(path, options)
