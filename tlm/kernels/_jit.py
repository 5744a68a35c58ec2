"""The traversal compiled with numba, one ray at a time: the fast path of :mod:`traverse`.

This is :func:`tlm.kernels.traverse._traverse` (root clip, leaf list, leaf loop,
float64 check, float64 fallback, work counts, memory touched) written per ray instead
of per block: a ray stops testing where its stopping rule says so (the numpy version
tests a batch of leaves ahead and discards the excess), and no (slot, ray) block is
materialized. Every floating-point operation is the numpy version's, in the same order
and precision: float32 for the block test (:func:`intersect.closest_slots`), float64
for the intervals, the check (:func:`intersect.check`) and the fallback
(:func:`intersect.closest_slots64`); where an operand provably is not NaN, numpy's
NaN-propagating minimum and maximum are the plain ones, one instruction each (the same
values: :func:`_key`, phase 1 in :func:`trace`). numba compiles without fast-math, so nothing is
reassociated or fused into an FMA. Hits, work counts and the memory touched are
therefore bit-identical to the numpy path, which stays the reference
(``TLM_KERNELS=numpy``); tests compare the two and a golden file pins both.

Rejection in the float32 test follows numpy's semantics: a NaN in ``u``, ``v`` or
``t'`` rejects the pair (numpy's ``minimum`` propagates it, and an x86 NaN has its sign
bit set, so ``copysign`` makes the key negative), and ``min(w, t')`` returns ``t'`` on
a tie of signed zeros, as the SIMD minimum does.

Layout: the float32 constants are one (16, m') stack whose every leaf starts on a
multiple of :data:`PAD` slots and is padded with NaN slots (rejected by every test),
so the vectorized slot loop never runs a scalar remainder; ``back`` maps a padded slot
to the accel's slot. Rays of one shared origin (eye rays) test from a second stack
whose ray-independent rows (``T.N``, ``E2 x T``, ``-E1 x T`` for the packet's origin,
:func:`shared_stack`) are computed once per origin (the caller keeps the last one),
with the same operations, so a slot costs
about a third fewer operations and the same bits; the slot loops of the two cases are
separate functions, as one loop holding both formulas evaluates both in every lane.
Each ray's ``1/d`` is divided once for the root clip and every level. Without
``record``, phase 1 walks the tree depth first (the leaves in the order of the level
lists; the lists themselves are formed only to record the nodes level by level). An
any-hit ray (``first_only``, not of a shared origin) runs its leaves through a filter first, one loop over
all their vectors (:func:`_scan`: never false on a leaf with a hit), and tests in
full (:func:`_leaf32`) only a leaf that passes; the first with a hit stops it.
The hot loops are written out in :func:`trace` or in functions that LLVM keeps free
of numba's reference counting (an inlined function's array arguments can cost two
atomic operations per call). Buffers are
sized up front; a ray that would overflow one stops the kernel with a status, and the
caller reruns it with larger buffers (no array is reallocated inside the loops, which
would cost reference counting per ray).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)

PAD = 8  # slots per AVX2 vector of float32
_NO_HIT = np.uint32(0x7F800000)  # float32 +inf
_REJECT = np.uint32(0xFFFFFFFF)
OK, FULL_LEVEL, FULL_LEAVES, FULL_NODES = 0, 1, 2, 3


@dataclass(frozen=True)
class Layout:
    """The compiled kernel's copy of a :class:`~tlm.kernels.traverse.TriangleAccel`."""

    soa32: np.ndarray  # (16, m') float32: v0, -E1, E2, N, -N (x, y, z), triangle id bits
    first: np.ndarray  # (leaves,) int64: a leaf's first padded slot
    last: np.ndarray  # (leaves,) int64: past its last padded slot (a multiple of PAD on)
    back: np.ndarray  # (m',) int64: the accel's slot of a padded slot (-1: padding)
    soa64: np.ndarray  # (9, m) float64: v0, -E1, E2 of the accel's slots (eq. 3.6's inputs)
    ids: np.ndarray  # (m,) int64: triangle id of the accel's slots
    size: np.ndarray  # (leaves,) int64: triangles per leaf (the Intersection PM's work)


