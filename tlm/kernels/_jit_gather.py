"""The fixed-radius photon gather compiled with numba, one query at a time: the fast path of
:func:`tlm.kernels.estimate._fixed_radius` (the disk and m-voxel filters).

The queries of a call are gathered in Morton order (:func:`morton_order`), so the nodes and
photons one query reads are mostly in cache from its predecessor; each query's results
are its own whatever the order, and go back to their places, the pairs in query order.

For each query the photon BSP is walked depth first, left child before right, which
reaches the leaves in the order of Fig. 8's level-by-level node lists (each level's list
keeps a node's left child before its right one) and enters the same inner nodes; then
every photon of every leaf on the list is tested against the radius. Every floating-point
operation is the numpy version's, in the same order: the squared distance summed x, y,
then z; the cosine ``inc . n`` likewise; each (query, leaf) pair's weighted powers summed
in slot order from 0, then the pairs' sums in list order from 0 (what ``np.bincount``
does). numba compiles without fast-math, so nothing is reassociated or fused: the
densities and work counts are bit-identical to the numpy path (``TLM_KERNELS=numpy``),
which stays the reference (tests/test_engines.py compares the two).

The (query, leaf) pairs are returned too, in order, for the page misses of the leaves'
reads (:func:`tlm.kernels.estimate.charge_leaves`). Their buffer is sized by the caller;
a block that would overflow it returns how many pairs it needed instead, and the caller
runs it again with a larger buffer.
"""

from __future__ import annotations

import math

import numpy as np

from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)


@njit(cache=True, error_model="numpy", nogil=True)
def fixed_radius(split, levels, leaf_offset, pos, inc, pw, first, size, pts, nrm, q0, q1, radius, slack,
                 cone, span, pair_query, pair_leaf, visits, sums, accepted):
    """Queries ``q0:q1``: fills ``visits`` (m,), ``sums`` (3, m) (the weighted power, not yet
    divided by the filter's area), ``accepted`` (m,) and the pairs; returns the pairs' count
    (more than the buffer holds: nothing is valid, run again with that many). Compiled
    ``nogil``: threads run blocks of queries at once (:mod:`tlm.kernels.threads`).

    The queries are taken in :func:`morton_order`: a query's nodes and photons are mostly
    its predecessor's, still in cache (a final gather's queries, in their own order,
    scatter over the scene, and read their nodes and photons from memory). Each query's
    values are its own, whatever the order, and its pairs are put back in query order."""
    r2 = radius * radius
    cap = pair_query.shape[0]
    m = q1 - q0
    n_pairs = 0
    stack = np.empty(levels + 1, dtype=np.int64)
    order = morton_order(pts, q0, q1)
    # the queries' points and normals in that order (read in one pass), and what each
    # gathers (written back to query order in one pass at the end)
    at = np.empty((6, m))
    for k in range(m):
        q = q0 + order[k]
        at[0, k], at[1, k], at[2, k] = pts[0, q], pts[1, q], pts[2, q]
        at[3, k], at[4, k], at[5, k] = nrm[0, q], nrm[1, q], nrm[2, q]
    got_sums = np.empty((3, m))
    got_counts = np.empty((3, m), dtype=np.int64)  # visits, accepted, pairs
    # (the leaves go to pair_query first, in the order gathered, then to their places)
    for k in range(m):
        before = n_pairs
        px, py, pz = at[0, k], at[1, k], at[2, k]
        nx, ny, nz = at[3, k], at[4, k], at[5, k]
        lo0 = px - (radius + slack * (abs(px) + radius))
        lo1 = py - (radius + slack * (abs(py) + radius))
        lo2 = pz - (radius + slack * (abs(pz) + radius))
        hi0 = px + (radius + slack * (abs(px) + radius))
        hi1 = py + (radius + slack * (abs(py) + radius))
        hi2 = pz + (radius + slack * (abs(pz) + radius))
        total0 = 0.0
        total1 = 0.0
        total2 = 0.0
        acc = 0
        vis = 0
        top = 0
        stack[0] = 0
        depth_of = 0  # (the depth is recomputed from the node index)
        while top >= 0:
            node = stack[top]
            top -= 1
            if node < leaf_offset:  # an inner node on the list
                vis += 1
                depth_of = 0
                e = node + 1
                while e > 1:
                    e >>= 1
                    depth_of += 1
                axis = depth_of % 3
                d = split[node]
                if axis == 0:
                    lo, hi = lo0, hi0
                elif axis == 1:
                    lo, hi = lo1, hi1
                else:
                    lo, hi = lo2, hi2
                if d <= hi:  # the right child, searched after the left
                    top += 1
                    stack[top] = 2 * node + 2
                if d > lo:
                    top += 1
                    stack[top] = 2 * node + 1
                continue
            leaf = node - leaf_offset
            if n_pairs < cap:
                pair_query[n_pairs] = leaf
            n_pairs += 1
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            for s in range(first[leaf], first[leaf] + size[leaf]):
                dx = pos[0, s] - px
                dy = pos[1, s] - py
                dz = pos[2, s] - pz
                d2 = dx * dx + dy * dy
                d2 = d2 + dz * dz
                if not (d2 <= r2):
                    continue
                c = inc[0, s] * nx + inc[1, s] * ny + inc[2, s] * nz
                if not (c < 0.0):
                    continue
                acc += 1
                if cone:
                    dist = math.sqrt(d2)
                    w = 1.0 - (dist / span if span > 0.0 else 0.0)
                    s0 += pw[0, s] * w
                    s1 += pw[1, s] * w
                    s2 += pw[2, s] * w
                else:
                    s0 += pw[0, s]
                    s1 += pw[1, s]
                    s2 += pw[2, s]
            total0 += s0
            total1 += s1
            total2 += s2
        got_counts[0, k], got_counts[1, k], got_counts[2, k] = vis, acc, n_pairs - before
        got_sums[0, k], got_sums[1, k], got_sums[2, k] = total0, total1, total2
    for k in range(m):
        i = order[k]
        visits[i], accepted[i] = got_counts[0, k], got_counts[1, k]
        sums[0, i], sums[1, i], sums[2, i] = got_sums[0, k], got_sums[1, k], got_sums[2, k]
    if n_pairs > cap:
        return n_pairs
    # the pairs in query order: query i's from where the queries before it end
    begin = np.empty(m, dtype=np.int64)
    for k in range(m):
        begin[order[k]] = got_counts[2, k]
    n = 0
    for i in range(m):
        c = begin[i]
        begin[i] = n
        n += c
    j = 0
    for k in range(m):
        to = begin[order[k]]
        for _ in range(got_counts[2, k]):
            pair_leaf[to] = pair_query[j]
            to += 1
            j += 1
    for i in range(m):
        for to in range(begin[i], begin[i + 1] if i + 1 < m else n_pairs):
            pair_query[to] = i
    return n_pairs


