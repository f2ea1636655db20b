"""Keep freed NumPy temporaries in the heap instead of returning them to the kernel.

A bounce allocates hundreds of short-lived arrays of 0.1-2 MB. glibc serves blocks of that
size with mmap (or trims them off the heap top when freed), so every new array costs fresh
page faults on first touch, which make element-wise operations on mid-sized arrays several
times slower than on reused memory. Raising glibc's mmap and trim thresholds (mallopt(3)) lets the heap
reuse the memory. Process-wide, idempotent; a no-op where glibc is not the allocator.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import sys

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
MMAP_THRESHOLD = 32 * 1024 * 1024  # glibc's maximum on 64-bit: larger blocks still use mmap
TRIM_THRESHOLD = 512 * 1024 * 1024  # free heap top kept before it is given back

_done = None


def keep_freed_memory() -> bool:
    """Apply the thresholds once; True if glibc accepted them."""
    global _done
    if _done is None:
        _done = False
        if sys.platform.startswith("linux"):
            try:
                libc = ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6")
                _done = bool(libc.mallopt(_M_MMAP_THRESHOLD, MMAP_THRESHOLD)) and \
                    bool(libc.mallopt(_M_TRIM_THRESHOLD, TRIM_THRESHOLD))
            except (OSError, AttributeError):  # musl or another libc: leave it alone
                _done = False
    return _done
