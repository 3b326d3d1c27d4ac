"""A site's background model to and from its file (``formats/background.py``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dronetrack.formats.background import (
    BackgroundSettings,
    load_background,
    load_learnt,
    save_background,
)
from dronetrack.preprocess.background import VoxelBackground
from dronetrack.preprocess.learning import LearningBackground
from dronetrack.preprocess.voxel import key_centres, unique_keys, voxel_keys

__all__ = ["load_model", "resume_learning", "save_model"]


def save_model(
    model: VoxelBackground | None, path: Path, learning: LearningBackground | None = None
) -> None:
    """Write a built model, and what a learning map holds, as ``background.npz`` (a map
    that only learnt is saved with no scanned cells)."""
    learnt = learning.learnt_keys() if learning is not None else None
    if model is not None:
        m = model
        settings = BackgroundSettings(
            m.resolution, m.inflate, m.lookup_depth, m.min_hits, m.min_neighbours
        )
        cells = model.cells.keys
    else:
        if learning is None:
            raise ValueError("save_model needs a model or a learning map")
        s = learning.settings
        settings = BackgroundSettings(s.resolution, s.inflate, 0, 1, 0)
        cells = np.empty(0, dtype=np.int64)
    resolution = learning.settings.resolution if learning is not None else None
    save_background(path, cells, settings, learnt, resolution)


def load_model(path: Path) -> VoxelBackground:
    """The model ``save_model`` wrote, ready for lookups."""
    s, cells = load_background(path)
    return VoxelBackground.from_cells(
        cells, s.resolution, s.inflate, s.lookup_depth, s.min_hits, s.min_neighbours
    )


def resume_learning(path: Path, learning: LearningBackground) -> int:
    """Start ``learning`` from the voxels the saved map had learnt (their centres taken
    to its voxel size); the number of voxels it starts with."""
    held = load_learnt(path)
    if held is None:
        return 0
    resolution, keys = held
    size = learning.settings.resolution
    if len(keys) and resolution != size:
        keys = unique_keys(voxel_keys(key_centres(keys, resolution), size))
    learning.seed(keys)
    return len(learning)
