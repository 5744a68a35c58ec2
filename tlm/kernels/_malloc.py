"""Keep freed array memory in the process (glibc), so kernels do not page-fault anew.

The kernels allocate many short-lived arrays of one to a few megabytes per packet. By
default glibc serves each of them with a fresh ``mmap`` and returns it on ``free``, so
every allocation touches new pages (a page fault per 4 KiB), which costs as much as
the arithmetic. Raising the mmap threshold and setting the trim threshold keeps such
blocks in the heap for reuse. This changes nothing but speed; set ``TLM_NO_MALLOPT=1``
to leave the allocator alone.

Every thread allocates from the one (main) arena. By default glibc gives each thread
its own, whose heaps are at most 64 MiB: there a larger array is a fresh ``mmap``
whatever the threshold, so the render's worker threads page-faulted anew where one
thread reused its blocks. On the conference room at 256x256 on two threads, five rounds
alternating the two settings, each render in its own process (2026-11-28, scratch,
``getrusage`` around ``render``): an arena per thread took 142-196k minor page faults
and 1.10-1.69 s of system time a frame, one arena 107-165k and 0.89-1.33 s (one thread,
separate runs: 90-100k and 0.5-0.6 s; 119k and 0.6 s). The setting reaches the threads
whose first allocation comes after :mod:`tlm.kernels` is imported (the render's pools'):
glibc keeps an arena that a thread made before, and hands the arenas out in turn to new
threads, so in a process whose threads allocated before the import (a notebook's, say)
some of them may still map their large arrays afresh.

The trim threshold, the free space at the heap's top kept, is half the mmap threshold
(it was twice): a freed block between the two at the heap's top goes back to the system
at once. The 1M-triangle Refract frame on two threads peaked at 2,003 and 2,009 MiB
with one arena and the old threshold, at 1,915 - 1,998 MiB with this one (five runs),
and at 1,914 and 1,970 MiB with an arena per thread and the old one
(``benchmarks/bench_memory.py --only large``: the peak varies by about 90 MiB from run
to run).

The price is memory the process holds after the arrays are gone: the freed blocks of a
stage (the BSP build's, the photon trace's, the batches') stay resident,
and on a 1M-triangle 1080p frame they were about 1 GiB beside 1.8 GiB of live arrays
(2026-11-28). :func:`trim` gives the freed pages back; the render calls it between
stages (after the BSP build, the photon trace and the timing model), not per batch or
packet, so the kernels and the batches still reuse their blocks.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import os

_M_TRIM_THRESHOLD = -1
_M_MMAP_THRESHOLD = -3
_M_ARENA_MAX = -8
_THRESHOLD = 256 << 20  # arrays up to 256 MiB come from the heap (freed: kept, but a top over half of this)
_M_ARENA_MAX_VALUE = 1  # one arena for every thread (see above)


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
    ok &= mallopt(_M_TRIM_THRESHOLD, _THRESHOLD // 2) == 1
    ok &= mallopt(_M_ARENA_MAX, _M_ARENA_MAX_VALUE) == 1
    return bool(ok)


_LIBC = None


def _libc():
    global _LIBC
    if _LIBC is None:
        name = ctypes.util.find_library("c") if hasattr(ctypes, "CDLL") else None
        try:
            _LIBC = ctypes.CDLL(name) if name else False
        except OSError:
            _LIBC = False
    return _LIBC


def trim() -> bool:
    """Return the whole free pages of every arena to the system (glibc's ``malloc_trim``);
    True when it did. Nothing else changes: no array is touched."""
    if os.environ.get("TLM_NO_MALLOPT"):
        return False
    libc = _libc()
    fn = getattr(libc, "malloc_trim", None) if libc else None
    if fn is None:
        return False
    fn.argtypes = [ctypes.c_size_t]
    return bool(fn(0))


TUNED = tune_allocator()
