"""Shared fixtures and test settings."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from typing import Any

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


@pytest.fixture
def keep_figures(monkeypatch: pytest.MonkeyPatch) -> Iterator[Callable[[], Any]]:
    """The plot functions close their figure after saving it; keep it open to inspect:
    ``keep_figures()`` is the last figure drawn."""
    import matplotlib.pyplot as plt  # after MPLBACKEND is set above

    monkeypatch.setattr(plt, "close", lambda *_args, **_kw: None)
    plt.close("all")

    def last() -> Any:
        fig = plt.figure(plt.get_fignums()[-1])
        fig.canvas.draw()
        return fig

    yield last
    monkeypatch.undo()
    plt.close("all")
