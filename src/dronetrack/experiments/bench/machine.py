"""The machine a benchmark runs on, and its thread pools.

``machine_info`` records what bench.json's figures depend on: the CPU, the core
count, the Python, numpy and numba versions and the thread counts in force.
``single_thread`` pins numba's thread pool and every loaded BLAS/OpenMP pool
(through threadpoolctl) to one thread for the caller, so that every figure is a
one-core figure whatever the machine; ``thread_counts`` shows that it did.
Nothing here changes process-wide settings unasked: ``single_thread`` sets the
thread counts for the caller's block and restores them after.
"""

from __future__ import annotations

import os
import platform
from collections.abc import Iterator
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


def thread_counts() -> dict[str, Any]:
    """The thread counts in force: numba's, and each loaded BLAS/OpenMP pool's."""
    import numba
    from threadpoolctl import threadpool_info

    return {
        "numba": int(numba.get_num_threads()),
        "blas": [
            {"api": pool["internal_api"], "threads": int(pool["num_threads"])}
            for pool in threadpool_info()
        ],
    }


@contextmanager
def single_thread() -> Iterator[None]:
    """Run the block with numba and every loaded BLAS/OpenMP pool on one thread; restore
    them after.

    The native pools are limited with threadpoolctl.  The
    OMP/OPENBLAS/MKL/NUMBA_NUM_THREADS environment variables act only on libraries
    loaded after they are set: a caller that can set them before numpy and numba
    load should do so as well (the benchmark scripts and ``dronetrack bench`` do).
    """
    import numba
    from threadpoolctl import threadpool_limits

    numba_before = int(numba.get_num_threads())
    numba.set_num_threads(1)
    try:
        with threadpool_limits(limits=1):
            yield
    finally:
        numba.set_num_threads(numba_before)


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