def layout(accel) -> Layout:
    """Build the :class:`Layout` of an accel (once per accel: it is cached there).

    The constants are those of :class:`~tlm.kernels.intersect.TriangleSoA` (the same
    operations, per triangle), gathered once into the slots: the float32 rows are the
    float64 ones rounded (as :class:`TriangleSoA` makes its float32 copy), so each is
    computed once, and a triangle's values are the same in every leaf that holds it."""
    tri = np.asarray(accel.triangles, dtype=np.float64).reshape(-1, 3, 3)
    items = np.asarray(accel.tree.items, dtype=np.int64)
    if tri.shape[0] and tri.shape[0] - 1 > np.iinfo(np.int32).max:
        raise ValueError("more than 2**31 triangles")
    n_tri = tri.shape[0]
    # per triangle, as TriangleSoA.from_triangles: v0 (from the origin), -E1, E2, N, -N
    rows = np.empty((15, n_tri))
    e1 = tri[:, 1] - tri[:, 0]
    e2 = tri[:, 2] - tri[:, 0]
    n = np.cross(e1, e2)
    for k, a in enumerate((tri[:, 0] - accel.origin, -e1, e2, n, -n)):
        rows[3 * k : 3 * k + 3] = a.T
    lf, ll = accel.leaf_first, accel.leaf_last
    size = (ll - lf).astype(np.int64)
    padded = (size + PAD - 1) // PAD * PAD
    first = np.zeros(size.shape[0], dtype=np.int64)
    np.cumsum(padded[:-1], out=first[1:])
    m2 = int(padded.sum())
    # where each accel slot goes: its leaf's padded start + its place in the leaf
    leaf_of = np.repeat(np.arange(size.shape[0]), size)
    within = np.arange(leaf_of.shape[0]) - np.repeat(np.cumsum(size) - size, size)
    src = lf[leaf_of].astype(np.int64) + within
    dst = first[leaf_of] + within
    # the triangle of each padded slot; padding reads an extra NaN column (rejected by every test)
    tri_of = np.full(m2, n_tri, dtype=np.int64)
    tri_of[dst] = items[src]
    rows32 = np.empty((16, n_tri + 1), dtype=np.float32)
    rows32[:15, :n_tri] = rows
    rows32[:15, n_tri] = np.nan
    rows32[15, :n_tri] = np.arange(n_tri, dtype=np.int32).view(np.float32)  # the triangle's id bits
    rows32[15, n_tri] = np.array([-2], dtype=np.int32).view(np.float32)[0]  # no triangle's id
    soa32 = np.take(rows32, tri_of, axis=1)
    back = np.full(m2, -1, dtype=np.int64)
    back[dst] = src
    soa64_rows = np.take(rows[:9], items, axis=1)  # (v0, -E1, E2 of the accel's slots: what _exact reads)
    return Layout(soa32, first, first + padded, back, soa64_rows, items.copy(), size)


@njit(cache=True, error_model="numpy", inline="always")
def _mn(a, b):
    """numpy's float minimum: a NaN operand wins (``a`` first), ``b`` on a tie."""
    if a != a:
        return a
    if a < b:
        return a
    return b


@njit(cache=True, error_model="numpy", inline="always")
def _mx(a, b):
    """numpy's float maximum: a NaN operand wins (``a`` first), ``b`` on a tie."""
    if a != a:
        return a
    if a > b:
        return a
    return b


@njit(cache=True, error_model="numpy", inline="always")
def _pick(keys, n, best_hi, s0, tmin, tmax):
    """The end of a leaf's float32 test: ``(slot, t)`` of the lowest key (the lowest
    slot among equal ones), or -1 and inf when nothing is accepted before ``tmax``."""
    if best_hi >= _NO_HIT:  # nothing accepted, or only at t' = inf
        return -1, np.float32(np.inf)
    best = 0
    while keys[best] != best_hi:
        best += 1
    tb = np.uint32(best_hi).view(np.float32) + tmin
    if not tb < tmax:
        return -1, np.float32(np.inf)
    return s0 + best, tb


@njit(cache=True, error_model="numpy", inline="always")
def _dot(ax, ay, az, bx, by, bz):
    """``(ax bx + ay by) + az bz``, in that order (the numpy engine's sums)."""
    out = ax * bx
    out = out + ay * by
    return out + az * bz


@njit(cache=True, error_model="numpy", inline="always")
def _lt_min(a, b):
    """``a if a < b else b``: :func:`_mn` where neither operand is NaN (one instruction
    on x86, whose minimum returns its second operand on a NaN or a tie)."""
    return a if a < b else b


@njit(cache=True, error_model="numpy", inline="always")
def _key(u, v, tp, idbits, ign32, eps, reject=_REJECT):
    """A pair's key from ``u, v`` and ``t' = t - tmin``: the bits of ``t'`` if accepted,
    0xFFFFFFFF if rejected (``w`` NaN or negative, or the ray's ignored triangle), where
    ``w = min(min(1 - (u + v), min(u, v)) + eps, t')`` with :func:`_mn`'s minimum.

    :func:`_mn` propagates a NaN operand, so ``w`` is NaN exactly when ``1 - (u + v)``
    (NaN where ``u`` or ``v`` is) or ``t'`` is, and ``+ eps`` (finite) makes no NaN;
    without a NaN, :func:`_mn` is :func:`_lt_min`. So ``w`` is computed with
    :func:`_lt_min` and the NaN test is one unordered compare of ``1 - (u + v)`` and
    ``t'``: the same key for every input, in fewer vector operations."""
    one = np.float32(1.0)
    w1 = one - (u + v)
    w = _lt_min(w1, _lt_min(u, v))
    w = w + eps
    w = _lt_min(w, tp)
    bad = (w1 != w1) | (tp != tp) | (np.float32(w).view(np.uint32) >= np.uint32(0x80000000)) | (
        np.float32(idbits).view(np.int32) == ign32)
    return reject if bad else np.float32(tp).view(np.uint32)  # tp >= +0: bits order as values


