"""The caustic group's cone mixture (:func:`tlm.kernels.emission.cone_mixture`) compiled with numba.

The numpy code forms, for a chunk of photons, every (photon, box) cone of
:func:`tlm.kernels.emission._box_cones` at once: (8, photons, boxes) corner arrays and
their temporaries, chunked so that photons x boxes stays near ``CONE_CHUNK``. A specular
mesh cut into many boxes (the 69k-triangle glass blob of ``benchmarks/bench_memory.py``:
2,064 boxes) leaves a few dozen photons to a chunk, and the emission of its 120,000
photons took 11 s. Here :func:`cone_pick` computes each photon's cones box by box (a loop
LLVM vectorizes: :func:`_cone` is branch-free), keeps them (32 bytes a cone) for
:func:`cones_holding`, and the threads run the chunks at once (``nogil``).

From float64 inputs (what :func:`~tlm.kernels.emission.emit` passes; the numpy code,
which computes in its inputs' type, runs for any other) the values are the numpy code's,
bit for bit, but for the sign of a NaN (from a NaN box, which no scene gives): each
box's cone is computed with the same operations in the same order (corner vectors
``lo - p`` and ``hi - p``, the centre's direction times ``1 / length``, each corner's
``dot / sqrt(sq)``, the least of the eight in numpy's order with its NaN rule, clipped
to [-1, 1], -1 inside the box); the solid angles are summed one after another
(``np.cumsum``); a cone holds a direction where ``(d0 a0 + d1 a1) + d2 a2 >= cos``.
numba compiles without fast-math (nothing is reassociated or fused). The direction in
the picked cone is drawn between the two calls by :func:`~tlm.kernels.emission._around`
(compiled too, :func:`tlm.kernels._jit_photons.around`; its sine and cosine are numpy's).
``TLM_KERNELS=numpy`` runs the numpy code, the reference (tests/test_engines.py compares
the two; ``benchmarks/bench_emission.py`` times them).
"""

from __future__ import annotations

import numpy as np

from tlm.kernels._jit_leaf import _mn
from tlm.kernels._numba_cache import njit  # (numba's, with the cache stamped on every compiled file)

_TWO_PI = 2.0 * np.pi  # (the numpy code's ``2.0 * np.pi * (1.0 - cos)`` multiplies left to right)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _cone(px, py, pz, box, k):
    """The cone from ``p`` bounding box ``k`` of ``box`` (6, K: the low corners' x, y,
    z, then the high ones'): its unit axis and the cosine of its half-angle (-1 where
    ``p`` is in the closed box), as ``_box_cones`` computes them. Written with selects,
    which LLVM keeps branch-free (:func:`_mn`'s tests too), so that a loop over the boxes
    vectorizes."""
    e00 = box[0, k] - px
    e01 = box[3, k] - px
    e10 = box[1, k] - py
    e11 = box[4, k] - py
    e20 = box[2, k] - pz
    e21 = box[5, k] - pz
    a0 = 0.5 * (e00 + e01)
    a1 = 0.5 * (e10 + e11)
    a2 = 0.5 * (e20 + e21)
    length = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2)
    inside = (e00 <= 0) & (e01 >= 0) & (e10 <= 0) & (e11 >= 0) & (e20 <= 0) & (e21 >= 0)
    inv = 1.0 / length
    pos = length > 0
    a0 = a0 * inv if pos else 0.0
    a1 = a1 * inv if pos else 0.0
    a2 = a2 * inv if pos else 1.0
    # the corners in numpy's order (x, then y, then z, low end first), reduced as
    # ``min(axis=0)``: the first, then numpy's minimum with each next (_mn)
    cos = _corner(a0, a1, a2, e00, e10, e20)
    cos = _mn(cos, _corner(a0, a1, a2, e00, e10, e21))
    cos = _mn(cos, _corner(a0, a1, a2, e00, e11, e20))
    cos = _mn(cos, _corner(a0, a1, a2, e00, e11, e21))
    cos = _mn(cos, _corner(a0, a1, a2, e01, e10, e20))
    cos = _mn(cos, _corner(a0, a1, a2, e01, e10, e21))
    cos = _mn(cos, _corner(a0, a1, a2, e01, e11, e20))
    cos = _mn(cos, _corner(a0, a1, a2, e01, e11, e21))
    # np.clip to [-1, 1] (a NaN stays), then -1 inside
    cos = 1.0 if cos > 1.0 else cos
    cos = -1.0 if cos < -1.0 else cos
    return a0, a1, a2, -1.0 if inside else cos


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _corner(a0, a1, a2, c0, c1, c2):
    """The cosine between the axis and one corner's vector: ``dot / sqrt(sq)``."""
    dot = a0 * c0 + a1 * c1 + a2 * c2
    sq = c0 * c0 + c1 * c1 + c2 * c2
    return dot / np.sqrt(sq)


