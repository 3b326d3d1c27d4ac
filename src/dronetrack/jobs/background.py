"""A site's background model to and from its file (``formats/background.py``)."""

from __future__ import annotations

from pathlib import Path

from dronetrack.formats.background import BackgroundSettings, load_background, save_background
from dronetrack.preprocess.background import VoxelBackground

__all__ = ["load_model", "save_model"]


def save_model(model: VoxelBackground, path: Path) -> None:
    """Write a built model as ``background.npz``."""
    settings = BackgroundSettings(
        model.resolution, model.inflate, model.lookup_depth, model.min_hits, model.min_neighbours
    )
    save_background(path, model.cells.keys, settings)


def load_model(path: Path) -> VoxelBackground:
    """The model ``save_model`` wrote, ready for lookups."""
    s, cells = load_background(path)
    return VoxelBackground.from_cells(
        cells, s.resolution, s.inflate, s.lookup_depth, s.min_hits, s.min_neighbours
    )
