"""The photon-map glue compiled with numba (``nogil``): what ran as small numpy steps, holding
the interpreter lock, between the compiled gathers of :mod:`tlm.kernels.estimate` and
:mod:`tlm.render.pmap`. Integers only, or the same floating-point formula in the same
order, so every result is bit-identical to the numpy code it replaces (tests/test_gather_glue.py).

* :func:`kth_neighbour_d2`: the density rule's k-th nearest neighbour distances
  (:func:`tlm.kernels.estimate.density_radius`), an exact search of a k-d tree of the map.
* :func:`pair_words`: a gather chunk's per-query leaf and photon counts and the word range
  of each (query, leaf) pair's photon reads (:func:`tlm.kernels.estimate.charge_leaves`).
* :func:`add_per_owner`: ``into += bincount(owner, weights=values)`` for integer counts.
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)

KNN_LEAF = 8  # points a leaf of kth_neighbour_d2's tree holds at the most (but identical points)


@njit(cache=True, error_model="numpy", nogil=True)
def kth_neighbour_d2(pos, at, kk, leaf_size):
    """For each sample ``at[t]`` (a row of ``pos``, (n, 3) float64), the ``kk``-th smallest
    squared distance ``(dx*dx + dy*dy) + dz*dz`` (``d = p - x``, numpy's ``((p - x)**2).sum(1)``)
    to the other rows (every row but ``at[t]`` itself; ``1 <= kk <= n - 1``). Exact: the
    value does not depend on which of several points tied at that distance are taken.

    A k-d tree (tight boxes, split at the middle of the widest side) is searched depth
    first, nearer child first; a node is skipped when the squared distance to its box,
    computed by the same formula from the box's sides, is not below the k-th best so far:
    rounding is monotonic, so no point in the box can be nearer than that bound."""
    n = pos.shape[0]
    s = at.shape[0]
    out = np.empty(s)
    idx = np.arange(n)
    max_nodes = 2 * n
    start = np.zeros(max_nodes, dtype=np.int64)
    stop = np.zeros(max_nodes, dtype=np.int64)
    child = np.full(max_nodes, -1, dtype=np.int64)  # the left child; the right one follows it
    blo = np.empty((max_nodes, 3))
    bhi = np.empty((max_nodes, 3))
    stop[0] = n
    nodes = 1
    i = 0
    while i < nodes:
        a0, a1 = start[i], stop[i]
        for c in range(3):
            lo = np.inf
            hi = -np.inf
            for e in range(a0, a1):
                v = pos[idx[e], c]
                if v < lo:
                    lo = v
                if v > hi:
                    hi = v
            blo[i, c] = lo
            bhi[i, c] = hi
        if a1 - a0 > leaf_size:
            axis = 0
            wide = bhi[i, 0] - blo[i, 0]
            for c in range(1, 3):
                if bhi[i, c] - blo[i, c] > wide:
                    wide = bhi[i, c] - blo[i, c]
                    axis = c
            if wide > 0.0:  # (identical points, or NaN: a leaf)
                cut = 0.5 * blo[i, axis] + 0.5 * bhi[i, axis]
                if not (cut > blo[i, axis]):  # (two adjacent floats: the upper one alone goes right)
                    cut = bhi[i, axis]
                mid = a0  # partition: coordinates below cut first
                for e in range(a0, a1):
                    if pos[idx[e], axis] < cut:
                        t = idx[e]
                        idx[e] = idx[mid]
                        idx[mid] = t
                        mid += 1
                if a0 < mid < a1:
                    child[i] = nodes
                    start[nodes], stop[nodes] = a0, mid
                    start[nodes + 1], stop[nodes + 1] = mid, a1
                    nodes += 2
        i += 1
    pp = np.empty((n, 3))  # the points in the tree's order
    for e in range(n):
        for c in range(3):
            pp[e, c] = pos[idx[e], c]
    heap = np.empty(kk)
    stack = np.empty(max_nodes, dtype=np.int64)
    bound = np.empty(max_nodes)
    for t in range(s):
        q = at[t]
        x0, x1, x2 = pos[q, 0], pos[q, 1], pos[q, 2]
        for h in range(kk):
            heap[h] = np.inf  # a max-heap of the kk smallest so far
        top = 0
        stack[0] = 0
        bound[0] = 0.0
        while top >= 0:
            node = stack[top]
            b = bound[top]
            top -= 1
            if not (b < heap[0]):
                continue
            if child[node] < 0:
                for e in range(start[node], stop[node]):
                    if idx[e] == q:
                        continue
                    dx = pp[e, 0] - x0
                    dy = pp[e, 1] - x1
                    dz = pp[e, 2] - x2
                    d2 = dx * dx + dy * dy
                    d2 = d2 + dz * dz
                    if d2 < heap[0]:
                        heap[0] = d2  # sift down
                        p = 0
                        while True:
                            lc = 2 * p + 1
                            if lc >= kk:
                                break
                            rc = lc + 1
                            big = lc if rc >= kk or heap[lc] >= heap[rc] else rc
                            if heap[big] > heap[p]:
                                tmp = heap[big]
                                heap[big] = heap[p]
                                heap[p] = tmp
                                p = big
                            else:
                                break
                continue
            left = child[node]
            bl = _box_d2(blo, bhi, left, x0, x1, x2)
            br = _box_d2(blo, bhi, left + 1, x0, x1, x2)
            if bl <= br:  # the nearer child is searched first (pushed last)
                stack[top + 1], bound[top + 1] = left + 1, br
                stack[top + 2], bound[top + 2] = left, bl
            else:
                stack[top + 1], bound[top + 1] = left, bl
                stack[top + 2], bound[top + 2] = left + 1, br
            top += 2
        out[t] = heap[0]
    return out


@njit(cache=True, error_model="numpy", nogil=True)
def _side(x, lo, hi):
    """The distance from x to [lo, hi] along one axis (0 inside), rounded as the points' ``p - x``."""
    if x < lo:
        return lo - x
    if x > hi:
        return x - hi
    return 0.0


@njit(cache=True, error_model="numpy", nogil=True)
def _box_d2(blo, bhi, node, x0, x1, x2):
    """The squared distance from x to the box of ``node`` (0 inside), by the points' formula."""
    d0 = _side(x0, blo[node, 0], bhi[node, 0])
    d1 = _side(x1, blo[node, 1], bhi[node, 1])
    d2 = _side(x2, blo[node, 2], bhi[node, 2])
    b = d0 * d0 + d1 * d1
    return b + d2 * d2


@njit(cache=True, error_model="numpy", nogil=True)
def pair_words(pq, leaf, first, size, m, words):
    """(query, leaf) pairs ``pq`` (in ``[0, m)``), ``leaf`` of a gather: each query's leaves
    (``bincount(pq, minlength=m)``) and photons tested (``bincount(pq, weights=size[leaf])``),
    and the pairs' word ranges ``first[leaf] * words`` .. that ``+ size[leaf] * words``."""
    p = pq.shape[0]
    leaves = np.zeros(m, dtype=np.int64)
    tested = np.zeros(m, dtype=np.int64)
    lo = np.empty(p, dtype=np.int64)
    hi = np.empty(p, dtype=np.int64)
    for i in range(p):
        f = leaf[i]
        q = pq[i]
        leaves[q] += 1
        tested[q] += size[f]
        lo[i] = first[f] * words
        hi[i] = lo[i] + size[f] * words
    return leaves, tested, lo, hi


@njit(cache=True, error_model="numpy", nogil=True)
def add_per_owner(into, owner, values):
    """``into[owner[i]] += values[i]`` in order (int64: ``bincount(owner, weights=values)``
    added, exact while the sums stay below 2**53)."""
    for i in range(owner.shape[0]):
        into[owner[i]] += values[i]
