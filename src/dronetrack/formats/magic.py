"""What kind of file a recording is, from its first bytes (see ``sources.recordings.opener``), and
whether a bag file is whole: an MCAP file ends with its magic too, and a ROS 1 bag's
file header says where its index starts, 0 until the writer closes it.
"""

from __future__ import annotations

import struct
from pathlib import Path

from dronetrack.errors import RecordingError

__all__ = ["EXPECTED", "MAGIC", "check_mcap_end", "ros1_damage", "sniff_file"]

ROSBAG1_MAGIC = b"#ROSBAG V2.0\n"
MCAP_MAGIC = b"\x89MCAP0\r\n"  # an MCAP file starts and ends with it
# What a file starts with, and what that makes it.
MAGIC: tuple[tuple[bytes, str], ...] = (
    (ROSBAG1_MAGIC, "ros1"),
    (MCAP_MAGIC, "mcap"),
    (b"SQLite format 3\x00", "sqlite3"),
    (b"LASF", "las"),
    (b"livox_tech", "lvx"),  # LVX and LVX2 (Livox Viewer 1 and 2)
)
_PCD_KEYS = (b"VERSION", b"FIELDS")
_HEAD = 4096  # bytes read to recognise a file (a PCD header's comments included)
EXPECTED = (
    "a ROS 1 bag ('#ROSBAG V2.0'), MCAP, a ROS 2 .db3 (SQLite), a PCD header, LAS ('LASF') "
    "or Livox LVX ('livox_tech')"
)


def sniff_file(path: Path) -> str | None:
    """ "ros1", "mcap", "sqlite3", "las", "lvx" or "pcd" from the file's first bytes; None if
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


def check_mcap_end(path: Path) -> None:
    """A ``RecordingError`` if the MCAP file ``path`` lacks its closing magic: the writer
    stopped before finishing it (a crash, a full disk, a copy cut short)."""
    size = path.stat().st_size
    with path.open("rb") as fh:
        fh.seek(max(0, size - len(MCAP_MAGIC)))
        tail = fh.read()
    if tail != MCAP_MAGIC:
        raise RecordingError(
            f"{path} is a truncated MCAP file: it does not end with MCAP's closing magic, "
            "so its writer stopped before finishing it; recover the messages it holds with "
            f"the mcap command-line tool, `mcap recover {path} -o recovered.mcap`, and read "
            "recovered.mcap"
        )


_REINDEX = "`rosbag reindex FILE` (ROS 1's tools) rebuilds its index; or record it again"
_INDEX_POS = b"index_pos="


def _ros1_index_pos(path: Path) -> int | None:
    """The ``index_pos`` of a ROS 1 bag's file-header record (ROS bag format 2.0): where
    the index starts, 0 while the bag is being written and until it is closed."""
    with path.open("rb") as fh:
        head = fh.read(len(ROSBAG1_MAGIC) + 4096)
    at = head.find(_INDEX_POS)
    if not head.startswith(ROSBAG1_MAGIC) or at < 0 or at + len(_INDEX_POS) + 8 > len(head):
        return None
    pos: int = struct.unpack_from("<Q", head, at + len(_INDEX_POS))[0]
    return pos


def ros1_damage(path: Path) -> str | None:
    """What is wrong with the ROS 1 bag ``path`` and how to mend it, if its header says:
    never closed (no index) or cut short (the index lies beyond the end); else None."""
    pos, size = _ros1_index_pos(path), path.stat().st_size
    if pos == 0:
        return "the ROS 1 bag was never closed (its header points to no index); " + _REINDEX
    if pos is not None and pos >= size:
        return (
            f"the ROS 1 bag is truncated (its index should start at byte {pos}, the file "
            f"has {size}); " + _REINDEX
        )
    return None
