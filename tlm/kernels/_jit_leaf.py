"""The leaf tests of the compiled traversal (:func:`tlm.kernels._jit.trace`), per ray, inlined
into it: the float32 test of a leaf's padded slots (:func:`_leaf32`; :func:`_leaf32_shared`
for rays of one shared origin, from the rows of :func:`shared_stack`), the any-hit filter
over a ray's leaves (:func:`_scan`), and the float64 check and fallback (:func:`_exact`,
:func:`_leaf64`, :func:`_lossy`). Every operation is the numpy engine's, in the same order
and precision (the rules are in :mod:`tlm.kernels._jit`'s docstring), and :func:`_mn`,
:func:`_mx` are numpy's NaN-propagating minimum and maximum, which the other compiled
modules take from here too.
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)

PAD = 8  # slots per AVX2 vector of float32
_NO_HIT = np.uint32(0x7F800000)  # float32 +inf
_REJECT = np.uint32(0xFFFFFFFF)


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


_NONE = np.uint64(0xFFFFFFFFFFFFFFFF)  # (no pair yet: above every packed key and place)


@njit(cache=True, error_model="numpy", inline="always")
def _pack(key, j):
    """A slot's key (:func:`_key`) in the high 32 bits and its place ``j`` in the leaf
    in the low ones: the minimum of these is the lowest key's, the lowest place among
    equal keys (one unsigned minimum a slot, which LLVM vectorizes)."""
    return (np.uint64(key) << np.uint64(32)) | j


@njit(cache=True, error_model="numpy", inline="always")
def _pick(best, s0, tmin, tmax):
    """The end of a leaf's float32 test from the minimum ``best`` of :func:`_pack`:
    ``(slot, t)`` of the lowest key (the lowest slot among equal ones), or -1 and inf
    when nothing is accepted before ``tmax``."""
    best_hi = np.uint32(best >> np.uint64(32))
    if best_hi >= _NO_HIT:  # nothing accepted, or only at t' = inf
        return -1, np.float32(np.inf)
    tb = best_hi.view(np.float32) + tmin
    if not tb < tmax:
        return -1, np.float32(np.inf)
    return s0 + np.int64(best & np.uint64(0xFFFFFFFF)), tb


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
def _leaf32(ox, oy, oz, dx, dy, dz, tmin, tmax, ign, soa, s0, s1, eps):
    """:func:`closest_slots` for one ray and the padded slots ``s0:s1``: ``(slot, t)``
    (a padded slot; -1 and inf when nothing is hit). Scalars are float32; ``ign`` is a
    triangle id or -1. Among equal distances the lowest slot wins.

    The slot loop is branch-free with unsigned indices, so LLVM vectorizes it (numba
    adds a negative-index wraparound to signed ones, and LLVM then gathers lane by lane).
    A slot's key is the bits of ``t' = t - tmin`` of an accepted pair and 0xFFFFFFFF
    of a rejected one; the loop keeps the minimum of the keys packed with their places
    (:func:`_pack`), so no key is stored and none searched for afterwards. Rays of a
    shared origin take :func:`_leaf32_shared` (the same values with the ray-independent
    part computed once): one loop each, as a loop holding both formulas computes both in
    every lane.
    """
    ign32 = np.int32(ign)
    u0 = np.uint64(s0)
    best = _NONE
    for j in range(np.uint64(s1 - s0)):
        best = min(best, _pack(_slot_key(ox, oy, oz, dx, dy, dz, tmin, ign32, soa, u0 + j, eps), j))
    return _pick(best, s0, tmin, tmax)


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
def _leaf32_shared(dx, dy, dz, tmin, tmax, ign, pre, s0, s1, eps):
    """:func:`_leaf32` for a ray of the packet's shared origin, from the rows of
    :func:`_shared_rows`: ``u`` and ``v`` are linear forms in ``D``, ``(K.D) / det``
    evaluated as ``(dx kx + dy ky) + dz kz`` (the numpy shared-origin path), and ``T.N``
    is the same for every ray."""
    best = _NONE
    ign32 = np.int32(ign)
    for j in range(np.uint64(s1 - s0)):  # (unsigned slots, as in _leaf32)
        s = np.uint64(s0) + j
        rdet = np.float32(1.0) / _dot(dx, dy, dz, pre[_S_NN, s], pre[_S_NN + 1, s], pre[_S_NN + 2, s])
        t = pre[_S_T, s] * rdet
        u = _dot(dx, dy, dz, pre[_S_U, s], pre[_S_U + 1, s], pre[_S_U + 2, s]) * rdet
        v = _dot(dx, dy, dz, pre[_S_V, s], pre[_S_V + 1, s], pre[_S_V + 2, s]) * rdet
        best = min(best, _pack(_key(u, v, t - tmin, pre[_S_ID, s], ign32, eps), j))
    return _pick(best, s0, tmin, tmax)


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