@njit(cache=True, error_model="numpy", inline="always")
def _slot_key(ox, oy, oz, dx, dy, dz, tmin, ign32, soa, s, eps, reject=_REJECT):
    """The key (:func:`_key`) of one ray and the padded slot ``s`` (float32 scalars).

    ``1/det`` is ``-1 / (D.N)`` from the ``N`` rows, where the numpy engine divides
    ``1 / (D.(-N))``: products and sums are symmetric in the sign under
    round-to-nearest, so ``D.(-N)`` is ``-(D.N)`` bit for bit unless it is zero (then
    a sum's zero may keep its sign), and ``1 / -x`` is ``-1 / x``. Where ``D.N`` is a
    zero of either sign, ``1/det`` is an infinity and ``u`` and ``v`` are infinities or
    NaN whatever its sign: ``w`` is NaN or -inf (an infinite ``u + v`` makes ``1 - (u +
    v)`` the opposite one, a -inf ``u`` or ``v`` is the minimum), so the pair is rejected
    either way. The ``-N`` rows are not read (three loads a slot fewer)."""
    t, u, v = _slot_tuv(ox, oy, oz, dx, dy, dz, soa, s)
    return _key(u, v, t - tmin, soa[15, s], ign32, eps, reject)


@njit(cache=True, error_model="numpy", inline="always")
def _slot_tuv(ox, oy, oz, dx, dy, dz, soa, s):
    """``t, u, v`` of one ray and the padded slot ``s`` in float32 (the operations of
    :func:`_slot_key`, which :func:`_scan` repeats: one copy of them)."""
    rdet = np.float32(-1.0) / _dot(dx, dy, dz, soa[9, s], soa[10, s], soa[11, s])
    tx = ox - soa[0, s]
    ty = oy - soa[1, s]
    tz = oz - soa[2, s]
    t = _dot(tx, ty, tz, soa[9, s], soa[10, s], soa[11, s]) * rdet
    cx = ty * dz - tz * dy
    cy = tz * dx - tx * dz
    cz = tx * dy - ty * dx
    u = _dot(cx, cy, cz, soa[6, s], soa[7, s], soa[8, s]) * rdet
    v = _dot(cx, cy, cz, soa[3, s], soa[4, s], soa[5, s]) * rdet
    return t, u, v


@njit(cache=True, error_model="numpy", inline="always")
def _leaf32(ox, oy, oz, dx, dy, dz, tmin, tmax, ign, soa, s0, s1, eps, keys):
    """:func:`closest_slots` for one ray and the padded slots ``s0:s1``: ``(slot, t)``
    (a padded slot; -1 and inf when nothing is hit). Scalars are float32; ``ign`` is a
    triangle id or -1. Among equal distances the lowest slot wins.

    The slot loop is branch-free with unsigned indices, so LLVM vectorizes it (numba
    adds a negative-index wraparound to signed ones, and LLVM then gathers lane by lane).
    ``keys`` (scratch) gets the bits of ``t' = t - tmin`` of an accepted pair and
    0xFFFFFFFF of a rejected one. Rays of a shared origin take :func:`_leaf32_shared`
    (the same values with the ray-independent part computed once): one loop each, as a
    loop holding both formulas computes both in every lane.
    """
    ign32 = np.int32(ign)
    u0 = np.uint64(s0)
    best_hi = _REJECT
    for j in range(np.uint64(s1 - s0)):
        key = _slot_key(ox, oy, oz, dx, dy, dz, tmin, ign32, soa, u0 + j, eps)
        keys[j] = key
        best_hi = min(best_hi, key)
    return _pick(keys, s1 - s0, best_hi, s0, tmin, tmax)


