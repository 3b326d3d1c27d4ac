"""``results.jsonl``: one JSON line per finished run, appended as each run ends.

Each line is written whole and flushed to disk before the next run's result is
taken, so a crash loses at most the line being written; a torn last line is
skipped (with a warning) when the file is read again.  A run is done when its
``key`` has a line, so an interrupted sweep resumes where it stopped.
"""

from __future__ import annotations

import json
import logging
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from dronetrack.sinks.run_folder import json_safe

__all__ = ["RESULTS_FILE", "ResultStore", "read_results"]

log = logging.getLogger(__name__)

RESULTS_FILE = "results.jsonl"  # its name in a sweep's folder


def read_results(path: Path) -> Iterator[dict[str, Any]]:
    """The result lines of ``path`` (none if it does not exist); torn lines are skipped."""
    if not path.exists():
        return
    with path.open() as fh:
        for n, line in enumerate(fh, start=1):
            if not line.strip():
                continue
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                log.warning("%s line %d is not complete JSON; skipped", path, n)
                continue
            if isinstance(row, dict) and "key" in row:
                yield row


class ResultStore:
    """Appends result lines to ``path`` and knows which runs are done."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.done: set[str] = {row["key"] for row in read_results(path)}
        path.parent.mkdir(parents=True, exist_ok=True)
        self._ends_cleanly = _ends_with_newline(path)

    def add(self, row: dict[str, Any]) -> bool:
        """Append ``row`` (it must have a ``key``) unless that run is done; True if written."""
        key = row["key"]
        if key in self.done:
            return False
        text = json.dumps(json_safe(row), sort_keys=True, allow_nan=False) + "\n"
        with self.path.open("a") as fh:
            if not self._ends_cleanly:  # after a torn line, start a fresh one
                fh.write("\n")
                self._ends_cleanly = True
            fh.write(text)
            fh.flush()
            os.fsync(fh.fileno())
        self.done.add(key)
        return True


def _ends_with_newline(path: Path) -> bool:
    if not path.exists() or path.stat().st_size == 0:
        return True
    with path.open("rb") as fh:
        fh.seek(-1, os.SEEK_END)
        return fh.read(1) == b"\n"
