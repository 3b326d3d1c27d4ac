"""The machine a benchmark runs on, and its thread pools.

``machine_info`` records what bench.json's figures depend on: the CPU, the core
count, the Python, numpy and numba versions and the thread counts in force.
``single_thread`` pins numba's and every loaded OpenBLAS's thread pool to one
thread for the caller, so that every figure is a one-core figure whatever the
machine; ``thread_counts`` shows that it did.  Nothing here changes process-wide
settings unasked: ``single_thread`` sets the thread counts for the caller's block
and restores them after.
"""

from __future__ import annotations

import ctypes
import os
import platform
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["cpu_model", "machine_info", "single_thread", "thread_counts"]


def cpu_model() -> str:
    """The CPU's model name from /proc/cpuinfo, else what ``platform`` knows."""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine() or "unknown"


def _blas_libraries() -> list[ctypes.CDLL]:
    """The OpenBLAS libraries loaded in this process (numpy's and scipy's), Linux only."""
    try:
        maps = Path("/proc/self/maps").read_text()
    except OSError:
        return []
    paths = sorted(
        {
            line.split()[-1]
            for line in maps.splitlines()
            if "openblas" in line.lower() and line.split()[-1].startswith("/")
        }
    )
    libraries = []
    for path in paths:
        try:
            libraries.append(ctypes.CDLL(path))
        except OSError:
            continue
    return libraries


# (get, set) names of OpenBLAS's thread count: upstream, scipy-openblas 32 and 64-bit ints.
_BLAS_FUNCTIONS = (
    ("openblas_get_num_threads", "openblas_set_num_threads"),
    ("scipy_openblas_get_num_threads", "scipy_openblas_set_num_threads"),
    ("scipy_openblas_get_num_threads64_", "scipy_openblas_set_num_threads64_"),
)


def _blas_controls() -> list[tuple[Callable[[], int], Callable[[int], None]]]:
    """(get, set) of every loaded OpenBLAS's thread count."""
    controls: list[tuple[Callable[[], int], Callable[[int], None]]] = []
    for lib in _blas_libraries():
        for get_name, set_name in _BLAS_FUNCTIONS:
            getter = getattr(lib, get_name, None)
            setter = getattr(lib, set_name, None)
            if getter is not None and setter is not None:
                getter.restype = ctypes.c_int
                getter.argtypes = []
                setter.restype = None
                setter.argtypes = [ctypes.c_int]
                controls.append((getter, setter))
                break
    return controls


def thread_counts() -> dict[str, Any]:
    """The thread counts in force: numba's, and each loaded OpenBLAS's."""
    import numba

    return {
        "numba": int(numba.get_num_threads()),
        "openblas": [int(get()) for get, _ in _blas_controls()],
    }


@contextmanager
def single_thread() -> Iterator[None]:
    """Run the block with numba and every loaded OpenBLAS on one thread; restore after.

    OpenBLAS is found among the process's mapped libraries and set through its
    ``openblas_set_num_threads`` (numpy's and scipy's builds rename it).  The
    OMP/OPENBLAS/MKL/NUMBA_NUM_THREADS environment variables act only on libraries
    loaded after they are set: a caller that can set them before numpy and numba
    load should do so as well (the benchmark scripts and ``dronetrack bench`` do).
    """
    import numba

    numba_before = int(numba.get_num_threads())
    blas = [(setter, int(getter())) for getter, setter in _blas_controls()]
    numba.set_num_threads(1)
    for setter, _ in blas:
        setter(1)
    try:
        yield
    finally:
        numba.set_num_threads(numba_before)
        for setter, before in blas:
            setter(before)


def machine_info() -> dict[str, Any]:
    """CPU, core count, Python and numpy versions, the platform and the thread counts."""
    import numba

    return {
        "cpu": cpu_model(),
        "cores": os.cpu_count() or 1,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "platform": platform.platform(),
        "threads": thread_counts(),
    }
