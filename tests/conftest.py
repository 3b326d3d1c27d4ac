"""Shared fixtures and test settings."""

from __future__ import annotations

import os

import numpy as np
import pytest
from hypothesis import settings

os.environ.setdefault("MPLBACKEND", "Agg")

# No per-example deadline: the first call of a numba kernel loads or compiles it.
# Derandomised, so every run checks the same examples.
settings.register_profile("dronetrack", deadline=None, derandomize=True, print_blob=True)
settings.load_profile("dronetrack")


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)
