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

Precision: the Intersection PM's datapath is 32-bit (a 96-bit vertex is three floats),
and so is the block test here: it decides *which* triangle a ray hits first in float32,
with vertices stored relative to the scene's centre. The hit's ``t``, ``u`` and ``v``
are then recomputed in float64 from eq. 3.6 for that one triangle (:func:`exact`).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np

EDGE_EPS = {np.dtype(np.float32): 2.0**-20, np.dtype(np.float64): 1e-9}


@dataclass(frozen=True)
class TriangleSoA:
    """Per-triangle constants of eq. 3.6, each a (3, m) array (rows x, y, z).

    ``v0`` is the first vertex relative to ``origin``, ``e2`` the edge ``V2 - V0``,
    ``e1n = -(V1 - V0)``, ``n = E1 x E2`` and ``nn = -n`` (signs folded in so the pair
    loop has no negation). ``ids`` are the triangle ids of the slots. The arrays are
    float32 for the Intersection PM's datapath (a 96-bit vertex is three 32-bit floats)
    or float64 for exact values; vertices are stored relative to ``origin`` (the
    scene's centre) so that a scene far from the world origin loses no precision.
    """

    v0: np.ndarray
    e1n: np.ndarray
    e2: np.ndarray
    n: np.ndarray
    nn: np.ndarray
    ids: np.ndarray
    origin: np.ndarray

    @classmethod
    def from_triangles(
        cls,
        triangles: np.ndarray,
        ids: np.ndarray | None = None,
        origin: np.ndarray | None = None,
        dtype: type = np.float64,
    ) -> TriangleSoA:
        """triangles : (m, 3, 3) float64; ids : (m,) int64 (default 0..m-1)."""
        tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        origin = np.zeros(3) if origin is None else np.asarray(origin, dtype=np.float64)
        v0 = tri[:, 0] - origin
        e1 = tri[:, 1] - tri[:, 0]
        e2 = tri[:, 2] - tri[:, 0]
        n = np.cross(e1, e2)
        if ids is None:
            ids = np.arange(tri.shape[0], dtype=np.int64)

        def rows(a: np.ndarray) -> np.ndarray:
            return np.ascontiguousarray(a.T, dtype=dtype)

        return cls(rows(v0), rows(-e1), rows(e2), rows(n), rows(-n), np.asarray(ids, np.int64), origin)

    @property
    def dtype(self) -> np.dtype:
        return self.v0.dtype

    def take(self, index: np.ndarray) -> TriangleSoA:
        """The slots ``index`` (for example a BSP's leaf order) as a new SoA."""
        return TriangleSoA(
            np.ascontiguousarray(self.v0[:, index]),
            np.ascontiguousarray(self.e1n[:, index]),
            np.ascontiguousarray(self.e2[:, index]),
            np.ascontiguousarray(self.n[:, index]),
            np.ascontiguousarray(self.nn[:, index]),
            self.ids[index],
            self.origin,
        )


class _Workspace:
    """Reused scratch for :func:`closest_slots`: no allocation per block.

    Each buffer is a contiguous (m, r) view, so that full-block operations run as one
    flat SIMD loop.
    """

    NAMES = ("tx", "ty", "tz", "cx", "cy", "cz", "rdet", "t", "tmp", "dx", "dy", "dz", "u", "v")

    def __init__(self) -> None:
        self.flat = np.empty(0, dtype=np.float32)
        self.key = np.empty(0, dtype=np.uint64)

    def views(self, m: int, r: int) -> tuple[np.ndarray, np.ndarray]:
        """A (k, m, r) float32 stack of buffers and an (m, r) uint64 key buffer."""
        size = m * r
        k = len(self.NAMES)
        if self.flat.shape[0] < k * size:
            self.flat = np.empty(max(k * size, 1 << 18), dtype=np.float32)
            self.key = np.empty(max(size, 1 << 15), dtype=np.uint64)
        return self.flat[: k * size].reshape(k, m, r), self.key[:size].reshape(m, r)


