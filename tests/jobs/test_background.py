"""A built background model saved and loaded answers every lookup as before."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dronetrack.jobs.background import load_model, save_model
from dronetrack.preprocess.background import VoxelBackground


def test_model_file_round_trip(tmp_path: Path) -> None:
    g = np.random.default_rng(0)
    wall = np.column_stack([np.full(5000, 20.0), g.uniform(-10, 10, 5000), g.uniform(0, 8, 5000)])
    bg = VoxelBackground(resolution=0.5, inflate=1, lookup_depth=1, min_hits=2, min_neighbours=1)
    bg.insert(wall)
    bg.build()
    path = tmp_path / "site.npz"
    save_model(bg, path)
    again = load_model(path)
    kept = (again.resolution, again.inflate, again.lookup_depth, again.min_hits)
    assert (*kept, again.min_neighbours) == (0.5, 1, 1, 2, 1)
    probe = np.random.default_rng(1).uniform([15, -12, -1], [25, 12, 10], (2000, 3))
    hits = bg.is_background(probe)
    assert 0 < hits.sum() < len(probe)  # the probe straddles the wall
    np.testing.assert_array_equal(again.is_background(probe), hits)
