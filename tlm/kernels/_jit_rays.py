"""Per-ray array passes around the compiled traversal, compiled with numba: what
:func:`tlm.kernels.traverse._prepare` and :func:`tlm.kernels.traverse._traverse_jit` ask
of a packet's rays before :func:`tlm.kernels._jit.trace` runs (the directions' range,
one shared origin, the ignored ids) and of its answers after (the triangle of each hit
slot). Each is one pass over the arrays, without numpy's temporaries, and returns what
the numpy expression it replaces returns (the tests compare them on edge cases).
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)


@njit(cache=True, error_model="numpy", nogil=True)
def direction_checks(d):
    """What :func:`tlm.kernels.traverse._prepare` asks of the directions ``d`` (r, 3)
    float64 (r >= 1), in one pass: ``plain``, every row's largest magnitude below 2**32
    and its sum of three magnitudes, ``(|x| + |y|) + |z|``, at least 2**-30 (numpy's
    ``mag.max() < 2.0**32 and (mag[:, 0] + mag[:, 1] + mag[:, 2]).min() >= 2.0**-30``: a
    NaN anywhere makes it False); and ``tiny``, some magnitude below float64's smallest
    normal (a subnormal or a zero; NaN is not)."""
    bad = 0  # (counts, without branches: the loop vectorizes)
    tiny = 0
    lim = np.finfo(np.float64).tiny
    for i in range(d.shape[0]):
        a, b, c = abs(d[i, 0]), abs(d[i, 1]), abs(d[i, 2])
        ok = (a < 2.0**32) & (b < 2.0**32) & (c < 2.0**32) & ((a + b) + c >= 2.0**-30)
        bad += np.int64(not ok)
        tiny += np.int64((a < lim) | (b < lim) | (c < lim))
    return bad == 0, tiny > 0


@njit(cache=True, error_model="numpy", nogil=True)
def same_rows(o):
    """Whether every row of ``o`` (r, 3) equals the first (``(o == o[:1]).all()``: a NaN
    equals nothing, -0.0 equals 0.0), stopping at the first that does not."""
    for i in range(1, o.shape[0]):
        if not ((o[i, 0] == o[0, 0]) and (o[i, 1] == o[0, 1]) and (o[i, 2] == o[0, 2])):
            return False
    return o.shape[0] == 0 or ((o[0, 0] == o[0, 0]) and (o[0, 1] == o[0, 1]) and (o[0, 2] == o[0, 2]))


@njit(cache=True, error_model="numpy", nogil=True)
def ignore_flags(ignore):
    """What :func:`tlm.kernels.traverse._traverse_jit` asks of the ignored triangle ids
    ``ignore`` (r,) int64, in one pass: ``has``, some id a triangle can have (0 up to
    int32's largest: the kernel compares ids as int32), and ``remap``, some id outside
    that range other than -1 (numpy's ``((ignore < -1) | (ignore > 2**31 - 1)).any()``:
    those become -1, none; -1 already is)."""
    has = 0  # (counts, without branches: the loop vectorizes)
    remap = 0
    top = np.int64(np.iinfo(np.int32).max)
    for i in range(ignore.shape[0]):
        x = ignore[i]
        has += np.int64((x >= 0) & (x <= top))
        remap += np.int64((x < -1) | (x > top))
    return has > 0, remap > 0


@njit(cache=True, error_model="numpy", nogil=True, boundscheck=True)
def triangles_of(slot, ids):
    """The triangle id of each accel slot ``slot`` (r,) int64 (-1: no hit) through
    ``ids`` (m,): numpy's ``np.where(slot >= 0, ids[np.maximum(slot, 0)], -1)``, in one
    pass (``ids`` is not read where no slot is; a slot past its end raises IndexError,
    as numpy's indexing does)."""
    out = np.empty(slot.shape[0], dtype=np.int64)
    for i in range(slot.shape[0]):
        s = slot[i]
        out[i] = ids[s] if s >= 0 else -1
    return out
