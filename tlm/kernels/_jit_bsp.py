"""The per-element passes of one level of Algorithm 1, compiled with numba.

:func:`tlm.kernels.bsp._build`'s numpy passes over the element buffer ``P`` (the
centre-of-mass sums, then the stable left/right storage into ``P'``), written as loops:

* :func:`level_sums` adds the elements' masses per node in buffer order, as
  ``np.bincount(label, weights=c)`` does (one float64 addition per element, in order),
  so the sums, and the splits computed from them, are bit-identical;
* :func:`level_sides` and :func:`level_write` store each node's left elements, then its
  right ones, in buffer order, which is what the numpy path's concatenation and stable
  sort by child label produce (``P`` is sorted by node).

Each pass runs over a range of the buffer that holds whole nodes, and touches only those
nodes' sums, counts and output places: :func:`tlm.kernels.bsp._build` cuts a level into
such groups, one per thread, and runs them at once (every node's elements are still
summed and stored in buffer order by one thread: the same tree at every thread count).

The splits themselves (``s`` from the sums, clamped to the node) stay in numpy: they
are per node, not per element. Compiled ``nogil``: the photon maps' trees are built on
threads at once (:func:`tlm.kernels.photons.trace_photons`), and one tree's level on
several.
"""

from __future__ import annotations

from tlm.kernels._jit_leaf import _mn, _mx
from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)


@njit(cache=True, error_model="numpy", nogil=True)
def level_sums(items, label, lo_col, hi_col, nlo, nhi, lo, hi, counts, sums, points):
    """Pass 1 over the elements ``lo .. hi - 1`` (whole nodes): elements and summed
    masses per node into ``counts`` and ``sums``, as ``bincount(label)`` and
    ``bincount(label, c)`` (one addition per element, in buffer order)."""
    for i in range(lo, hi):
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


@njit(cache=True, error_model="numpy", nogil=True)
def level_sides(items, label, lo_col, hi_col, s, lo, hi, side, n_left, n_right, points):
    """Pass 2 over the elements ``lo .. hi - 1`` (whole nodes): each one's side (bit 0:
    left, ``x_lo < s``; bit 1: right, ``x_hi >= s``, for points not left) into ``side``,
    counted per node into ``n_left`` and ``n_right``."""
    for i in range(lo, hi):
        lab = label[i]
        left = lo_col[items[i]] < s[lab]
        right = (not left) if points else hi_col[items[i]] >= s[lab]
        side[i] = (1 if left else 0) | (2 if right else 0)
        if left:
            n_left[lab] += 1
        if right:
            n_right[lab] += 1


@njit(cache=True, error_model="numpy", nogil=True)
def level_write(items, label, side, lo, hi, put_left, put_right, new_items, new_label):
    """Pass 3 over the elements ``lo .. hi - 1`` (whole nodes): each node's left
    elements from ``put_left[node]`` on, then its right ones from ``put_right[node]``,
    in buffer order (the ``put_*`` of the group's own nodes advance)."""
    for i in range(lo, hi):
        lab = label[i]
        if side[i] & 1:
            new_items[put_left[lab]] = items[i]
            new_label[put_left[lab]] = 2 * lab
            put_left[lab] += 1
        if side[i] & 2:
            new_items[put_right[lab]] = items[i]
            new_label[put_right[lab]] = 2 * lab + 1
            put_right[lab] += 1
