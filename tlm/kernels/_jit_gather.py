"""The fixed-radius photon gather compiled with numba, one query at a time: the fast path of
:func:`tlm.kernels.estimate._fixed_radius` (the disk and m-voxel filters).

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
reads (:func:`tlm.kernels.estimate._charge_leaves`). Their buffer is sized by the caller;
a block that would overflow it returns how many pairs it needed instead, and the caller
runs it again with a larger buffer.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, error_model="numpy", nogil=True)
def fixed_radius(split, levels, leaf_offset, pos, inc, pw, first, size, pts, nrm, q0, q1, radius, slack,
                 cone, span, pair_query, pair_leaf, visits, sums, accepted):
    """Queries ``q0:q1``: fills ``visits`` (m,), ``sums`` (3, m) (the weighted power, not yet
    divided by the filter's area), ``accepted`` (m,) and the pairs; returns the pairs' count
    (more than the buffer holds: nothing is valid, run again with that many). Compiled
    ``nogil``: threads run blocks of queries at once (:mod:`tlm.kernels.threads`)."""
    r2 = radius * radius
    cap = pair_query.shape[0]
    n_pairs = 0
    stack = np.empty(levels + 1, dtype=np.int64)
    for q in range(q0, q1):
        i = q - q0
        px, py, pz = pts[0, q], pts[1, q], pts[2, q]
        nx, ny, nz = nrm[0, q], nrm[1, q], nrm[2, q]
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
                k = node + 1
                while k > 1:
                    k >>= 1
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
                pair_query[n_pairs] = i
                pair_leaf[n_pairs] = leaf
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
        visits[i] = vis
        accepted[i] = acc
        sums[0, i] = total0
        sums[1, i] = total1
        sums[2, i] = total2
    return n_pairs