@njit(cache=True, error_model="numpy", inline="always")
def _scan(ox, oy, oz, dx, dy, dz, tmin, tmax, soa, fs, fe, k, n, eps):
    """The any-hit filter: the first of the leaves ``k:n`` (``k < n``; padded slots
    ``fs[j]:fe[j]``, none empty) that may hold an accepted slot of ``t < tmax``, or
    ``n``. One loop over the leaves' vectors of 8 slots, going on to the next
    leaf at a leaf's end (no loop to set up and leave per leaf).

    A slot passes where ``w`` (:func:`_key`, the same operations) has its sign bit clear
    and ``t' + tmin < tmax``: :func:`_key` and :func:`_pick`'s test without the NaN and
    ignored-id tests. A slot whose key is accepted before ``tmax`` passes (its ``w`` is
    this ``w``, and its ``t'`` is not NaN); one that passes with a rejected key is the
    ray's ignored triangle or has a NaN ``1 - (u + v)`` and a number ``t'`` (a zero
    ``D.N``): both rare. So a leaf with a hit is never skipped, and the leaf found is
    tested in full (:func:`_leaf32`), which decides."""
    one = np.float32(1.0)
    sign = np.uint32(0x80000000)
    uk = np.uint64(k)
    un = np.uint64(n)
    s = np.uint64(fs[uk])
    end = np.uint64(fe[uk])
    while True:
        hit = False
        for lane in range(PAD):
            t, u, v = _slot_tuv(ox, oy, oz, dx, dy, dz, soa, s + np.uint64(lane))
            tp = t - tmin
            w = _lt_min(one - (u + v), _lt_min(u, v))
            w = _lt_min(w + eps, tp)
            hit = hit | ((np.float32(w).view(np.uint32) < sign) & (tp + tmin < tmax))
        if hit:
            return np.int64(uk)
        s = s + np.uint64(PAD)
        at_end = s == end
        uk = uk + np.uint64(1 if at_end else 0)
        if uk == un:
            return n
        s0 = np.uint64(fs[uk])
        s1 = np.uint64(fe[uk])
        s = s0 if at_end else s
        end = s1 if at_end else end


# rows of the shared-origin stack (:func:`_shared_rows`)
_S_NN, _S_T, _S_U, _S_V, _S_ID, _S_ROWS = 0, 3, 4, 7, 10, 11


@njit(cache=True, error_model="numpy", inline="always")
def _shared_rows(soa, ox, oy, oz, pre, s0, s1):
    """The ray-independent part of the shared-origin test for the padded slots
    ``s0:s1``, into ``pre``: ``-N``, ``T.N``, ``E2 x T``, ``-E1 x T`` and the id bits
    (``T = o - v0`` for the packet's one float32 origin), each as the per-ray formula
    of the numpy shared-origin path computes it, so the values are the same bits."""
    for s in range(s0, s1):
        tx = ox - soa[0, s]
        ty = oy - soa[1, s]
        tz = oz - soa[2, s]
        t = tx * soa[9, s]
        t = t + ty * soa[10, s]
        pre[_S_T, s] = t + tz * soa[11, s]
        for k, a in ((_S_U, 6), (_S_V, 3)):  # K = A x T of A = E2 (for u), -E1 (for v)
            ax, ay, az = soa[a, s], soa[a + 1, s], soa[a + 2, s]
            pre[k, s] = ay * tz - az * ty
            pre[k + 1, s] = az * tx - ax * tz
            pre[k + 2, s] = ax * ty - ay * tx
        for k in range(3):
            pre[_S_NN + k, s] = soa[12 + k, s]
        pre[_S_ID, s] = soa[15, s]


@njit(cache=True, error_model="numpy", nogil=True)
def shared_stack(soa32, o32):
    """The rows of :func:`_shared_rows` for every padded slot, the packet's float32
    origin ``o32`` (3,): read by every chunk of every packet of that origin."""
    pre = np.empty((_S_ROWS, soa32.shape[1]), dtype=np.float32)
    _shared_rows(soa32, o32[0], o32[1], o32[2], pre, 0, soa32.shape[1])
    return pre


@njit(cache=True, error_model="numpy", inline="always")
def _leaf32_shared(dx, dy, dz, tmin, tmax, ign, pre, s0, s1, eps, keys):
    """:func:`_leaf32` for a ray of the packet's shared origin, from the rows of
    :func:`_shared_rows`: ``u`` and ``v`` are linear forms in ``D``, ``(K.D) / det``
    evaluated as ``(dx kx + dy ky) + dz kz`` (the numpy shared-origin path), and ``T.N``
    is the same for every ray."""
    best_hi = _REJECT
    ign32 = np.int32(ign)
    for j in range(np.uint64(s1 - s0)):  # (unsigned slots, as in _leaf32)
        s = np.uint64(s0) + j
        rdet = np.float32(1.0) / _dot(dx, dy, dz, pre[_S_NN, s], pre[_S_NN + 1, s], pre[_S_NN + 2, s])
        t = pre[_S_T, s] * rdet
        u = _dot(dx, dy, dz, pre[_S_U, s], pre[_S_U + 1, s], pre[_S_U + 2, s]) * rdet
        v = _dot(dx, dy, dz, pre[_S_V, s], pre[_S_V + 1, s], pre[_S_V + 2, s]) * rdet
        key = _key(u, v, t - tmin, pre[_S_ID, s], ign32, eps)
        keys[j] = key
        best_hi = min(best_hi, key)
    return _pick(keys, s1 - s0, best_hi, s0, tmin, tmax)


