"""Loopback-only DDS for the ROS 2 tests, and the check of the tracks a run publishes.

Cyclone DDS reads its configuration from ``CYCLONEDDS_URI``: here the loopback
interface only, no multicast, and 127.0.0.1 as the one unicast peer (discovery
probes the participant indices 0-``MAX_INDEX`` there).  Each test takes a domain
id of its own from ``DOMAIN_BASE`` on, with the process id mixed in, so two test
runs on one machine do not hear each other.
"""

from __future__ import annotations

import csv
import itertools
import os
from pathlib import Path
from typing import Any

import pytest

MAX_INDEX = 30
CONFIG = f"""<?xml version="1.0" encoding="UTF-8"?>
<CycloneDDS><Domain Id="any">
  <General>
    <Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>
    <AllowMulticast>false</AllowMulticast>
  </General>
  <Discovery>
    <ParticipantIndex>auto</ParticipantIndex>
    <MaxAutoParticipantIndex>{MAX_INDEX}</MaxAutoParticipantIndex>
    <Peers><Peer address="127.0.0.1"/></Peers>
  </Discovery>
</Domain></CycloneDDS>
"""
DOMAIN_BASE = 120
_ids = itertools.count()


def loopback_dds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> int:
    """Point Cyclone at the loopback configuration (for this process and its children)
    and return a fresh domain id for the test."""
    pytest.importorskip("cyclonedds")
    path = tmp_path / "cyclonedds.xml"
    path.write_text(CONFIG)
    monkeypatch.setenv("CYCLONEDDS_URI", path.as_uri())
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    return DOMAIN_BASE + (os.getpid() * 7 + next(_ids)) % 90


def check_tracks_published(messages: list[Any], run_folder: Path) -> None:
    """The decoded ``/dronetrack/tracks`` MarkerArrays of a run hold, frame by frame,
    the tracks its ``tracks.csv`` logs: one message per tracking frame (``frames.csv``),
    and per track a sphere at its position and a ``<id> <class> p=<p_drone>`` label
    (`` locked`` after it on the locked one), marker id = track id."""
    with (run_folder / "frames.csv").open() as fh:
        times = [row["t"] for row in csv.DictReader(fh)]
    with (run_folder / "tracks.csv").open() as fh:
        tracks = list(csv.DictReader(fh))
    assert len(messages) == len(times)
    assert len(tracks) > 0  # there is something to compare
    for t, msg in zip(times, messages, strict=True):
        rows = [row for row in tracks if row["t"] == t]
        assert all(m.header.frame_id == "world" for m in msg.markers)
        spheres = {m.id: m for m in msg.markers if m.ns == "tracks" and m.action == 0}
        labels = {m.id: m.text for m in msg.markers if m.ns == "track_labels" and m.action == 0}
        assert sorted(spheres) == sorted(labels) == sorted(int(row["id"]) for row in rows)
        for row in rows:
            p = spheres[int(row["id"])].pose.position
            assert [p.x, p.y, p.z] == pytest.approx([float(row[k]) for k in "xyz"], abs=1e-5)
            label = f"{row['id']} {row['class']} p={float(row['p_drone']):.2f}"
            assert labels[int(row["id"])] == label + (" locked" if row["locked"] == "1" else "")
