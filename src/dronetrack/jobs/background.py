"""A site's background model to and from its file (``formats/background.py``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from dronetrack.formats.background import (
    BackgroundSettings,
    IntArray,
    load_background,
    load_background_and_learnt,
    load_learnt,
    save_background,
)
from dronetrack.pipeline.factory import SavedBackground
from dronetrack.preprocess.background import VoxelBackground
from dronetrack.preprocess.learning import LearningBackground

__all__ = ["load_model", "load_saved", "resume_learning", "save_model"]


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


def _model(s: BackgroundSettings, cells: IntArray) -> VoxelBackground:
    return VoxelBackground.from_cells(
        cells, s.resolution, s.inflate, s.lookup_depth, s.min_hits, s.min_neighbours
    )


def load_model(path: Path) -> VoxelBackground:
    """The model ``save_model`` wrote, ready for lookups."""
    return _model(*load_background(path))


def load_saved(path: Path) -> SavedBackground:
    """Everything ``save_model`` wrote, in one read: the model and the voxels a learning
    map held."""
    settings, cells, learnt = load_background_and_learnt(path)
    return SavedBackground(_model(settings, cells), learnt)


def resume_learning(path: Path, learning: LearningBackground) -> int:
    """Start ``learning`` from the voxels the saved map had learnt; the number of voxels
    it starts with."""
    held = load_learnt(path)
    return 0 if held is None else learning.resume(held[1], held[0])
