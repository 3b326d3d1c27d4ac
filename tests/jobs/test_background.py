"""A built background model saved and loaded answers every lookup as before."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dronetrack.jobs.background import load_model, load_saved, resume_learning, save_model
from dronetrack.preprocess.background import VoxelBackground
from dronetrack.preprocess.learning import LearningBackground, LearningSettings
from dronetrack.preprocess.voxel import key_centres


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


def _learnt_map(size: float = 1.0) -> LearningBackground:
    """A learning map that has learnt a 2 m box 10 m in front of a static sensor."""
    model = LearningBackground(LearningSettings(min_occupied_s=1.0, resolution=size), 0.1)
    g = np.random.default_rng(3)
    box = g.uniform([10.0, -1.0, -1.0], [12.0, 1.0, 1.0], (400, 3))
    for i in range(40):
        model.observe(0.1 * i, box, box, np.eye(4), box, np.empty((0, 3)), np.empty(0))
    assert len(model) > 0
    return model


def test_a_learnt_map_is_saved_and_learning_resumes_from_it(tmp_path: Path) -> None:
    learnt = _learnt_map()
    path = tmp_path / "site.npz"
    save_model(None, path, learnt)  # learnt only: no scan
    again = LearningBackground(LearningSettings(min_occupied_s=1.0), 0.1)
    assert resume_learning(path, again) == len(learnt)
    np.testing.assert_array_equal(again.learnt_keys(), learnt.learnt_keys())
    probe = np.random.default_rng(4).uniform([8, -3, -3], [14, 3, 3], (2000, 3))
    inside = learnt.is_background(probe)
    assert 0 < inside.sum() < len(probe)
    np.testing.assert_array_equal(again.is_background(probe), inside)
    assert len(load_model(path)) == 0  # no scanned cells
    # Another voxel size takes the learnt voxels' centres.
    fine = LearningBackground(LearningSettings(min_occupied_s=1.0, resolution=0.5), 0.1)
    assert resume_learning(path, fine) == len(learnt)
    assert fine.is_background(key_centres(learnt.learnt_keys(), 1.0)).all()


def test_a_scanned_model_without_learnt_voxels_resumes_nothing(tmp_path: Path) -> None:
    bg = VoxelBackground(resolution=1.0)
    bg.insert(np.array([[20.0, 0.0, 1.0]]))
    bg.build()
    path = tmp_path / "scan.npz"
    save_model(bg, path)
    fresh = LearningBackground(LearningSettings(), 0.1)
    assert resume_learning(path, fresh) == 0
    assert len(fresh) == 0


def test_the_saved_map_read_at_once_is_the_model_and_the_learnt_voxels(tmp_path: Path) -> None:
    learnt = _learnt_map()
    path = tmp_path / "site.npz"
    save_model(None, path, learnt)
    saved = load_saved(path)
    assert len(saved.model) == len(load_model(path)) == 0
    assert saved.learnt is not None
    assert saved.learnt[0] == learnt.settings.resolution
    np.testing.assert_array_equal(saved.learnt[1], learnt.learnt_keys())
