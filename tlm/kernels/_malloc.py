"""Keep freed array memory in the process (glibc), so kernels do not page-fault anew.

The kernels allocate many short-lived arrays of one to a few megabytes per packet. By
default glibc serves each of them with a fresh ``mmap`` and returns it on ``free``, so
every allocation touches new pages (a page fault per 4 KiB), which costs as much as
the arithmetic. Raising the mmap and trim thresholds keeps such blocks in the heap for
reuse. This changes nothing but speed; set ``TLM_NO_MALLOPT=1`` to leave the
allocator alone.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_THRESHOLD = 256 << 20  # arrays up to 256 MiB come from the heap and stay there


def tune_allocator() -> bool:
    """Apply the thresholds once; True when glibc accepted them."""
    if os.environ.get("TLM_NO_MALLOPT") or not hasattr(ctypes, "CDLL"):
        return False
    name = ctypes.util.find_library("c")
    if not name:
        return False
    try:
        libc = ctypes.CDLL(name)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    ok = mallopt(_M_MMAP_THRESHOLD, _THRESHOLD) == 1
    ok &= mallopt(_M_TRIM_THRESHOLD, 2 * _THRESHOLD) == 1
    return bool(ok)


TUNED = tune_allocator()
