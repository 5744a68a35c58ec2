"""The traversal compiled with numba, one ray at a time: the fast path of :mod:`traverse`
(its leaf tests, inlined: :mod:`tlm.kernels._jit_leaf`).

This is :func:`tlm.kernels.traverse._traverse` (root clip, leaf list, leaf loop,
float64 check, float64 fallback, work counts, memory touched) written per ray instead
of per block: a ray stops testing where its stopping rule says so (the numpy version
tests a batch of leaves ahead and discards the excess), and no (slot, ray) block is
materialized. Every floating-point operation is the numpy version's, in the same order
and precision: float32 for the block test (:func:`intersect.closest_slots`), float64
for the intervals, the check (:func:`intersect.check`) and the fallback
(:func:`intersect.closest_slots64`); where an operand provably is not NaN, numpy's
NaN-propagating minimum and maximum are the plain ones, one instruction each (the same
values: :func:`~tlm.kernels._jit_leaf._key`, phase 1 in :func:`trace`). numba compiles without fast-math, so nothing is
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
:func:`~tlm.kernels._jit_leaf.shared_stack`) are computed once per origin (the caller keeps the last one),
with the same operations, so a slot costs
about a third fewer operations and the same bits; the slot loops of the two cases are
separate functions, as one loop holding both formulas evaluates both in every lane.
Each ray's ``1/d`` is divided once for the root clip and every level. Without
``record``, phase 1 walks the tree depth first (the leaves in the order of the level
lists; the lists themselves are formed only to record the nodes level by level). An
any-hit ray (``first_only``, not of a shared origin) runs its leaves through a filter first, one loop over
all their vectors (:func:`~tlm.kernels._jit_leaf._scan`: never false on a leaf with a hit), and tests in
full (:func:`~tlm.kernels._jit_leaf._leaf32`) only a leaf that passes; the first with a hit stops it.
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

from tlm.kernels._jit_leaf import PAD, _exact, _leaf32, _leaf32_shared, _leaf64, _lossy, _mn, _mx, _scan
from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)

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
    ``pre`` is :func:`~tlm.kernels._jit_leaf.shared_stack` of that origin (unused otherwise).
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
                slot, pt = _leaf32(ox32, oy32, oz32, dx32, dy32, dz32, t0, t1, ign, soa32, fs[q], fe[q], eps32)
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
                slot, pt = _leaf32_shared(dx32, dy32, dz32, t0, t1, ign, pre, s0, s1, eps32)
            elif s1 > s0:
                slot, pt = _leaf32(ox32, oy32, oz32, dx32, dy32, dz32, t0, t1, ign, soa32, s0, s1, eps32)
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
