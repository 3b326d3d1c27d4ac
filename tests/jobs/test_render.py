"""render's files: the clutter's truth is written only when the scene has clutter."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dronetrack.config.scenarios import SCENARIOS
from dronetrack.jobs.render import render_scenario, write_rendering


def test_frames_npz_holds_the_clutter_truth_only_with_clutter(tmp_path: Path) -> None:
    for name in ("default", "outdoor-clutter"):
        cfg = SCENARIOS[name].model_copy(update={"duration_s": 0.3})
        rendering = render_scenario(cfg)
        write_rendering(rendering, tmp_path / name)
        with np.load(tmp_path / name / "frames.npz") as data:
            if name == "default":
                assert "clutter" not in data
                assert "bird_positions" not in data
                continue
            assert data["clutter"].shape == data["hit_target"].shape
            assert not np.any(data["hit_target"] & (data["clutter"] != 0))
            assert data["bird_positions"].shape == (3, 5, 3)  # frames × birds × xyz
