"""Process-level tuning for image work, applied by the command line and the benchmark.

glibc serves allocations above 128 KiB with fresh ``mmap`` pages and returns them on ``free``: every
640x480 float32 temporary (1.2 MB) then costs ~300 page faults, and paper mode spent more time
faulting pages than computing (15-22 ms per image instead of 6). Raising the mmap and trim thresholds
keeps those blocks in the heap for reuse. Linux/glibc only; elsewhere this does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import logging

log = logging.getLogger(__name__)

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_done = False


def tune_allocator(mmap_threshold: int = 32 * 1024 * 1024, trim_threshold: int = 256 * 1024 * 1024) -> bool:
    """Keep large image buffers in the heap (glibc ``mallopt``); True when applied."""
    global _done
    if _done:
        return True
    name = ctypes.util.find_library("c")
    if name is None:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    ok = bool(mallopt(_M_MMAP_THRESHOLD, mmap_threshold)) and bool(mallopt(_M_TRIM_THRESHOLD, trim_threshold))
    log.debug("allocator tuned for image buffers: %s", ok)
    _done = ok
    return ok