MORTON_BITS = 10  # bits per axis of the gather's query order (1024^3 cells): fixed, the bit-spreading masks are for 10


@njit(cache=True, error_model="numpy", nogil=True)
def morton_order(pts, q0, q1):
    """The order of the points ``pts[:, q0:q1]`` along a Morton curve over their bounding
    box (:data:`MORTON_BITS` per axis, x lowest; equal codes in index order): indices
    from 0. Only an order, for the cache: a NaN coordinate's cell is 0, and so is every
    cell of an axis with an infinite coordinate or an extent that overflows."""
    m = q1 - q0
    cells = (1 << MORTON_BITS) - 1
    lo = np.empty(3)
    scale = np.empty(3)
    for axis in range(3):
        a = np.inf
        b = -np.inf
        for q in range(q0, q1):
            x = pts[axis, q]
            if x < a:
                a = x
            if x > b:
                b = x
        lo[axis] = a
        scale[axis] = cells / (b - a) if b > a and b - a < np.inf else 0.0
    code = np.zeros(m, dtype=np.uint32)
    for i in range(m):
        c = np.uint32(0)
        for axis in range(3):
            f = (pts[axis, q0 + i] - lo[axis]) * scale[axis]
            g = np.uint32(min(max(f, 0.0), cells)) if f == f else np.uint32(0)
            g = (g | (g << np.uint32(16))) & np.uint32(0x030000FF)
            g = (g | (g << np.uint32(8))) & np.uint32(0x0300F00F)
            g = (g | (g << np.uint32(4))) & np.uint32(0x030C30C3)
            g = (g | (g << np.uint32(2))) & np.uint32(0x09249249)
            c |= g << np.uint32(axis)
        code[i] = c
    # a stable radix sort, MORTON_BITS bits a pass, the lowest first
    order = np.arange(m)
    spare = np.empty(m, dtype=np.int64)
    buckets = 1 << MORTON_BITS
    count = np.empty(buckets + 1, dtype=np.int64)
    for p in range(3):
        shift = np.uint32(MORTON_BITS * p)
        count[:] = 0
        for i in range(m):
            count[((code[order[i]] >> shift) & np.uint32(buckets - 1)) + 1] += 1
        for b in range(buckets):
            count[b + 1] += count[b]
        for i in range(m):
            d = (code[order[i]] >> shift) & np.uint32(buckets - 1)
            spare[count[d]] = order[i]
            count[d] += 1
        order, spare = spare, order
    return order