@njit(cache=True, error_model="numpy", inline="always")
def _exact(ox, oy, oz, dx, dy, dz, soa, s):
    """:func:`intersect.exact`: eq. 3.6 in float64 for one ray and one slot."""
    v0x, v0y, v0z = soa[0, s], soa[1, s], soa[2, s]
    e1x, e1y, e1z = -soa[3, s], -soa[4, s], -soa[5, s]
    e2x, e2y, e2z = soa[6, s], soa[7, s], soa[8, s]
    tx, ty, tz = ox - v0x, oy - v0y, oz - v0z
    px, py, pz = dy * e2z - dz * e2y, dz * e2x - dx * e2z, dx * e2y - dy * e2x
    qx, qy, qz = ty * e1z - tz * e1y, tz * e1x - tx * e1z, tx * e1y - ty * e1x
    inv = 1.0 / ((px * e1x + py * e1y) + pz * e1z)
    t = ((qx * e2x + qy * e2y) + qz * e2z) * inv
    u = ((px * tx + py * ty) + pz * tz) * inv
    v = ((qx * dx + qy * dy) + qz * dz) * inv
    return t, u, v


@njit(cache=True, error_model="numpy")
def _leaf64(ox, oy, oz, dx, dy, dz, tmin, tmax, ign, soa, ids, s0, s1, eps):
    """:func:`closest_slots64` for one ray and the accel's slots ``s0:s1``: ``(slot, t)``
    (-1 and inf when nothing is hit), float64, eq. 3.6 written out; first minimum wins."""
    best = -1
    best_t = np.inf
    for s in range(s0, s1):
        t, u, v = _exact(ox, oy, oz, dx, dy, dz, soa, s)
        ok = (u >= -eps) and (v >= -eps) and (u + v <= 1.0 + eps) and (t > tmin) and (t < tmax)
        if ok and ids[s] != ign and t < best_t:
            best_t = t
            best = s
    if not np.isfinite(best_t):
        return -1, np.inf
    return best, best_t


@njit(cache=True, error_model="numpy", inline="always")
def _lossy(x0, x1, x2, y0, y1, y2):
    """:func:`intersect.lossy32` for one row: ``x`` float64, ``y`` its float32 copy."""
    big = max(abs(x0), abs(x1), abs(x2))
    lim = 2.0**-22 * big
    e0 = abs(np.float64(y0) - x0)
    e1 = abs(np.float64(y1) - x1)
    e2 = abs(np.float64(y2) - x2)
    return not (e0 <= lim and e1 <= lim and e2 <= lim)


