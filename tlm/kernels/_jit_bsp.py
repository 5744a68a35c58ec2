"""The per-element passes of one level of Algorithm 1, compiled with numba.

:func:`tlm.kernels.bsp._build`'s numpy passes over the element buffer ``P`` (the
centre-of-mass sums, then the stable left/right storage into ``P'``), written as loops:

* :func:`level_sums` adds the elements' masses per node in buffer order, as
  ``np.bincount(label, weights=c)`` does (one float64 addition per element, in order),
  so the sums, and the splits computed from them, are bit-identical;
* :func:`level_partition` writes each node's left elements, then its right ones, in
  buffer order, which is what the numpy path's concatenation and stable sort by child
  label produce (``P`` is sorted by node).

The splits themselves (``s`` from the sums, clamped to the node) stay in numpy: they
are per node, not per element. Compiled ``nogil``: the photon maps' trees are built on
threads at once (:func:`tlm.kernels.photons.trace_photons`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from tlm.kernels._jit import _mn, _mx


@njit(cache=True, error_model="numpy", nogil=True)
def level_sums(items, label, lo_col, hi_col, nlo, nhi, nodes, points):
    """Elements and summed masses per node: ``bincount(label)``, ``bincount(label, c)``."""
    counts = np.zeros(nodes, dtype=np.int64)
    sums = np.zeros(nodes)
    for i in range(items.shape[0]):
        lab = label[i]
        x = lo_col[items[i]]
        if points:
            c = x
        else:
            a = nlo[lab]
            b = nhi[lab]
            y = hi_col[items[i]]
            c = 0.5 * (_mx(x, a) + _mn(y, b))  # the node-clipped box's centre
        counts[lab] += 1
        sums[lab] += c
    return counts, sums


@njit(cache=True, error_model="numpy", nogil=True)
def level_partition(items, label, lo_col, hi_col, s, nodes, points, capacity):
    """``P'``: every node's left elements (``x_lo < s``), then its right ones
    (``x_hi >= s``; for points the others), in buffer order.

    Returns ``n_out`` and, when it fits in ``capacity``, the new items and labels
    (``2 l`` left, ``2 l + 1`` right) and the per-node left and right counts; when it
    does not, empty arrays (the caller stops the tree a level early).
    """
    n = items.shape[0]
    n_left = np.zeros(nodes, dtype=np.int64)
    n_right = np.zeros(nodes, dtype=np.int64)
    side = np.empty(n, dtype=np.uint8)  # bit 0: goes left, bit 1: goes right
    for i in range(n):
        lab = label[i]
        left = lo_col[items[i]] < s[lab]
        right = (not left) if points else hi_col[items[i]] >= s[lab]
        side[i] = (1 if left else 0) | (2 if right else 0)
        if left:
            n_left[lab] += 1
        if right:
            n_right[lab] += 1
    n_out = 0
    for lab in range(nodes):
        n_out += n_left[lab] + n_right[lab]
    if n_out > capacity:
        return n_out, np.empty(0, np.int64), np.empty(0, np.int64), n_left, n_right
    put_left = np.empty(nodes, dtype=np.int64)
    put_right = np.empty(nodes, dtype=np.int64)
    at = 0
    for lab in range(nodes):
        put_left[lab] = at
        put_right[lab] = at + n_left[lab]
        at += n_left[lab] + n_right[lab]
    new_items = np.empty(n_out, dtype=np.int64)
    new_label = np.empty(n_out, dtype=np.int64)
    for i in range(n):
        lab = label[i]
        if side[i] & 1:
            new_items[put_left[lab]] = items[i]
            new_label[put_left[lab]] = 2 * lab
            put_left[lab] += 1
        if side[i] & 2:
            new_items[put_right[lab]] = items[i]
            new_label[put_right[lab]] = 2 * lab + 1
            put_right[lab] += 1
    return n_out, new_items, new_label, n_left, n_right
