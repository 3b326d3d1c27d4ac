"""A world with one drone draws exactly what it drew before a world could hold several.

The digests below were taken from the simulator as it was before ``[[targets]]``
existed (commit 47b7a74, one target cast by itself, birds against it by a two-way
rule): the frames of ``default`` (no clutter) and of ``outdoor-clutter`` (birds, two
of them crossing the line of sight, sharing frames with the drone), with the turret
on the true target.  Values are rounded (points to 0.1 mm, intensities to 0.001)
before hashing, so a last-bit difference of another CPU's floating point does not
matter; a changed random draw, detection or point does.
"""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from dronetrack.config.scenarios import SCENARIOS
from dronetrack.control.aiming import aim_angles
from dronetrack.sim.build import build_world
from dronetrack.types import TurretCommand

# scenario → (frames, SHA-256 of the rounded frames), from commit 47b7a74
BEFORE = {
    "default": (300, "37b9bbb04f23154b79d0089ba4441f56e104b79e5a1f51fa8913140fa80ca939"),
    "outdoor-clutter": (140, "acbb4da6eb39d43ac049071893907aa8a7a43da23fc97e4f9b1f269cbb467b91"),
}


def frames_digest(name: str, n_frames: int) -> str:
    """SHA-256 of a scenario's first frames (seed as given), the turret on the truth."""
    world = build_world(SCENARIOS[name])
    digest = hashlib.sha256()
    for _ in range(n_frames):
        pan, tilt = aim_angles(world.target_position(world.time), world.mount)
        world.command(TurretCommand(world.time, pan, tilt))
        frame, truth = world.step()
        parts = [
            np.round(frame.points * 1e4).astype(np.int64),
            np.round(frame.t * 1e9).astype(np.int64),
            frame.line.astype(np.int64),
            np.round(frame.intensity.astype(np.float64) * 1e3).astype(np.int64),
            truth.hit_target.astype(np.int64),
            np.round(frame.poses * 1e6).astype(np.int64),
        ]
        if truth.clutter is not None and truth.bird_positions is not None:
            parts += [truth.clutter.astype(np.int64), np.round(truth.bird_positions * 1e4)]
        for part in parts:
            digest.update(np.ascontiguousarray(part, dtype=np.int64).tobytes())
    return digest.hexdigest()


@pytest.mark.parametrize("name", list(BEFORE))
@pytest.mark.slow
def test_a_scenario_without_other_drones_gives_the_frames_it_gave_before(name: str) -> None:
    n_frames, before = BEFORE[name]
    assert frames_digest(name, n_frames) == before
