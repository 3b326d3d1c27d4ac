"""What kind of file a recording is, from its first bytes (see ``io.recordings``)."""

from __future__ import annotations

from pathlib import Path

__all__ = ["EXPECTED", "MAGIC", "sniff_file"]

# What a file starts with, and what that makes it.
MAGIC: tuple[tuple[bytes, str], ...] = (
    (b"#ROSBAG V2.0\n", "ros1"),
    (b"\x89MCAP0\r\n", "mcap"),
    (b"SQLite format 3\x00", "sqlite3"),
    (b"LASF", "las"),
)
_PCD_KEYS = (b"VERSION", b"FIELDS")
_HEAD = 4096  # bytes read to recognise a file (a PCD header's comments included)
EXPECTED = "a ROS 1 bag ('#ROSBAG V2.0'), MCAP, a ROS 2 .db3 (SQLite), a PCD header or LAS ('LASF')"


def sniff_file(path: Path) -> str | None:
    """ "ros1", "mcap", "sqlite3", "las" or "pcd" from the file's first bytes; None if
    it is none of them."""
    with path.open("rb") as fh:
        head = fh.read(_HEAD)
    for magic, kind in MAGIC:
        if head.startswith(magic):
            return kind
    for line in head.splitlines():
        line = line.strip()
        if not line or line.startswith(b"#"):
            continue
        return "pcd" if line.split()[0] in _PCD_KEYS else None
    return None