_LOCAL = threading.local()


def _workspace() -> _Workspace:
    """This thread's scratch: threads test blocks at once (``render.threads``), and a
    shared one would be overwritten under another thread's block."""
    ws = getattr(_LOCAL, "ws", None)
    if ws is None:
        ws = _LOCAL.ws = _Workspace()
    return ws


_NO_HIT = np.uint64(0x7F800000) << np.uint64(32)  # float32 +inf in the high word


def closest_slots(
    o: np.ndarray,
    d: np.ndarray,
    tmin: np.ndarray,
    tmax: np.ndarray,
    ignore: np.ndarray | None,
    tri: TriangleSoA,
    s0: int,
    s1: int,
    shared: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Which of slots ``s0:s1`` each ray hits first inside ``(tmin, tmax)``.

    o, d : (3, r) float32 origins (relative to ``tri.origin``) and directions;
        directions need not be unit (``t`` is in units of their length).
    shared : the rays share one origin by construction (eye rays) and ``o`` is (3, 1):
        ``T`` is then one column and ``u``, ``v`` are linear forms in ``D``. That path
        rounds differently from the general one, so the caller chooses it by ray kind,
        never by what a packet happens to contain (packet invariance): a lone ray with
        ``shared=False`` takes the general path.
    tmin, tmax : (r,) float32, ``0 <= tmin``. ignore : (r,) int64 triangle id each ray
        must not hit (-1: none), or None when no ray ignores anything.

    Returns ``slot`` (r,) int64, an index into ``tri`` (-1: no hit), and the hit
    distance ``t`` (r,) float32 (inf: no hit); among equal distances the lowest slot
    wins. The pairs form an (m, r) block, slot-major, so every numpy loop runs along
    the rays; scratch buffers are reused.

    The accept test is branch-free and mask-free: with ``t' = t - tmin`` and
    ``w = min(u, v, 1 - u - v) + eps``, the value ``copysign(t', min(w, t'))`` is
    negative, or NaN, exactly when the pair is rejected, and a negative or NaN float
    has its top bit set, so as an unsigned integer it sorts after every positive
    distance. The smallest ``(bits(t'), slot)`` key is the first hit.
    """
    r = d.shape[1]
    m = s1 - s0
    if r == 0 or m <= 0:
        return np.full(r, -1, dtype=np.int64), np.full(r, np.inf, dtype=np.float32)
    dt = np.float32
    eps = dt(EDGE_EPS[np.dtype(dt)])
    ox, oy, oz = o[0][None, :], o[1][None, :], o[2][None, :]
    dx, dy, dz = d[0][None, :], d[1][None, :], d[2][None, :]
    sl = slice(s0, s1)

    def col(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return a[0, sl, None], a[1, sl, None], a[2, sl, None]

    (tx, ty, tz, cx, cy, cz, rdet, t, tmp, dfx, dfy, dfz, u, v), key = _workspace().views(m, r)  # unpacks axis 0
    mul, add, sub, mn = np.multiply, np.add, np.subtract, np.minimum
    np.copyto(dfx, dx)  # D spread over the block: full-by-full products are faster
    np.copyto(dfy, dy)
    np.copyto(dfz, dz)
    dx, dy, dz = dfx, dfy, dfz
    if shared and o.shape[1] != 1:
        raise ValueError("shared=True takes one origin column")
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        v0x, v0y, v0z = col(tri.v0)
        nnx, nny, nnz = col(tri.nn)
        mul(dx, nnx, out=rdet)  # det = P.E1 = -D.N
        add(rdet, mul(dy, nny, out=tmp), out=rdet)
        add(rdet, mul(dz, nnz, out=tmp), out=rdet)
        np.divide(dt(1.0), rdet, out=rdet)
        nx, ny, nz = col(tri.n)
        e2x, e2y, e2z = col(tri.e2)
        e1x, e1y, e1z = col(tri.e1n)
        if shared:
            # T is one column; P.T = (E2 x T).D and Q.D = (-E1 x T).D are then linear
            # in D with per-slot coefficients, and T.N is per slot.
            tx, ty, tz = ox - v0x, oy - v0y, oz - v0z
            mul((tx * nx + ty * ny) + tz * nz, rdet, out=t)
            for (ax, ay, az), out in (((e2x, e2y, e2z), u), ((e1x, e1y, e1z), v)):
                kx, ky, kz = ay * tz - az * ty, az * tx - ax * tz, ax * ty - ay * tx
                mul(dx, kx, out=out)
                add(out, mul(dy, ky, out=tmp), out=out)
                add(out, mul(dz, kz, out=tmp), out=out)
                mul(out, rdet, out=out)
        else:
            sub(ox, v0x, out=tx)  # T = O - V0
            sub(oy, v0y, out=ty)
            sub(oz, v0z, out=tz)
            mul(tx, nx, out=t)  # t = Q.E2 / det = T.N / det
            add(t, mul(ty, ny, out=tmp), out=t)
            add(t, mul(tz, nz, out=tmp), out=t)
            mul(t, rdet, out=t)
            sub(mul(ty, dz, out=cx), mul(tz, dy, out=tmp), out=cx)  # C = T x D
            sub(mul(tz, dx, out=cy), mul(tx, dz, out=tmp), out=cy)
            sub(mul(tx, dy, out=cz), mul(ty, dx, out=tmp), out=cz)
            mul(cx, e2x, out=u)  # u = P.T / det = C.E2 / det
            add(u, mul(cy, e2y, out=tmp), out=u)
            add(u, mul(cz, e2z, out=tmp), out=u)
            mul(u, rdet, out=u)
            mul(cx, e1x, out=v)  # v = Q.D / det = -C.E1 / det
            add(v, mul(cy, e1y, out=tmp), out=v)
            add(v, mul(cz, e1z, out=tmp), out=v)
            mul(v, rdet, out=v)
        w = cz  # C is dead once u and v are known
        sub(dt(1.0), add(u, v, out=w), out=w)  # w = min(u, v, 1 - u - v) + eps
        mn(w, mn(u, v, out=tmp), out=w)
        add(w, eps, out=w)
        sub(t, tmin[None, :], out=t)  # t' = t - tmin
        mn(w, t, out=w)
        if ignore is not None:
            np.copyto(w, dt(-1.0), where=tri.ids[sl, None] == ignore[None, :])
        np.copysign(t, w, out=t)
    np.left_shift(t.view(np.uint32), np.uint32(32), out=key, dtype=np.uint64)
    key |= np.arange(m, dtype=np.uint64)[:, None]
    best = key.min(axis=0)
    t_best = (best >> np.uint64(32)).astype(np.uint32).view(np.float32) + tmin
    hit = (best < _NO_HIT) & (t_best < tmax)
    slot = np.where(hit, (best & np.uint64(0xFFFFFFFF)).astype(np.int64) + s0, -1)
    return slot, np.where(hit, t_best, np.float32(np.inf))


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of (3, k) row arrays."""
    return np.stack([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def exact(o: np.ndarray, d: np.ndarray, tri: TriangleSoA, slot: np.ndarray):
    """Eq. 3.6 in float64 for one (ray, slot) pair per row: ``t``, ``u``, ``v``.

    o : (k, 3) float64 origins relative to ``tri.origin``; d : (k, 3); slot : (k,) valid
    slots of a float64 ``tri``.
    """
    v0 = tri.v0[:, slot]
    e1 = -tri.e1n[:, slot]
    e2 = tri.e2[:, slot]
    tv = o.T - v0
    dd = d.T
    p = _cross(dd, e2)
    q = _cross(tv, e1)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / _dot(p, e1)
        t = _dot(q, e2) * inv
        u = _dot(p, tv) * inv
        v = _dot(q, dd) * inv
    return t, u, v


def check(
    o: np.ndarray, d: np.ndarray, tmin: np.ndarray, tmax: np.ndarray, tri: TriangleSoA, slot: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The float64 check of float32 choices: eq. 3.6 for one chosen slot per ray.

    o, d : (k, 3) float64 origins (relative to ``tri.origin``) and directions; tmin,
    tmax : (k,); slot : (k,) valid slots of the float64 ``tri``. Returns ``t``, ``u``,
    ``v`` and ``ok``: the choice stands when ``t`` lies strictly inside ``(tmin, tmax)``
    and the barycentrics within the float32 tolerance. Where it does not (a grazing
    hit that float32 put on the wrong side of ``tmax``, say), the caller decides again
    in float64 with :func:`closest_slots64`.
    """
    t, u, v = exact(o, d, tri, slot)
    eps = EDGE_EPS[np.dtype(np.float32)]
    with np.errstate(invalid="ignore"):
        ok = (t > tmin) & (t < tmax) & (u >= -eps) & (v >= -eps) & (u + v <= 1.0 + eps)
    return t, u, v, ok


def closest_slots64(
    o: np.ndarray,
    d: np.ndarray,
    tmin: np.ndarray,
    tmax: np.ndarray,
    ignore: np.ndarray | None,
    tri: TriangleSoA,
    s0: int,
    s1: int,
    shared: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`closest_slots` in float64, eq. 3.6 written out: the fallback of :func:`check`.

    Same arguments and results as :func:`closest_slots`, with float64 ``o`` (3, r) or
    (3, 1), ``d`` (3, r), ``tmin``, ``tmax`` and a float64 ``tri``. One path serves
    both shapes (broadcasting gives the same numbers), so ``shared`` changes nothing.
    """
    r = d.shape[1]
    if r == 0 or s1 <= s0:
        return np.full(r, -1, dtype=np.int64), np.full(r, np.inf)
    eps = EDGE_EPS[np.dtype(np.float64)]
    sl = slice(s0, s1)
    v0 = tri.v0[:, sl, None]
    e1 = -tri.e1n[:, sl, None]
    e2 = tri.e2[:, sl, None]
    dd = d[:, None, :]
    tv = o[:, None, :] - v0
    p = _cross(np.broadcast_to(dd, (3, s1 - s0, r)), e2)
    q = _cross(np.broadcast_to(tv, (3, s1 - s0, r)), e1)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = 1.0 / _dot(p, e1)
        t = _dot(q, e2) * inv
        u = _dot(p, tv) * inv
        v = _dot(q, dd) * inv
        ok = (u >= -eps) & (v >= -eps) & (u + v <= 1.0 + eps) & (t > tmin) & (t < tmax)
    if ignore is not None:
        ok &= tri.ids[sl, None] != ignore[None, :]
    t = np.where(ok, t, np.inf)
    j = np.argmin(t, axis=0)
    best = t[j, np.arange(r)]
    return np.where(np.isfinite(best), j + s0, -1), best


def scale_directions(d: np.ndarray, tmin: np.ndarray, tmax: np.ndarray):
    """Directions far outside float32's comfortable range, rescaled by exact powers of two.

    ``d`` (r, 3) float64. A row whose largest component is outside about [2**-32, 2**32]
    is multiplied by ``2**-e`` (its largest component then lies in [0.5, 1)) and its
    ``tmin``, ``tmax`` by ``2**e``, so the hit point ``o + t d`` is unchanged and a
    subnormal or huge direction is traced like any other. Other rows are untouched
    (bitwise); ``tmax`` is capped where ``t`` would leave float64's range. Returns
    ``d, tmin, tmax, e`` (e int (r,), 0 where untouched); the caller
    maps ``t`` back with :func:`unscale_t`.
    """
    _, e = np.frexp(np.abs(d).max(axis=1, initial=0.0))
    e = np.where(np.abs(e) > 32, e, 0)
    if not e.any():
        return d, tmin, tmax, e
    with np.errstate(over="ignore", under="ignore"):
        # a hit whose distance would leave float64's range is no hit, for any_hit too
        tmax = np.minimum(np.ldexp(tmax, e), np.ldexp(np.finfo(np.float64).max, e))
        return np.ldexp(d, -e[:, None]), np.ldexp(tmin, e), tmax, e


def unscale_t(t: np.ndarray, e: np.ndarray) -> np.ndarray:
    """``t`` measured along a direction rescaled by :func:`scale_directions`, back in
    units of the caller's direction (inf where it leaves float64's range)."""
    if not e.any():
        return t
    with np.errstate(over="ignore", under="ignore"):
        return np.ldexp(t, -e)


def lossy32(x: np.ndarray, x32_t: np.ndarray) -> np.ndarray:
    """Rows of ``x`` (r, 3; float64) whose float32 copy ``x32_t`` (3, r) lost more than a
    float32 rounding relative to the row's largest component (overflow to inf, flush to 0)."""
    with np.errstate(invalid="ignore", over="ignore"):
        err = np.abs(x32_t.T.astype(np.float64) - x).max(axis=1)
        big = np.abs(x).max(axis=1)
        return ~(err <= 2.0**-22 * big)


def brute_force(
    origins: np.ndarray,
    directions: np.ndarray,
    triangles: np.ndarray,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
    ignore: np.ndarray | None = None,
    chunk: int = 1 << 16,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Closest hit of every ray against every triangle, without a tree (for tests).

    Returns ``t`` (r,), ``triangle`` (r,) int64 (-1 on a miss), ``u``, ``v``.
    """
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    r = o.shape[0]
    tmin = np.broadcast_to(np.asarray(tmin, dtype=np.float64), (r,))
    tmax = np.broadcast_to(np.asarray(tmax, dtype=np.float64), (r,))
    d, tmin, tmax, scale = scale_directions(d, tmin, tmax)
    ignore = None if ignore is None else np.asarray(ignore, np.int64)
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    origin = 0.5 * (tri.reshape(-1, 3).min(axis=0) + tri.reshape(-1, 3).max(axis=0)) if tri.size else None
    soa = TriangleSoA.from_triangles(tri, origin=origin, dtype=np.float32)
    soa64 = TriangleSoA.from_triangles(tri, origin=origin)
    o = o - soa64.origin
    m = soa.ids.shape[0]
    slot = np.full(r, -1, dtype=np.int64)
    step = max(1, chunk // max(m, 1))
    for a in range(0, r, step):
        s = slice(a, a + step)
        ign = None if ignore is None else ignore[s]
        slot[s], _ = closest_slots(
            o[s].T.astype(np.float32), d[s].T.astype(np.float32), tmin[s].astype(np.float32),
            tmax[s].astype(np.float32), ign, soa, 0, m,
        )
    t, u, v = np.full(r, np.inf), np.zeros(r), np.zeros(r)
    hit = np.flatnonzero(slot >= 0)
    t[hit], u[hit], v[hit], ok = check(o[hit], d[hit], tmin[hit], tmax[hit], soa64, slot[hit])
    bad = hit[~ok]
    with np.errstate(over="ignore"):
        lossy = lossy32(d, d.T.astype(np.float32)) | lossy32(o, o.T.astype(np.float32))
    if lossy.any():  # rays float32 cannot carry (see ``lossy32``) are tested in float64
        bad = np.union1d(bad, np.flatnonzero(lossy))
    if bad.shape[0]:
        ign = None if ignore is None else ignore[bad]
        slot[bad], _ = closest_slots64(o[bad].T, d[bad].T, tmin[bad], tmax[bad], ign, soa64, 0, m)
        t[bad], u[bad], v[bad] = np.inf, 0.0, 0.0
        redo = bad[slot[bad] >= 0]
        t[redo], u[redo], v[redo], _ = check(o[redo], d[redo], tmin[redo], tmax[redo], soa64, slot[redo])
    t = unscale_t(t, scale)
    slot = np.where(np.isfinite(t), slot, -1)
    u, v = np.where(slot >= 0, u, 0.0), np.where(slot >= 0, v, 0.0)
    return t, np.where(slot >= 0, soa.ids[np.maximum(slot, 0)], -1), u, v
