"""One bounce of the final-gather rays (:func:`tlm.kernels.shade.final_gather_bounce`) compiled with numba.

After a bounce's rays are traced and the lights they see are found, the numpy code picks
the rays that end on a Lambertian surface (a gather there: its point, normal, the weight
the path carries) and sends the others on through mirrors and glass (the shading normal,
the Fresnel term, one branch by the ray's own random number, the medium and the weight),
in about 40 array operations. Two batches' threads doing that at once waited on each
other for the interpreter's lock. :func:`fg_bounce` does it in one call, ray by ray,
without the lock (``nogil``).

Every floating-point operation is the numpy code's, in its order (the helpers of
:mod:`tlm.kernels._jit_photons`, which the photon trace's bounce shares), and the random
numbers are the same hash, so the gathers, their weights and the paths are the numpy
code's, bit for bit (but for the sign or payload of a NaN, from a NaN input).
``TLM_KERNELS=numpy`` runs the numpy code, the reference (tests/test_engines.py compares
the two).
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._jit_hash import _GOLD, _mix, uniform3
from tlm.kernels._jit_photons import _facing, _scatter_specular, _shading_normal
from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)


@njit(cache=True, nogil=True, error_model="numpy")
def fg_bounce(seed, bounce_no, last, j, r, owner, pkeys, medium, med, w, origin, d,
              h_triangle, h_t, h_u, h_v, seen,
              kind_of, normals, shading, reflectance, transmittance, ior, lambertian, mirror, fresnel,
              fragments, specular_bounces):
    """The rays ``(j, r)`` (gather point, ray index) of bounce ``bounce_no`` after their trace.

    seed : the final gather's hash key (uint64). owner, pkeys, medium : per gather point
    (its pixel, its hash key, the index of refraction around it). med, w, origin, d : per
    ray (the index around it, the weight its path carries, its origin and direction).
    h_* : the rays' hits; seen : a light is nearer than the hit (the ray ends there). last :
    no bounce follows this one (a specular hit ends the path). The tables are the scene's
    (per triangle). fragments, specular_bounces : per pixel, added to.

    Returns the gathers (the rays that end on a Lambertian surface: j, r, the point, the
    normal facing the arriving side, the weight as it arrives, the triangle) and the rays
    that go on (j, r, med, w, origin, direction, the triangle each leaves).
    """
    m = j.shape[0]
    start = _mix(seed + _GOLD)
    n_lam = 0
    n_go = 0
    for i in range(m):
        tri = h_triangle[i]
        if tri >= 0 and not seen[i]:
            if kind_of[tri] == lambertian:
                n_lam += 1
            elif not last:
                n_go += 1
    f_j = np.empty(n_lam, dtype=np.int64)
    f_r = np.empty(n_lam, dtype=np.int64)
    f_x = np.empty((n_lam, 3))
    f_n = np.empty((n_lam, 3))
    f_w = np.empty((n_lam, 3))
    f_tri = np.empty(n_lam, dtype=np.int64)
    g_j = np.empty(n_go, dtype=np.int64)
    g_r = np.empty(n_go, dtype=np.int64)
    g_med = np.empty(n_go)
    g_w = np.empty((n_go, 3))
    g_o = np.empty((n_go, 3))
    g_d = np.empty((n_go, 3))
    g_tri = np.empty(n_go, dtype=np.int64)
    a = 0
    b = 0
    for i in range(m):
        tri = h_triangle[i]
        if tri < 0 or seen[i]:
            continue
        kind = kind_of[tri]
        lam = kind == lambertian
        if not lam and last:
            continue
        jj = j[i]
        d0, d1, d2 = d[i, 0], d[i, 1], d[i, 2]
        t = h_t[i]
        x0 = origin[i, 0] + t * d0
        x1 = origin[i, 1] + t * d1
        x2 = origin[i, 2] + t * d2
        g0, g1, g2 = normals[tri, 0], normals[tri, 1], normals[tri, 2]
        if lam:
            q = medium[jj] / med[i]
            q = q * q  # (``** 2``: numpy squares)
            f_j[a], f_r[a], f_tri[a] = jj, r[i], tri
            f_x[a, 0], f_x[a, 1], f_x[a, 2] = x0, x1, x2
            f_n[a, 0], f_n[a, 1], f_n[a, 2] = _facing(g0, g1, g2, d0, d1, d2)
            f_w[a, 0], f_w[a, 1], f_w[a, 2] = w[i, 0] * q, w[i, 1] * q, w[i, 2] * q
            fragments[owner[jj]] += 1
            a += 1
            continue
        # a mirror or glass surface: one branch (glass: reflected with the Fresnel probability)
        s0, s1, s2 = _shading_normal(shading, tri, h_u[i], h_v[i], g0, g1, g2)
        is_mirror = kind == mirror
        index = 1.0 if is_mirror else ior[tri]
        r0, r1, r2, q0, q1, q2, f, entering = _scatter_specular(d0, d1, d2, s0, s1, s2, g0, g1, g2, index)
        if not fresnel:
            f = 0.0 if f < 1.0 else 1.0
        take_refl = is_mirror or uniform3(start, pkeys[jj], r[i], 2 + bounce_no) < f
        g_j[b], g_r[b], g_tri[b] = jj, r[i], tri
        if take_refl:
            g_med[b] = med[i]
        else:
            g_med[b] = ior[tri] if entering else 1.0
        for c in range(3):
            if is_mirror:
                g_w[b, c] = w[i, c] * reflectance[tri, c]
            elif take_refl:
                g_w[b, c] = w[i, c] * 1.0
            else:
                g_w[b, c] = w[i, c] * transmittance[tri, c]
        g_o[b, 0], g_o[b, 1], g_o[b, 2] = x0, x1, x2
        if take_refl:
            g_d[b, 0], g_d[b, 1], g_d[b, 2] = r0, r1, r2
        else:
            g_d[b, 0], g_d[b, 1], g_d[b, 2] = q0, q1, q2
        specular_bounces[owner[jj]] += 1
        b += 1
    return (f_j, f_r, f_x, f_n, f_w, f_tri), (g_j, g_r, g_med, g_w, g_o, g_d, g_tri)