@njit(cache=True, nogil=True, error_model="numpy")
def cone_pick(o, box, u_pick, cones):
    """The cone each photon is drawn in: ``o`` (m, 3), or (1, 3) for one origin shared
    by all (a point light); ``box`` (6, K) the boxes (K >= 1: :func:`_cone`); ``u_pick``
    (m,); ``cones`` (len(o), 4, K) receives each origin's cones (axes, cosines) for
    :func:`cones_holding`. Returns the picked cone's index (m,) int64, axis (m, 3),
    cosine (m,) and the summed solid angles of all the cones (m,)."""
    m = u_pick.shape[0]
    k_n = np.uint64(box.shape[1])
    shared = o.shape[0] == 1
    pick = np.empty(m, dtype=np.int64)
    axis = np.empty((m, 3))
    cos = np.empty(m)
    total = np.empty(m)
    cum = np.empty(k_n)  # one photon's solid angles, then their running sums
    for i in range(m):
        r = 0 if shared else i
        if i == 0 or not shared:
            px, py, pz = o[r, 0], o[r, 1], o[r, 2]
            for k in range(k_n):  # (vectorized: no carried value)
                a0, a1, a2, c = _cone(px, py, pz, box, k)
                cones[r, 0, k], cones[r, 1, k], cones[r, 2, k], cones[r, 3, k] = a0, a1, a2, c
                cum[k] = _TWO_PI * (1.0 - c)
            for k in range(np.uint64(1), k_n):  # np.cumsum: one after another
                cum[k] = cum[k - np.uint64(1)] + cum[k]
        t = cum[k_n - np.uint64(1)]
        thr = u_pick[i] * t
        n = 0
        for k in range(k_n):
            n += 1 if cum[k] <= thr else 0
        p = min(n, np.int64(k_n) - 1)
        pick[i] = p
        axis[i, 0], axis[i, 1], axis[i, 2] = cones[r, 0, p], cones[r, 1, p], cones[r, 2, p]
        cos[i] = cones[r, 3, p]
        total[i] = t
    return pick, axis, cos, total


@njit(cache=True, nogil=True, error_model="numpy")
def cones_holding(cones, d, pick):
    """How many of the cones (:func:`cone_pick`'s ``cones``: one origin's for all, or
    one each) hold each direction ``d`` (m, 3); the picked one always, whatever the
    rounding: it holds its own draw."""
    m = d.shape[0]
    k_n = np.uint64(cones.shape[2])
    shared = cones.shape[0] == 1
    out = np.empty(m, dtype=np.int64)
    for i in range(m):
        r = 0 if shared else i
        d0, d1, d2 = d[i, 0], d[i, 1], d[i, 2]
        n = 0
        for k in range(k_n):
            n += 1 if d0 * cones[r, 0, k] + d1 * cones[r, 1, k] + d2 * cones[r, 2, k] >= cones[r, 3, k] else 0
        q = np.uint64(pick[i])
        held = d0 * cones[r, 0, q] + d1 * cones[r, 1, q] + d2 * cones[r, 2, q] >= cones[r, 3, q]
        out[i] = n + (0 if held else 1)
    return out
