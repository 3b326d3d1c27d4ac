"""background.npz: a model's lookup cells and settings, and the errors of bad files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from dronetrack.errors import InputError
from dronetrack.formats.background import (
    BackgroundSettings,
    load_background,
    read_background_settings,
    save_background,
)


def test_cells_and_settings_round_trip(tmp_path: Path) -> None:
    cells = np.random.default_rng(0).integers(-(2**40), 2**40, 500)
    settings = BackgroundSettings(
        resolution=0.25, inflate=2, lookup_depth=1, min_hits=3, min_neighbours=2
    )
    path = tmp_path / "site" / "background.npz"
    save_background(path, cells, settings)
    assert read_background_settings(path) == settings
    again, keys = load_background(path)
    assert again == settings
    np.testing.assert_array_equal(keys, cells)


def test_a_file_from_before_min_neighbours_reads_as_none_needed(tmp_path: Path) -> None:
    path = tmp_path / "old.npz"
    np.savez(
        path,
        format=np.array("dronetrack-background-1"),
        cells=np.arange(4, dtype=np.int64),
        resolution=np.float64(1.0),
        inflate=np.int64(1),
        lookup_depth=np.int64(2),
        min_hits=np.int64(1),
    )
    assert read_background_settings(path) == BackgroundSettings(1.0, 1, 2, 1, 0)


def test_bad_background_files(tmp_path: Path) -> None:
    with pytest.raises(InputError, match="not found"):
        load_background(tmp_path / "none.npz")
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(InputError, match=r"not a background model \(not an \.npz archive\)"):
        load_background(junk)
    other = tmp_path / "other.npz"
    np.savez(other, cells=np.zeros(3, dtype=np.int64))
    with pytest.raises(InputError, match="has no format, resolution"):
        read_background_settings(other)
    foreign = tmp_path / "foreign.npz"
    np.savez(
        foreign,
        format=np.array("someone-else-1"),
        cells=np.zeros(1, dtype=np.int64),
        resolution=1.0,
        inflate=0,
        lookup_depth=0,
        min_hits=1,
    )
    with pytest.raises(InputError, match="another format"):
        load_background(foreign)
    objects = tmp_path / "objects.npz"
    np.savez(
        objects,
        format=np.array("dronetrack-background-1"),
        cells=np.array([{"a": 1}], dtype=object),
        resolution=1.0,
        inflate=0,
        lookup_depth=0,
        min_hits=1,
    )
    with pytest.raises(InputError, match="holds Python objects"):
        load_background(objects)
