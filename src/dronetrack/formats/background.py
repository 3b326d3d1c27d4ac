"""A background model's file (``background.npz``): its lookup cells and settings,
as numpy arrays, so a site is scanned once; and, when the map kept learning online,
the voxels it learnt (``learnt``, at ``learnt_resolution``), so a site learns on."""

from __future__ import annotations

import zipfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from dronetrack.errors import InputError

__all__ = [
    "BackgroundSettings",
    "load_background",
    "load_background_and_learnt",
    "load_learnt",
    "read_background_settings",
    "save_background",
]

FORMAT = "dronetrack-background-1"
IntArray = NDArray[np.int64]


@dataclass(frozen=True, slots=True)
class BackgroundSettings:
    """How a saved model was built: voxel size [m], inflation and lookup depth
    [levels], the returns a voxel needed and the neighbours hit it needed."""

    resolution: float
    inflate: int
    lookup_depth: int
    min_hits: int
    min_neighbours: int = 0  # files written before the setting existed: none needed


def save_background(
    path: Path,
    cells: IntArray,
    settings: BackgroundSettings,
    learnt: IntArray | None = None,
    learnt_resolution: float | None = None,
) -> None:
    """Write a built model's lookup-cell keys and settings as a compressed ``.npz``, and
    the voxel keys a learning map holds, with their voxel size [m], if given."""
    path.parent.mkdir(parents=True, exist_ok=True)
    members: dict[str, Any] = {}
    if learnt is not None:
        if learnt_resolution is None or not learnt_resolution > 0:
            raise InputError("a learnt map needs its voxel size")
        members["learnt"] = np.asarray(learnt, dtype=np.int64)
        members["learnt_resolution"] = np.float64(learnt_resolution)
    np.savez_compressed(
        path,
        **members,
        format=np.array(FORMAT),
        cells=np.asarray(cells, dtype=np.int64),
        resolution=np.float64(settings.resolution),
        inflate=np.int64(settings.inflate),
        lookup_depth=np.int64(settings.lookup_depth),
        min_hits=np.int64(settings.min_hits),
        min_neighbours=np.int64(settings.min_neighbours),
    )


_MEMBERS = ("format", "cells", "resolution", "inflate", "lookup_depth", "min_hits")
_HINT = "give the background.npz that a dronetrack run wrote"


def _read(
    path: Path, cells: bool, learnt: bool = False
) -> tuple[BackgroundSettings, IntArray | None, tuple[float, IntArray] | None]:
    """The settings of a model written by ``save_background``, its cells if asked, and
    its learnt voxels if asked and held (the npz members load lazily, so settings alone
    skip the cells)."""
    if not path.is_file():
        raise InputError(f"background file not found: {path}")
    try:
        # The file is opened here, so it is closed even when numpy cannot read it.
        with path.open("rb") as fh:
            if fh.read(4) != b"PK\x03\x04":  # an .npz is a zip archive
                raise InputError(f"{path} is not a background model (not an .npz archive); {_HINT}")
            fh.seek(0)
            with np.load(fh, allow_pickle=False) as data:
                missing = [name for name in _MEMBERS if name not in data.files]
                if missing:
                    raise InputError(
                        f"{path} is not a dronetrack background model (it has no "
                        f"{', '.join(missing)}); {_HINT}"
                    )
                if str(data["format"]) != FORMAT:
                    raise InputError(
                        f"{path} is a background model of another format "
                        f"({str(data['format'])!r}, not {FORMAT!r}); {_HINT}"
                    )
                settings = BackgroundSettings(
                    float(data["resolution"]),
                    int(data["inflate"]),
                    int(data["lookup_depth"]),
                    int(data["min_hits"]),
                    int(data["min_neighbours"]) if "min_neighbours" in data.files else 0,
                )
                held = None
                if learnt and "learnt" in data.files:
                    held = (float(data["learnt_resolution"]), data["learnt"])
                return settings, (data["cells"] if cells else None), held
    except ValueError as err:
        if "pickle" in str(err):  # object arrays, which are never loaded
            raise InputError(
                f"{path} holds Python objects, not a background model; {_HINT}"
            ) from None
        raise InputError(f"cannot read background model {path}: {err}") from None
    except (OSError, zipfile.BadZipFile, EOFError) as err:
        raise InputError(f"cannot read background model {path} (damaged?): {err}") from None


def read_background_settings(path: Path) -> BackgroundSettings:
    """The settings of a saved model, without reading its cells."""
    return _read(path, cells=False)[0]


def load_background(path: Path) -> tuple[BackgroundSettings, IntArray]:
    """The settings and lookup-cell keys of a model written by ``save_background``."""
    settings, keys, _ = _read(path, cells=True)
    assert keys is not None
    return settings, keys


def load_background_and_learnt(
    path: Path,
) -> tuple[BackgroundSettings, IntArray, tuple[float, IntArray] | None]:
    """``load_background`` and ``load_learnt`` of one file in one read."""
    settings, keys, held = _read(path, cells=True, learnt=True)
    assert keys is not None
    return settings, keys, held


def load_learnt(path: Path) -> tuple[float, IntArray] | None:
    """The voxel size [m] and keys of what a learning map held when the model was saved;
    None for a model without (a scan's only, or written before maps learnt)."""
    return _read(path, cells=False, learnt=True)[2]