@njit(cache=True, error_model="numpy", nogil=True)
def trace(o, d, tmin, tmax, ignore, has_ignore, root_lo, root_hi, origin,
          split, levels, leaf_offset, soa32, first32, last32, back, soa64, ids, size, pre,
          eps32, eps_check, eps64, first_only, shared, shared_o32, record,
          level_cap, leaf_cap, node_cap):
    """Every ray of a packet, start to finish (see :func:`tlm.kernels.traverse._traverse`).

    o, d : (r, 3) float64 (after ``_prepare``: rescaled, subnormals flushed); tmin, tmax,
    ignore : (r,). The layout arrays are :class:`Layout`'s. ``*_cap`` size the buffers:
    the widest level list, and the visited leaves and entered nodes of all rays.
    ``shared``: the float32 test takes the packet's one origin, ``shared_o32`` (3,)
    float32, the first ray's ``o - origin`` as the numpy engine does (the origins are equal
    as float32 values, but a zero's sign may differ); given by the caller, so that a
    chunk of the packet (:mod:`tlm.kernels.threads`) tests exactly as the whole does;
    ``pre`` is :func:`shared_stack` of that origin (unused otherwise).
    Compiled ``nogil``: threads run chunks of a packet at once.

    Returns ``status`` (``OK`` or which buffer overflowed: rerun with it doubled), then
    ``t, u, v`` (r,) float64, ``slot`` (r,) int64 (the accel's slot; -1: none),
    ``node_visits, cnt, leaf_visits, tri_tests`` (r,) int64, and with ``record`` the
    entered nodes and visited leaves, ray-major (sizes ``node_visits``, ``leaf_visits``).
    """
    r = o.shape[0]
    t_out = np.full(r, np.inf)
    u_out = np.zeros(r)
    v_out = np.zeros(r)
    slot_out = np.full(r, -1, dtype=np.int64)
    node_visits = np.zeros(r, dtype=np.int64)
    cnt = np.zeros(r, dtype=np.int64)
    leaf_visits = np.zeros(r, dtype=np.int64)
    tri_tests = np.zeros(r, dtype=np.int64)
    leaf_ids = np.empty(leaf_cap if record else 0, dtype=np.int64)
    node_ids = np.empty(node_cap if record else 0, dtype=np.int64)
    n_leaf_out = 0
    n_node_out = 0
    lnode = np.empty(2 * level_cap, dtype=np.int64)  # two halves: this level, the next
    la = np.empty(2 * level_cap)
    lb = np.empty(2 * level_cap)
    ray9 = np.empty(9)  # a ray's o, d, 1/d (phase 1 without record)
    st_node = np.empty(levels + 1, dtype=np.int64)  # its stack of far children
    st_a = np.empty(levels + 1)
    st_b = np.empty(levels + 1)
    st_depth = np.empty(levels + 1, dtype=np.int64)
    st_axis = np.empty(levels + 1, dtype=np.int64)
    keys = np.empty(max(PAD, int((last32 - first32).max()) if first32.shape[0] else PAD), dtype=np.uint32)
    # an any-hit ray's non-empty leaves (their padded slots, their place in its list),
    # and the triangle tests up to each leaf of its list
    fs = np.empty(2 * level_cap, dtype=np.int64)
    fe = np.empty(2 * level_cap, dtype=np.int64)
    fi = np.empty(2 * level_cap, dtype=np.int64)
    fcum = np.empty(2 * level_cap, dtype=np.int64)
    any_list = first_only and not shared and not record  # (phase 1 lists them)
    lo0, lo1, lo2 = root_lo[0], root_lo[1], root_lo[2]
    hi0, hi1, hi2 = root_hi[0], root_hi[1], root_hi[2]
    sx32, sy32, sz32 = shared_o32[0], shared_o32[1], shared_o32[2]  # (used when shared)
    for i in range(r):
        # the root clip (_clip_root): slabs, a zero component inside or outside its slab
        ta = tmin[i]
        tb = tmax[i]
        # 1/d once per ray for the clip and every level (inf of a zero: never used)
        ic0, ic1, ic2 = 1.0 / d[i, 0], 1.0 / d[i, 1], 1.0 / d[i, 2]
        for k in range(3):
            oc = o[i, k]
            dc = d[i, k]
            lo = lo0 if k == 0 else (lo1 if k == 1 else lo2)
            hi = hi0 if k == 0 else (hi1 if k == 1 else hi2)
            if dc == 0.0:
                inside = (oc >= lo) and (oc <= hi)
                near = -np.inf if inside else np.inf
                far = np.inf if inside else -np.inf
            else:
                ic = ic0 if k == 0 else (ic1 if k == 1 else ic2)
                t0 = (lo - oc) * ic
                t1 = (hi - oc) * ic
                near = _mn(t0, t1)
                far = _mx(t0, t1)
            ta = _mx(ta, near)
            tb = _mn(tb, far)
        if not ta <= tb:
            continue
        # phase 1 (_leaf_lists): the crossed leaves, near child first, from the root
        # interval ta <= tb (neither NaN): m leaves from cur in lnode (their exits in
        # lb), visits the inner nodes entered. Written out here, not in a function of
        # its own: numba counts references to the arrays an inlined function takes, an
        # atomic increment and decrement per array and ray that LLVM keeps around the
        # loops. No interval is NaN (a child is entered only where its a <= b), so
        # _mn(b, ts) is ``b if b < ts else ts`` and _mx(a, ts) is ``a if a > ts else
        # ts`` (the same values, a NaN ts included); indices are unsigned (no
        # negative-index wraparound); the side of the near child is the level's.
        status = OK
        cur = 0
        m = 1
        visits = 0
        if not record:
            # depth first, near child first, with a stack of the far children still
            # to enter: the level lists put a node's children (near, far) where the
            # node was, so the leaves come in this order, with the same intervals (a
            # child's from its parent's by the same operations) and the same inner
            # nodes entered, each once; only the leaves are stored (from 0), not the
            # lists of the levels between. (With record the nodes are recorded level
            # by level, as the numpy engine orders them: the lists are formed there.)
            ray9[0], ray9[1], ray9[2] = o[i, 0], o[i, 1], o[i, 2]
            ray9[3], ray9[4], ray9[5] = d[i, 0], d[i, 1], d[i, 2]
            ray9[6], ray9[7], ray9[8] = ic0, ic1, ic2
            m = 0
            sp = 0
            node = 0
            a = ta
            b = tb
            depth = 0
            axis = 0
            ne = 0  # (an any-hit ray's list of non-empty leaves, made here: see phase 2)
            tests = 0
            while True:
                if depth == levels:  # a leaf: onto the list, then the next pushed far child
                    if m >= 2 * level_cap:
                        status = FULL_LEVEL
                        break
                    lnode[np.uint64(m)] = node
                    lb[np.uint64(m)] = b
                    if any_list:
                        leaf = np.uint64(node - leaf_offset)
                        s0, s1 = first32[leaf], last32[leaf]
                        q = np.uint64(ne)
                        fs[q], fe[q], fi[q] = s0, s1, m
                        ne += 1 if s1 > s0 else 0  # (an empty leaf is overwritten: no branch)
                        tests += size[leaf]
                        fcum[np.uint64(m)] = tests  # (the triangle tests of leaves 0..m)
                    m += 1
                    if sp == 0:
                        break
                    sp -= 1
                    q = np.uint64(sp)
                    node, a, b, depth, axis = st_node[q], st_a[q], st_b[q], st_depth[q], st_axis[q]
                    continue
                visits += 1
                ua = np.uint64(axis)
                oc, dc, ic = ray9[ua], ray9[ua + np.uint64(3)], ray9[ua + np.uint64(6)]
                left = 2 * node + 1
                sp_node = split[np.uint64(node)]
                if dc == 0.0:
                    nr = 1 if oc >= sp_node else 0
                    near_b = b
                    far_a = np.inf
                    keep_near = a <= b
                    keep_far = np.inf <= b
                else:
                    nr = 1 if dc < 0.0 else 0
                    ts = (sp_node - oc) * ic
                    near_b = b if b < ts else ts
                    far_a = a if a > ts else ts
                    keep_near = a <= near_b
                    keep_far = far_a <= b
                depth += 1
                axis = axis + 1 if axis < 2 else 0
                if keep_near:
                    if keep_far:
                        q = np.uint64(sp)
                        st_node[q], st_a[q], st_b[q], st_depth[q], st_axis[q] = left + (1 - nr), far_a, b, depth, axis
                        sp += 1
                    node = left + nr
                    b = near_b
                elif keep_far:
                    node = left + (1 - nr)
                    a = far_a
                else:
                    if sp == 0:
                        break
                    sp -= 1
                    q = np.uint64(sp)
                    node, a, b, depth, axis = st_node[q], st_a[q], st_b[q], st_depth[q], st_axis[q]
        else:  # the level lists, in two halves of lnode, la, lb (level_cap each)
            lnode[0] = 0
            la[0] = ta
            lb[0] = tb
            axis = 0
            for _ in range(levels):
                if axis == 0:
                    oc, dc, ic = o[i, 0], d[i, 0], ic0
                elif axis == 1:
                    oc, dc, ic = o[i, 1], d[i, 1], ic1
                else:
                    oc, dc, ic = o[i, 2], d[i, 2], ic2
                axis = axis + 1 if axis < 2 else 0
                visits += m
                if n_node_out + m > node_cap:
                    status = FULL_NODES
                    break
                for e in range(m):
                    node_ids[np.uint64(n_node_out + e)] = lnode[np.uint64(cur + e)]
                n_node_out += m
                if 2 * m > level_cap:
                    status = FULL_LEVEL
                    break
                nxt = level_cap - cur
                kk = nxt
                if dc == 0.0:
                    for e in range(m):
                        p = np.uint64(cur + e)
                        node = lnode[p]
                        a = la[p]
                        b = lb[p]
                        near_right = oc >= split[np.uint64(node)]
                        left = 2 * node + 1
                        if a <= b:
                            q = np.uint64(kk)
                            lnode[q] = left + (1 if near_right else 0)
                            la[q] = a
                            lb[q] = b
                            kk += 1
                        if np.inf <= b:
                            q = np.uint64(kk)
                            lnode[q] = left + (0 if near_right else 1)
                            la[q] = np.inf
                            lb[q] = b
                            kk += 1
                else:
                    nr = 1 if dc < 0.0 else 0
                    for e in range(m):
                        p = np.uint64(cur + e)
                        node = lnode[p]
                        a = la[p]
                        b = lb[p]
                        ts = (split[np.uint64(node)] - oc) * ic
                        near_b = b if b < ts else ts
                        far_a = a if a > ts else ts
                        left = 2 * node + 1
                        if a <= near_b:
                            q = np.uint64(kk)
                            lnode[q] = left + nr
                            la[q] = a
                            lb[q] = near_b
                            kk += 1
                        if far_a <= b:
                            q = np.uint64(kk)
                            lnode[q] = left + (1 - nr)
                            la[q] = far_a
                            lb[q] = b
                            kk += 1
                m = kk - nxt
                cur = nxt
                if m == 0:
                    break
        node_visits[i] = visits
        if status != OK:
            return status, t_out, u_out, v_out, slot_out, node_visits, cnt, leaf_visits, \
                tri_tests, node_ids, leaf_ids
        cnt[i] = m
        if m == 0:
            continue
        # phase 2 in float32, the datapath (the numpy leaf loop's stopping rule)
        ox, oy, oz = o[i, 0] - origin[0], o[i, 1] - origin[1], o[i, 2] - origin[2]  # o_local
        dx, dy, dz = d[i, 0], d[i, 1], d[i, 2]
        ox32, oy32, oz32 = np.float32(ox), np.float32(oy), np.float32(oz)
        if shared:
            ox32, oy32, oz32 = sx32, sy32, sz32
        dx32, dy32, dz32 = np.float32(dx), np.float32(dy), np.float32(dz)
        t0, t1 = np.float32(tmin[i]), np.float32(tmax[i])
        ign = ignore[i] if has_ignore else -1
        last = m - 1
        best = -1  # padded slot
        best_t = np.inf
        if first_only and not shared:
            # any hit: the non-empty leaves in order (listed by phase 1 without record),
            # filtered in one loop (_scan); a leaf that passes is tested in full, and
            # the first with a hit stops the ray
            if record:
                ne = 0
                tests = 0
            for e in range(m if record else 0):
                leaf = np.uint64(lnode[np.uint64(cur + e)] - leaf_offset)
                s0, s1 = first32[leaf], last32[leaf]
                q = np.uint64(ne)
                fs[q], fe[q], fi[q] = s0, s1, e
                ne += 1 if s1 > s0 else 0  # (an empty leaf is overwritten: no branch)
                tests += size[leaf]
                fcum[np.uint64(e)] = tests  # (the triangle tests of leaves 0..e)
            k = 0
            while k < ne:
                k = _scan(ox32, oy32, oz32, dx32, dy32, dz32, t0, t1, soa32, fs, fe, k, ne, eps32)
                if k >= ne:
                    break
                q = np.uint64(k)
                slot, pt = _leaf32(ox32, oy32, oz32, dx32, dy32, dz32, t0, t1, ign, soa32, fs[q], fe[q], eps32, keys)
                if slot >= 0:
                    best = slot
                    last = fi[q]
                    break
                k += 1
        for e in range(m if not (first_only and not shared) else 0):
            leaf = np.uint64(lnode[np.uint64(cur + e)] - leaf_offset)  # (unsigned: no wraparound)
            slot, pt = -1, np.float32(np.inf)
            s0, s1 = first32[leaf], last32[leaf]
            if s1 > s0 and shared:
                slot, pt = _leaf32_shared(dx32, dy32, dz32, t0, t1, ign, pre, s0, s1, eps32, keys)
            elif s1 > s0:
                slot, pt = _leaf32(ox32, oy32, oz32, dx32, dy32, dz32, t0, t1, ign, soa32, s0, s1, eps32, keys)
            if first_only:
                if slot >= 0:
                    best = slot
                    last = e
                    break
            else:
                if np.float64(pt) < best_t:
                    best_t = np.float64(pt)
                    best = slot
                if best_t <= lb[cur + e]:
                    last = e
                    break
        # the float64 check of the float32 answer (check), the rays that float32
        # cannot carry (lossy32), and the float64 fallback of both
        redo = _lossy(dx, dy, dz, dx32, dy32, dz32) or _lossy(
            ox, oy, oz, np.float32(ox), np.float32(oy), np.float32(oz))  # the ray's own origin
        if best >= 0:
            sb = back[best]
            t, u, v = _exact(ox, oy, oz, dx, dy, dz, soa64, sb)
            ok = (t > tmin[i]) and (t < tmax[i]) and (u >= -eps_check) and (v >= -eps_check) and (
                u + v <= 1.0 + eps_check)
            t_out[i], u_out[i], v_out[i], slot_out[i] = t, u, v, sb
            redo = redo or not ok
        if redo:
            t_out[i], u_out[i], v_out[i], slot_out[i] = np.inf, 0.0, 0.0, -1
            last = m - 1
            best_t = np.inf
            sb = -1
            for e in range(m):
                leaf = lnode[cur + e] - leaf_offset
                s0 = first32[leaf]
                slot, pt = _leaf64(ox, oy, oz, dx, dy, dz, tmin[i], tmax[i], ign, soa64, ids,
                                   back[s0], back[s0] + size[leaf], eps64) if size[leaf] > 0 else (-1, np.inf)
                if first_only:
                    if slot >= 0:
                        sb = slot
                        last = e
                        break
                else:
                    if pt < best_t:
                        best_t = pt
                        sb = slot
                    if best_t <= lb[cur + e]:
                        last = e
                        break
            if sb >= 0:
                t, u, v = _exact(ox, oy, oz, dx, dy, dz, soa64, sb)
                t_out[i], u_out[i], v_out[i], slot_out[i] = t, u, v, sb
        leaf_visits[i] = last + 1
        if first_only and not shared and not record:
            tri_tests[i] = fcum[np.uint64(last)]
            continue
        tests = 0
        if record and n_leaf_out + last + 1 > leaf_cap:
            return FULL_LEAVES, t_out, u_out, v_out, slot_out, node_visits, cnt, leaf_visits, \
                tri_tests, node_ids, leaf_ids
        for e in range(last + 1):
            leaf = lnode[np.uint64(cur + e)] - leaf_offset
            tests += size[np.uint64(leaf)]
            if record:
                leaf_ids[n_leaf_out + e] = leaf
        tri_tests[i] = tests
        if record:
            n_leaf_out += last + 1
    return OK, t_out, u_out, v_out, slot_out, node_visits, cnt, leaf_visits, tri_tests, \
        node_ids[:n_node_out], leaf_ids[:n_leaf_out]
