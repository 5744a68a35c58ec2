"""The per-ray and per-photon random numbers (:func:`tlm.kernels.shade.hash_uniform`) compiled
with numba.

A number is the splitmix64 finaliser chained over the seed and the keys, in uint64
arithmetic that wraps (the numpy code's), then its top 53 bits as a float64 in [0, 1).
Integer operations and one exact conversion, so the numbers are the numpy code's, bit
for bit, and ``nogil``: the threads of a render draw them at once. ``TLM_KERNELS=numpy``
runs the numpy code, the reference (tests/test_engines.py compares the two).
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)

# tlm.kernels.shade's constants (not imported: shade imports this module, and the layers'
# import graph has no cycle; tests/test_engines.py compares the numbers)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLD = np.uint64(0x9E3779B97F4A7C15)


@njit(cache=True, nogil=True, inline="always")
def _mix(x):
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


_SCALE = 1.0 / 9007199254740992.0  # 2**-53: a hash's top 53 bits as a float in [0, 1)


@njit(cache=True, nogil=True)
def hash_uniform(seed, keys):
    """``seed`` (uint64), ``keys`` (k, n) int64: n numbers in [0, 1)."""
    k, n = keys.shape
    out = np.empty(n)
    start = _mix(seed + _GOLD)
    for i in range(n):
        h = start
        for j in range(k):
            h = _mix(h ^ (np.uint64(keys[j, i]) * _GOLD))
        out[i] = np.float64(h >> np.uint64(11)) * _SCALE
    return out


@njit(cache=True, nogil=True, inline="always")
def uniform3(start, a, b, c):
    """One number of :func:`hash_uniform` with the three keys ``(a, b, c)``, from ``start``
    (``_mix(seed + _GOLD)``, made once per call by the compiled bounces that use it)."""
    h = _mix(start ^ (np.uint64(a) * _GOLD))
    h = _mix(h ^ (np.uint64(b) * _GOLD))
    h = _mix(h ^ (np.uint64(c) * _GOLD))
    return np.float64(h >> np.uint64(11)) * _SCALE
