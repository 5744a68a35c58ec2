"""One bounce of the photon trace (:func:`tlm.kernels.photons.trace_photons`) compiled with numba.

The numpy code scatters a chunk's photons bounce by bounce in about 150 array operations
(the hits kept, the photons stored, Russian roulette, the cosine-weighted directions, the
shading normals, mirrors and glass with their Fresnel term, the paths kept). On arrays of
a few thousand photons their cost is the interpreter's, which holds its lock: two threads
tracing chunks at once waited on each other (the Cornell box's photon stage ran 1.36x
faster on two threads, the passes 1.8x). :func:`bounce` does all of it in one call,
photon by photon, without the lock (``nogil``): the threads' chunks run at once.

Every floating-point operation is the numpy code's, in its order, so the photons, their
paths and their work are the numpy code's, bit for bit (but for the sign or payload of a
NaN, from a NaN input, which no scene gives). numba compiles without fast-math: nothing
is reassociated or fused. Dot products and norms are summed from +0.0, then x, y, z
(``np.sum`` over three columns: three products of -0.0 sum to +0.0); numpy's ``maximum``
(:func:`~tlm.kernels._jit_leaf._mx`: a NaN wins, the second operand on a tie), ``np.clip`` (a
NaN stays, ``x`` on a tie), ``np.nan_to_num`` and the cross products of ``np.cross`` are
written out. The random numbers are the same hash (:mod:`tlm.kernels._jit_hash`). The
one exception is the azimuth of a diffuse bounce: its sine and cosine are numpy's,
computed by the caller (on every photon of the bounce, before the kernel), so that they
are the reference's wherever numpy's ``sin`` and ``cos`` differ from the C library's
(numpy's AVX-512 code). ``TLM_KERNELS=numpy`` runs the numpy code, the reference
(tests/test_engines.py compares the two).
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._jit_hash import _GOLD, _mix, uniform3
from tlm.kernels._jit_leaf import _mx
from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)

_BIG = np.finfo(np.float64).max  # np.nan_to_num's stand-in for an infinity


@njit(cache=True, nogil=True, inline="always")
def _clip(x, lo, hi):
    """``np.clip`` of a float: a NaN stays, ``x`` on a tie (so -0.0 stays -0.0)."""
    if x != x:
        return x
    if x < lo:
        return lo
    if x > hi:
        return hi
    return x


@njit(cache=True, nogil=True, inline="always")
def _dot(a0, a1, a2, b0, b1, b2):
    """``np.sum(a * b, axis=1)`` of one row: from +0.0 (LLVM keeps the ``0.0 +``), x, y, then z."""
    return ((0.0 + a0 * b0) + a1 * b1) + a2 * b2


@njit(cache=True, nogil=True, inline="always")
def _facing(g0, g1, g2, d0, d1, d2):
    """:func:`tlm.kernels.shade.facing` of one ray: the normal ``g`` turned to face the side
    a ray of direction ``d`` arrives from."""
    if _dot(g0, g1, g2, d0, d1, d2) > 0:
        return -g0, -g1, -g2
    return g0, g1, g2


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _fresnel(cos_i, eta):
    """:func:`tlm.kernels.shade.fresnel_dielectric` of one ray: ``(F, cos_t)``."""
    sin2_t = (eta * eta) * _mx(0.0, 1.0 - cos_i * cos_i)
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(_mx(0.0, 1.0 - sin2_t))
    rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
    rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    if tir:
        f = 1.0
    else:
        f = 0.5 * (rs * rs + rp * rp)
        if f != f:
            f = 1.0
        elif f == np.inf:
            f = _BIG
        elif f == -np.inf:
            f = -_BIG
    return _clip(f, 0.0, 1.0), 0.0 if tir else cos_t


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _snell(d0, d1, d2, n0, n1, n2, eta):
    """``tlm.kernels.shade._snell`` of one ray: the unit refracted direction (``d`` where
    it has no length) and ``F``."""
    cos_i = _clip(-_dot(d0, d1, d2, n0, n1, n2), 0.0, 1.0)
    f, cos_t = _fresnel(cos_i, eta)
    k = eta * cos_i - cos_t
    t0 = eta * d0 + k * n0
    t1 = eta * d1 + k * n1
    t2 = eta * d2 + k * n2
    length = np.sqrt(_dot(t0, t1, t2, t0, t1, t2))
    if length > 0:
        return t0 / length, t1 / length, t2 / length, f
    return d0, d1, d2, f


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _reflect(d0, d1, d2, n0, n1, n2):
    """:func:`tlm.kernels.shade.reflect` of one ray."""
    k = 2.0 * _dot(d0, d1, d2, n0, n1, n2)
    return d0 - k * n0, d1 - k * n1, d2 - k * n2


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _direction_about(n0, n1, n2, cos_t, cos_phi, sin_phi):
    """:func:`tlm.kernels.emission._around` of one direction: the unit direction at polar
    cosine ``cos_t`` and azimuth ``phi`` (its cosine and sine given) about the unit axis
    ``n``, in the tangent frame of ``_frame`` (``cross(n, e)`` normalised, ``e`` the y axis
    where ``|n_x| > 0.9``, else the x axis; then ``cross(n, t)``)."""
    if abs(n0) > 0.9:
        e0, e1, e2 = 0.0, 1.0, 0.0
    else:
        e0, e1, e2 = 1.0, 0.0, 0.0
    t0 = n1 * e2 - n2 * e1
    t1 = n2 * e0 - n0 * e2
    t2 = n0 * e1 - n1 * e0
    length = np.sqrt(_dot(t0, t1, t2, t0, t1, t2))
    t0, t1, t2 = t0 / length, t1 / length, t2 / length
    b0 = n1 * t2 - n2 * t1
    b1 = n2 * t0 - n0 * t2
    b2 = n0 * t1 - n1 * t0
    s = np.sqrt(_mx(0.0, 1.0 - cos_t * cos_t))
    sc = s * cos_phi
    ss = s * sin_phi
    v0 = (sc * t0 + ss * b0) + cos_t * n0
    v1 = (sc * t1 + ss * b1) + cos_t * n1
    v2 = (sc * t2 + ss * b2) + cos_t * n2
    length = np.sqrt(_dot(v0, v1, v2, v0, v1, v2))
    return v0 / length, v1 / length, v2 / length


@njit(cache=True, nogil=True, error_model="numpy")
def around(axis, cos_t, cos_phi, sin_phi):
    """:func:`tlm.kernels.emission._around` compiled: (k, 3) unit directions about the unit
    axes ``axis`` (k, 3), from float64 inputs, the numpy code's bits but for the sign or
    payload of a NaN (the sines and cosines of the azimuths are the caller's, numpy's)."""
    k = axis.shape[0]
    out = np.empty((k, 3))
    for i in range(k):
        out[i, 0], out[i, 1], out[i, 2] = _direction_about(axis[i, 0], axis[i, 1], axis[i, 2], cos_t[i],
                                                           cos_phi[i], sin_phi[i])
    return out


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _shading_normal(shading, tri, u, v, g0, g1, g2):
    """:func:`tlm.scenes.normals.interpolate` at one hit: the unit interpolated shading normal
    of triangle ``tri`` at barycentrics ``(u, v)``, turned to the geometric normal ``g``'s
    side; ``g`` where the interpolation vanishes."""
    w0 = (1.0 - u) - v
    s0 = (w0 * shading[tri, 0, 0] + u * shading[tri, 1, 0]) + v * shading[tri, 2, 0]
    s1 = (w0 * shading[tri, 0, 1] + u * shading[tri, 1, 1]) + v * shading[tri, 2, 1]
    s2 = (w0 * shading[tri, 0, 2] + u * shading[tri, 1, 2]) + v * shading[tri, 2, 2]
    length = np.sqrt(_dot(s0, s1, s2, s0, s1, s2))
    if length > 0:
        s0, s1, s2 = s0 / length, s1 / length, s2 / length
    else:
        s0, s1, s2 = 0.0, 0.0, 0.0
    if _dot(s0, s1, s2, g0, g1, g2) < 0.0:
        s0, s1, s2 = -s0, -s1, -s2
    if not (s0 != 0.0 or s1 != 0.0 or s2 != 0.0):
        return g0, g1, g2
    return s0, s1, s2


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _scatter_specular(d0, d1, d2, s0, s1, s2, g0, g1, g2, index):
    """:func:`tlm.kernels.shade.scatter_specular` of one ray (shading normal ``s``, geometric
    ``g``, the dielectric's index; 1.0 for a mirror): the reflected direction, the refracted
    one, ``F``, and whether the ray arrives on the side ``g`` points to."""
    front = _dot(d0, d1, d2, g0, g1, g2) < 0.0
    if front:
        m0, m1, m2 = g0, g1, g2
        n0, n1, n2 = s0, s1, s2
    else:
        m0, m1, m2 = -g0, -g1, -g2
        n0, n1, n2 = -s0, -s1, -s2
    if _dot(d0, d1, d2, n0, n1, n2) >= 0.0:
        n0, n1, n2 = m0, m1, m2
    r0, r1, r2 = _reflect(d0, d1, d2, n0, n1, n2)
    if _dot(r0, r1, r2, m0, m1, m2) <= 0.0:
        r0, r1, r2 = _reflect(d0, d1, d2, m0, m1, m2)
    eta = 1.0 / index if front else index
    q0, q1, q2, f = _snell(d0, d1, d2, n0, n1, n2, eta)
    if _dot(q0, q1, q2, m0, m1, m2) >= 0.0:
        q0, q1, q2, f = _snell(d0, d1, d2, m0, m1, m2, eta)
    return r0, r1, r2, q0, q1, q2, f, front


@njit(cache=True, nogil=True, inline="always")
def _put(pos, nrm, inc, pw, caus, row, x0, x1, x2, n0, n1, n2, d0, d1, d2, p0, p1, p2, caustic):
    """Row ``row`` of a map's photons: position, normal, incoming direction, power, caustic."""
    pos[row, 0], pos[row, 1], pos[row, 2] = x0, x1, x2
    nrm[row, 0], nrm[row, 1], nrm[row, 2] = n0, n1, n2
    inc[row, 0], inc[row, 1], inc[row, 2] = d0, d1, d2
    pw[row, 0], pw[row, 1], pw[row, 2] = p0, p1, p2
    caus[row] = caustic


@njit(cache=True, nogil=True, error_model="numpy")
def bounce(seed, lo, bounce_no, pid, o, d, power, specular_only, direct,
           h_triangle, h_t, h_u, h_v, h_counts, cos_phi, sin_phi,
           caustic_group, kind_of, normals, shading, albedo, reflectance, transmittance, ior, matched,
           lambertian, mirror, split, global_map, russian_roulette, fresnel, eps,
           w_counts, w_rays, w_lost, w_bounces, w_stored, w_absorbed):
    """Scatter the photons ``pid`` (from ``lo``) at their hits of bounce ``bounce_no``:
    what the loop body of ``trace_photons``'s chunk does after its ``closest_hit``.

    seed : the photons' hash key (uint64). pid, o, d, power, specular_only, direct : the
    travelling photons (chunk index, origin, direction, RGB power, every bounce so far
    specular, straight from the light). h_* : their hits (h_counts: node visits, leaves
    crossed, leaf visits and triangle tests, a tuple of 4 arrays). cos_phi, sin_phi : the
    cosine and sine of ``2 pi u2`` (numpy's) of every photon of ``pid``. The tables are
    the scene's (per triangle); lambertian, mirror : their kind codes. eps : the spawn
    offset (the next bounce's ``tmin`` is ``eps / |d|``). w_* : the chunk's work, added to
    (w_counts: the four counts of h_counts).

    Returns the photons still travelling (pid, origin, direction, power, the triangle each
    leaves, specular_only, direct, the next tmin), the photons stored (position, normal
    facing the arriving side, incoming direction, power, caustic) and, with
    ``global_map``, every Lambertian hit of the global group (the same five).
    """
    m = pid.shape[0]
    start = _mix(seed + _GOLD)
    # (hits first: the outputs hold at most one row per hit)
    hits = 0
    for i in range(m):
        if h_triangle[i] >= 0:
            hits += 1
    n_pid = np.empty(hits, dtype=np.int64)
    n_o = np.empty((hits, 3))
    n_d = np.empty((hits, 3))
    n_power = np.empty((hits, 3))
    n_last = np.empty(hits, dtype=np.int64)
    n_spec = np.empty(hits, dtype=np.bool_)
    n_direct = np.empty(hits, dtype=np.bool_)
    n_rel = np.empty(hits)
    s_pos = np.empty((hits, 3))
    s_nrm = np.empty((hits, 3))
    s_inc = np.empty((hits, 3))
    s_pow = np.empty((hits, 3))
    s_caus = np.empty(hits, dtype=np.bool_)
    g_rows = hits if global_map else 0
    g_pos = np.empty((g_rows, 3))
    g_nrm = np.empty((g_rows, 3))
    g_inc = np.empty((g_rows, 3))
    g_pow = np.empty((g_rows, 3))
    g_caus = np.empty(g_rows, dtype=np.bool_)
    kept = 0
    stored = 0
    every = 0
    for i in range(m):
        p = pid[i]
        for c in range(4):
            w_counts[c][p] += h_counts[c][i]
        w_rays[p] += 1
        tri = h_triangle[i]
        if tri < 0:
            w_lost[p] += 1
            continue
        w_bounces[p] += 1
        d0, d1, d2 = d[i, 0], d[i, 1], d[i, 2]
        t = h_t[i]
        x0 = o[i, 0] + t * d0
        x1 = o[i, 1] + t * d1
        x2 = o[i, 2] + t * d2
        p0, p1, p2 = power[i, 0], power[i, 1], power[i, 2]
        g0, g1, g2 = normals[tri, 0], normals[tri, 1], normals[tri, 2]
        f0, f1, f2 = _facing(g0, g1, g2, d0, d1, d2)
        kind = kind_of[tri]
        lam = kind == lambertian
        spec_only = specular_only[i]
        group = caustic_group[lo + p]
        store = lam and not direct[i]
        if split:
            store = store and spec_only == group
        if store:
            _put(s_pos, s_nrm, s_inc, s_pow, s_caus, stored, x0, x1, x2, f0, f1, f2, d0, d1, d2, p0, p1, p2, spec_only)
            stored += 1
        if global_map:
            every_hit = lam and not group
            if every_hit:
                _put(g_pos, g_nrm, g_inc, g_pow, g_caus, every, x0, x1, x2, f0, f1, f2, d0, d1, d2, p0, p1, p2,
                     spec_only)
                every += 1
                w_stored[p] += 1
            if store and spec_only:
                w_stored[p] += 1
        elif store:
            w_stored[p] += 1

        alive = True
        if lam:
            a0, a1, a2 = albedo[tri, 0], albedo[tri, 1], albedo[tri, 2]
            most = _mx(_mx(a0, a1), a2)
            if russian_roulette:
                survive = uniform3(start, lo + p, bounce_no, 0) < most
                if survive:
                    q = most if most > 0 else 1.0
                    c0, c1, c2 = a0 / q, a1 / q, a2 / q
                else:
                    c0, c1, c2 = 0.0, 0.0, 0.0
            else:
                survive = most > 0
                c0, c1, c2 = a0, a1, a2
            p0, p1, p2 = p0 * c0, p1 * c1, p2 * c2
            # cosine_directions about the facing normal (emission._around)
            cos_t = np.sqrt(_mx(0.0, 1.0 - uniform3(start, lo + p, bounce_no, 1)))
            nd0, nd1, nd2 = _direction_about(f0, f1, f2, cos_t, cos_phi[i], sin_phi[i])
            if split:
                survive = survive and not group
            alive = survive
            if not survive:
                w_absorbed[p] += 1
        else:
            s0, s1, s2 = _shading_normal(shading, tri, h_u[i], h_v[i], g0, g1, g2)
            is_mirror = kind == mirror
            index = 1.0 if is_mirror else ior[tri]
            r0, r1, r2, q0, q1, q2, f, _ = _scatter_specular(d0, d1, d2, s0, s1, s2, g0, g1, g2, index)
            if not fresnel:
                f = 0.0 if f < 1.0 else 1.0
            go_reflect = is_mirror or uniform3(start, lo + p, bounce_no, 3) < f
            if go_reflect:
                nd0, nd1, nd2 = r0, r1, r2
            else:
                nd0, nd1, nd2 = q0, q1, q2
            if is_mirror:
                p0, p1, p2 = p0 * reflectance[tri, 0], p1 * reflectance[tri, 1], p2 * reflectance[tri, 2]
            if not go_reflect:
                p0, p1, p2 = p0 * transmittance[tri, 0], p1 * transmittance[tri, 1], p2 * transmittance[tri, 2]
        if not (alive and _mx(_mx(p0, p1), p2) > 0):
            continue
        n_pid[kept] = p
        n_o[kept, 0], n_o[kept, 1], n_o[kept, 2] = x0, x1, x2
        n_d[kept, 0], n_d[kept, 1], n_d[kept, 2] = nd0, nd1, nd2
        n_power[kept, 0], n_power[kept, 1], n_power[kept, 2] = p0, p1, p2
        n_last[kept] = tri
        n_spec[kept] = spec_only and not lam
        n_direct[kept] = direct[i] and matched[tri]
        n_rel[kept] = eps / np.sqrt(_dot(nd0, nd1, nd2, nd0, nd1, nd2))
        kept += 1
    return ((n_pid[:kept].copy(), n_o[:kept].copy(), n_d[:kept].copy(), n_power[:kept].copy(),
             n_last[:kept].copy(), n_spec[:kept].copy(), n_direct[:kept].copy(), n_rel[:kept].copy()),
            (s_pos[:stored].copy(), s_nrm[:stored].copy(), s_inc[:stored].copy(), s_pow[:stored].copy(),
             s_caus[:stored].copy()),
            (g_pos[:every].copy(), g_nrm[:every].copy(), g_inc[:every].copy(), g_pow[:every].copy(),
             g_caus[:every].copy()))
