"""The tracker interface stands alone: the pipeline and the controllers that drive a
Tracker and read its TrackEstimate load no tracker implementation (the pipeline only
the filters' clock)."""

from __future__ import annotations

import ast
import subprocess
import sys

import pytest

DRIVERS = [
    "dronetrack.track.base",
    "dronetrack.pipeline",
    "dronetrack.control.controller",
    "dronetrack.control.strategies",
]


@pytest.mark.parametrize("module", DRIVERS)
def test_the_drivers_do_not_load_a_tracker(module: str) -> None:
    code = (
        f"import sys, {module}; "
        "print(sorted(m for m in sys.modules if m.startswith('dronetrack.track.')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    loaded = ast.literal_eval(out.stdout)
    # the interface, and the filters' clock the pipeline keeps for them
    assert set(loaded) <= {"dronetrack.track.base", "dronetrack.track.clock"}, loaded
