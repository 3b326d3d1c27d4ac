"""Keep Python's cyclic garbage collector from stalling a real-time loop.

A full collection walks every container object the process holds.  At the start
of a live run that is the start-up heap (modules, numba's dispatchers, the ROS 2
type store): about 130,000 objects, one full pass ~60 ms on this project's 2-core
reference machine, and several times that inside a long test session.  The
collector starts such a pass on its own, at some allocation mid-run, and every
thread waits for it; a 10 Hz loop with a queue of two frames then drops one.

``frozen_heap`` collects once, then moves every object alive into the collector's
permanent generation (``gc.freeze``, Python ≥ 3.7) for the loop's duration: later
passes walk only what the loop itself allocates.  Objects of the start-up heap
that become garbage during the loop are freed by reference counting as usual;
only cycles among them wait until ``gc.unfreeze`` on the way out.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["frozen_heap"]


@contextmanager
def frozen_heap() -> Iterator[None]:
    """Hide the objects alive now from the cyclic collector until the block ends."""
    gc.collect()
    gc.freeze()
    try:
        yield
    finally:
        gc.unfreeze()
