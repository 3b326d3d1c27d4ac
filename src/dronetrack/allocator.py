"""Keep large temporary arrays in the heap between frames (glibc only).

glibc serves every allocation above 128 kB with a fresh mmap and returns it to
the kernel on free, so a 24,000-point frame's arrays page-fault all over again
on every frame; on a virtual machine that can cost more than the arithmetic.
Raising the mmap and trim thresholds lets freed blocks be reused.  The command
line and the benchmarks call ``tune_allocator`` once at start-up; the library
itself never changes process-wide settings.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

__all__ = ["tune_allocator"]

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3


def tune_allocator(mmap_threshold: int = 256 << 20, trim_threshold: int = 512 << 20) -> bool:
    """Apply the thresholds with mallopt; False where there is no glibc."""
    if not sys.platform.startswith("linux"):
        return False
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    ok = int(mallopt(_M_MMAP_THRESHOLD, mmap_threshold)) == 1
    return ok and int(mallopt(_M_TRIM_THRESHOLD, trim_threshold)) == 1
