"""The Ray-Triangle Intersection PM's test: Möller–Trumbore, eq. 3.6, over blocks of pairs.

Eq. 3.6 gives, with ``E1 = V1 - V0``, ``E2 = V2 - V0``, ``T = O - V0``,
``P = D x E2`` and ``Q = T x E1``::

    [t, u, v] = [Q.E2, P.T, Q.D] / (P.E1)

We evaluate the same four scalar triple products through their cyclic identities,
which lets the per-triangle part be computed once (``N = E1 x E2``) and the per-pair
part shrink to one cross product ``C = T x D``::

    P.E1 = -D.N      P.T = C.E2      Q.D = -C.E1      Q.E2 = T.N

The hardware has no branches and says yes or no at the end of the pipeline; so does
this code: a ray parallel to the triangle (``P.E1 = 0``) or a degenerate triangle
produces an infinite or NaN quotient, which every comparison rejects, and rejected
pairs get ``t = inf``. No epsilon on the determinant is needed, and nothing NaN is
returned. The barycentric edge tests carry a tolerance of ``EDGE_EPS`` (dimensionless)
so that a ray through a shared edge or vertex of a closed mesh always hits one of the
triangles that meet there (no leaks); it may then hit two at the same ``t``, and the
lower triangle id wins.

All functions here are array functions: one call tests a block of rays against a
block of triangles with numpy broadcasting, elementwise, so each pair's result is the
same whatever else is in the block (packet invariance, bit for bit).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EDGE_EPS = 1e-9


@dataclass(frozen=True)
class TriangleSoA:
    """Per-triangle constants of eq. 3.6, structure of arrays, each (m,) float64.

    ``v0`` is the first vertex, ``e2`` the edge ``V2 - V0``, ``e1n = -(V1 - V0)``,
    ``n = E1 x E2`` and ``nn = -n`` (signs folded in so the pair loop has no negation).
    ``ids`` are the triangle ids of the slots.
    """

    v0: tuple[np.ndarray, np.ndarray, np.ndarray]
    e1n: tuple[np.ndarray, np.ndarray, np.ndarray]
    e2: tuple[np.ndarray, np.ndarray, np.ndarray]
    n: tuple[np.ndarray, np.ndarray, np.ndarray]
    nn: tuple[np.ndarray, np.ndarray, np.ndarray]
    ids: np.ndarray

    @classmethod
    def from_triangles(cls, triangles: np.ndarray, ids: np.ndarray | None = None) -> TriangleSoA:
        """triangles : (m, 3, 3) float64; ids : (m,) int64 (default 0..m-1)."""
        tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        v0 = tri[:, 0]
        e1 = tri[:, 1] - v0
        e2 = tri[:, 2] - v0
        n = np.cross(e1, e2)

        def cols(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            a = np.ascontiguousarray(a.T)
            return a[0], a[1], a[2]

        if ids is None:
            ids = np.arange(tri.shape[0], dtype=np.int64)
        return cls(cols(v0), cols(-e1), cols(e2), cols(n), cols(-n), np.asarray(ids, np.int64))

    def take(self, index: np.ndarray) -> TriangleSoA:
        """The slots ``index`` (for example a BSP's leaf order) as a new SoA."""

        def sel(t: tuple[np.ndarray, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            return t[0][index], t[1][index], t[2][index]

        return TriangleSoA(
            sel(self.v0), sel(self.e1n), sel(self.e2), sel(self.n), sel(self.nn), self.ids[index]
        )


def closest_block(
    o: np.ndarray,
    d: np.ndarray,
    tmin: np.ndarray,
    tmax: np.ndarray,
    ignore: np.ndarray,
    tri: TriangleSoA,
    s0: int,
    s1: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Test rays against slots ``s0:s1`` of ``tri``; closest valid hit per ray.

    o, d : (r, 3) float64 origins and directions (any length; t is in units of d).
    tmin, tmax : (r,) float64, the open interval a hit must lie in.
    ignore : (r,) int64, a triangle id each ray must not hit (-1: none).

    Returns ``t`` (r,) (inf: no hit), ``slot`` (r,) int64 (index into ``tri``, -1 on
    no hit), ``u``, ``v`` (r,) barycentrics of the hit (0 on no hit).
    """
    r = o.shape[0]
    if r == 0 or s1 <= s0:
        return (
            np.full(r, np.inf),
            np.full(r, -1, dtype=np.int64),
            np.zeros(r),
            np.zeros(r),
        )
    ox, oy, oz = (o[:, i, None] for i in range(3))
    dx, dy, dz = (d[:, i, None] for i in range(3))
    sl = slice(s0, s1)
    v0x, v0y, v0z = (a[None, sl] for a in tri.v0)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        # T = O - V0
        tx = ox - v0x
        ty = oy - v0y
        tz = oz - v0z
        # det = P.E1 = -D.N
        nnx, nny, nnz = (a[None, sl] for a in tri.nn)
        rdet = dx * nnx
        rdet += dy * nny
        rdet += dz * nnz
        np.divide(1.0, rdet, out=rdet)
        # C = T x D
        cx = ty * dz - tz * dy
        cy = tz * dx - tx * dz
        cz = tx * dy - ty * dx
        # u = P.T / det = C.E2 / det
        e2x, e2y, e2z = (a[None, sl] for a in tri.e2)
        u = cx * e2x
        u += cy * e2y
        u += cz * e2z
        u *= rdet
        # v = Q.D / det = -C.E1 / det
        e1x, e1y, e1z = (a[None, sl] for a in tri.e1n)
        v = cx * e1x
        v += cy * e1y
        v += cz * e1z
        v *= rdet
        # t = Q.E2 / det = T.N / det
        nx, ny, nz = (a[None, sl] for a in tri.n)
        t = tx * nx
        t += ty * ny
        t += tz * nz
        t *= rdet
        ok = u >= -EDGE_EPS
        ok &= v >= -EDGE_EPS
        u_plus_v = u + v
        ok &= u_plus_v <= 1.0 + EDGE_EPS
        ok &= t > tmin[:, None]
        ok &= t < tmax[:, None]
        ok &= tri.ids[None, sl] != ignore[:, None]
    t = np.where(ok, t, np.inf)
    j = np.argmin(t, axis=1)
    rows = np.arange(r)
    best = t[rows, j]
    hit = best < np.inf
    slot = np.where(hit, j + s0, -1)
    return best, slot, np.where(hit, u[rows, j], 0.0), np.where(hit, v[rows, j], 0.0)


def any_block(
    o: np.ndarray,
    d: np.ndarray,
    tmin: np.ndarray,
    tmax: np.ndarray,
    ignore: np.ndarray,
    tri: TriangleSoA,
    s0: int,
    s1: int,
) -> np.ndarray:
    """Like :func:`closest_block` but only whether any valid hit exists: (r,) bool."""
    t, _, _, _ = closest_block(o, d, tmin, tmax, ignore, tri, s0, s1)
    return t < np.inf


def brute_force(
    origins: np.ndarray,
    directions: np.ndarray,
    triangles: np.ndarray,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
    ignore: np.ndarray | None = None,
    chunk: int = 1 << 18,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Closest hit of every ray against every triangle (the reference for tests).

    Returns ``t`` (r,), ``triangle`` (r,) int64 (-1 on a miss), ``u``, ``v``.
    """
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    r = o.shape[0]
    tmin = np.broadcast_to(np.asarray(tmin, dtype=np.float64), (r,))
    tmax = np.broadcast_to(np.asarray(tmax, dtype=np.float64), (r,))
    ignore = np.full(r, -1, np.int64) if ignore is None else np.asarray(ignore, np.int64)
    soa = TriangleSoA.from_triangles(triangles)
    m = soa.ids.shape[0]
    t = np.full(r, np.inf)
    tri = np.full(r, -1, dtype=np.int64)
    u = np.zeros(r)
    v = np.zeros(r)
    step = max(1, chunk // max(m, 1))
    for a in range(0, r, step):
        s = slice(a, a + step)
        t[s], slot, u[s], v[s] = closest_block(o[s], d[s], tmin[s], tmax[s], ignore[s], soa, 0, m)
        tri[s] = np.where(slot >= 0, soa.ids[np.maximum(slot, 0)], -1)
    return t, tri, u, v
