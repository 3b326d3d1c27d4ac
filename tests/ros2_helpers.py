"""Loopback-only DDS for the ROS 2 tests.

Cyclone DDS reads its configuration from ``CYCLONEDDS_URI``: here the loopback
interface only, no multicast, and 127.0.0.1 as the one unicast peer (discovery
probes the participant indices 0-``MAX_INDEX`` there).  Each test takes a domain
id of its own from ``DOMAIN_BASE`` on, with the process id mixed in, so two test
runs on one machine do not hear each other.
"""

from __future__ import annotations

import itertools
import os
from pathlib import Path

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
