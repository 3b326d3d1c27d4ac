"""Save and load a background model, so a site is scanned once."""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from dronetrack.errors import InputError
from dronetrack.preprocess.background import VoxelBackground

__all__ = ["load_background", "save_background"]

FORMAT = "dronetrack-background-1"


def save_background(model: VoxelBackground, path: Path) -> None:
    """Write a built model as a compressed ``.npz``."""
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(
        path,
        format=np.array(FORMAT),
        cells=model.cells.keys,
        resolution=np.float64(model.resolution),
        inflate=np.int64(model.inflate),
        lookup_depth=np.int64(model.lookup_depth),
        min_hits=np.int64(model.min_hits),
    )


def load_background(path: Path) -> VoxelBackground:
    """Read a model written by ``save_background``."""
    if not path.is_file():
        raise InputError(f"background file not found: {path}")
    try:
        with np.load(path, allow_pickle=False) as data:
            if str(data["format"]) != FORMAT:
                raise InputError(f"{path} is not a dronetrack background model")
            return VoxelBackground.from_cells(
                data["cells"],
                float(data["resolution"]),
                int(data["inflate"]),
                int(data["lookup_depth"]),
                int(data["min_hits"]),
            )
    except (KeyError, ValueError, OSError, zipfile.BadZipFile) as err:
        raise InputError(f"cannot read background model {path}: {err}") from None
