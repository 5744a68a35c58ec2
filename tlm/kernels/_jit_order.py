"""Orders for the cache, compiled with numba: Morton codes and a stable radix sort of them.

A kernel that takes its items (gather queries, rays) in one of these orders reads
mostly what the item before it read, still in cache; the items' results are their own
whatever the order, and the caller puts them back in their places, so no result
depends on the order. Used by the photon gather (:func:`tlm.kernels._jit_gather.morton_order`)
and the traversal (:func:`ray_order`, :func:`tlm.kernels.traverse._traverse_jit`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

SPREAD_BITS = 10  # bits a coordinate may have in spread10 (its masks are for 10)


@njit(cache=True, error_model="numpy", inline="always")
def spread10(g):
    """The low 10 bits of ``g`` (uint32) with two zero bits after each: bit ``b`` goes to
    bit ``3 b`` (a Morton code is ``spread10(x) | spread10(y) << 1 | spread10(z) << 2``)."""
    g = (g | (g << np.uint32(16))) & np.uint32(0x030000FF)
    g = (g | (g << np.uint32(8))) & np.uint32(0x0300F00F)
    g = (g | (g << np.uint32(4))) & np.uint32(0x030C30C3)
    return (g | (g << np.uint32(2))) & np.uint32(0x09249249)


@njit(cache=True, error_model="numpy", nogil=True)
def radix_order30(code):
    """The stable order of the codes ``code`` (uint32, each below 2**30): indices from 0,
    equal codes in index order (``np.argsort(code, kind="stable")``), by a radix sort of
    three passes of 10 bits, the lowest first (numba's stable argsort takes about four
    times as long on 16k codes)."""
    m = code.shape[0]
    order = np.arange(m)
    spare = np.empty(m, dtype=np.int64)
    buckets = 1 << SPREAD_BITS
    count = np.empty(buckets + 1, dtype=np.int64)
    for p in range(3):
        shift = np.uint32(SPREAD_BITS * p)
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


@njit(cache=True, error_model="numpy", inline="always")
def _cell(x, lo, scale, cells):
    """The cell of ``x`` among ``cells + 1`` from ``lo`` (clamped; a NaN is cell 0)."""
    f = (x - lo) * scale
    return np.uint32(min(max(f, 0.0), cells)) if f == f else np.uint32(0)


DIRECTION_BITS = 3  # bits per axis of a ray's direction in its key (8 cells from -1 to 1)
ORIGIN_BITS = 7  # bits per axis of its origin (128 cells over the tree's box)


@njit(cache=True, error_model="numpy", nogil=True)
def ray_keys(o, d, lo, hi):
    """Each ray's key (uint32, below 2**30): the Morton code of its unit direction's cell
    (:data:`DIRECTION_BITS` per axis, components from -1 to 1) above that of its origin's
    cell in the box ``lo``-``hi`` (:data:`ORIGIN_BITS` per axis; an origin outside is
    clamped to the box's edge). Rays of one key leave nearby points in nearby directions,
    so they mostly enter the same nodes and leaves; a direction matters more than an
    origin for that (the traversal's order, x lowest). Only an order: a NaN or infinite
    component's cell is 0, as is every cell of an axis whose box is flat or infinite."""
    r = o.shape[0]
    dcells = (1 << DIRECTION_BITS) - 1
    ocells = (1 << ORIGIN_BITS) - 1
    dscale = (dcells + 1) / 2.0
    oscale = np.empty(3)
    for axis in range(3):
        ext = hi[axis] - lo[axis]
        oscale[axis] = (ocells + 1) / ext if ext > 0.0 and ext < np.inf else 0.0
    key = np.empty(r, dtype=np.uint32)
    for i in range(r):
        norm = np.sqrt(d[i, 0] * d[i, 0] + d[i, 1] * d[i, 1] + d[i, 2] * d[i, 2])
        inv = 1.0 / norm if norm > 0.0 and norm < np.inf else 0.0
        kd = np.uint32(0)
        ko = np.uint32(0)
        for axis in range(3):
            kd |= spread10(_cell(d[i, axis] * inv, -1.0, dscale, dcells)) << np.uint32(axis)
            ko |= spread10(_cell(o[i, axis], lo[axis], oscale[axis], ocells)) << np.uint32(axis)
        key[i] = (kd << np.uint32(3 * ORIGIN_BITS)) | ko
    return key


@njit(cache=True, error_model="numpy", nogil=True)
def ray_order(o, d, lo, hi):
    """The rays ``o``, ``d`` (r, 3) in the stable order of their :func:`ray_keys`."""
    return radix_order30(ray_keys(o, d, lo, hi))


@njit(cache=True, error_model="numpy", nogil=True)
def csr_unorder(ids, counts, order):
    """Ray-major lists back in ray order: ``ids`` holds each ray's list, the rays taken in
    ``order`` (the list of ray ``order[k]`` is the ``k``-th, ``counts[k]`` long); returns
    the same lists with ray 0's first, then ray 1's, and so on."""
    r = order.shape[0]
    start = np.empty(r + 1, dtype=np.int64)  # where ray j's list goes
    start[0] = 0
    length = np.empty(r, dtype=np.int64)
    for k in range(r):
        length[order[k]] = counts[k]
    for j in range(r):
        start[j + 1] = start[j] + length[j]
    out = np.empty_like(ids)
    at = 0
    for k in range(r):
        to = start[order[k]]
        for e in range(counts[k]):
            out[to + e] = ids[at + e]
        at += counts[k]
    return out
