"""The Fragment PM's arithmetic: direct light with shadow rays, mirror and Snell directions.

* Lambertian direct light: ``L = albedo / pi * sum_lights E``. A point light of power
  ``P`` gives ``E = P / (4 pi) * cos / d**2``; a spot light the same times its falloff
  (:func:`~tlm.scenes.model.spot_falloff`) at the angle between its axis and the point (no
  shadow ray outside its outer cone); a directional light of irradiance ``E0`` gives
  ``E = E0 * cos``, its shadow ray going the other way along its direction, out of the scene
  (twice the scene's diagonal long); a quad light of power ``P`` and area
  ``A`` has radiance ``Le = P / (pi A)`` and is sampled with ``n x n`` stratified
  points, ``E ~= Le * A / S * sum cos_x cos_l / d**2``. A mesh light (emitting
  triangles) is sampled with ``n x n`` points too, stratified over the triangles'
  power CDF, each uniform on its triangle: ``E ~= 1 / S * sum Le_j cos_x cos_l / d**2 / pdf``
  with ``pdf = P_j / (P A_j)``. Each sample is one shadow ray (any-hit), cast only
  where both cosines are positive.
* Mirror: ``R = D - 2 (D.N) N``. Dielectric: Snell's law with total internal
  reflection (``k < 0``), entering when ``D.N < 0`` for the outward geometric normal,
  and the exact Fresnel reflectance of unpolarised light (:func:`scatter_specular`,
  which takes the directions about the interpolated shading normal and falls back to
  the geometric one where the shading normal would send a ray to the wrong side).
* Random numbers are a counter-based hash of (seed, pixel, stream, ...), so a pixel's
  samples never depend on which other pixels share its packet.

Secondary and shadow rays leave a surface with ``ignore`` set to the triangle they
leave (they can never re-hit it) and ``tmin`` a relative epsilon (scene diagonal x
``SPAWN_EPS``), so coplanar neighbours do not shadow their own surface.
"""

from __future__ import annotations

import math

import numpy as np

from tlm.kernels.engine import engine
from tlm.kernels.memory import PAGE_WORDS, Accesses
from tlm.kernels.recording import Recorder, traversal_accesses
from tlm.kernels.traverse import Counts, TriangleAccel, any_hit, closest_hit
from tlm.scenes.model import KIND, Light, spot_falloff
from tlm.scenes.normals import interpolate

TRAVERSAL_COUNTS = ("node_visits", "leaves_crossed", "leaf_visits", "tri_tests")
SPAWN_EPS = 1e-5  # relative to the scene diagonal: above float32 test error

_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)
_GOLD = np.uint64(0x9E3779B97F4A7C15)


def _mix(x: np.ndarray) -> np.ndarray:
    """splitmix64 finaliser on uint64 arrays (wrapping arithmetic)."""
    x = (x ^ (x >> np.uint64(30))) * _M1
    x = (x ^ (x >> np.uint64(27))) * _M2
    return x ^ (x >> np.uint64(31))


HASH_MIN_COMPILED = 64  # fewer numbers than this: the numpy code (a compiled call's fixed cost)


def hash_uniform(seed: int, *keys: np.ndarray | int) -> np.ndarray:
    """Uniform [0, 1) numbers, one per element of the broadcast ``keys`` (compiled,
    :mod:`tlm.kernels._jit_hash`, unless ``TLM_KERNELS=numpy``: the same numbers)."""
    arrays = [np.asarray(k, dtype=np.int64) for k in keys]
    shape = np.broadcast_shapes(*(a.shape for a in arrays))
    if arrays and math.prod(shape) >= HASH_MIN_COMPILED and engine() == "numba":
        from tlm.kernels import _jit_hash

        # each key broadcast straight into its row (no broadcast copy first)
        stacked = np.empty((len(arrays), *shape), dtype=np.int64)
        for row, a in zip(stacked, arrays, strict=True):
            row[...] = a
        return _jit_hash.hash_uniform(np.uint64(seed & 0xFFFFFFFFFFFFFFFF),
                                      stacked.reshape(len(arrays), -1)).reshape(shape)
    arrays = np.broadcast_arrays(*arrays)
    h = _mix(np.full(arrays[0].shape, np.uint64(seed & 0xFFFFFFFFFFFFFFFF)) + _GOLD)
    for k in arrays:
        h = _mix(h ^ (k.astype(np.uint64) * _GOLD))
    return (h >> np.uint64(11)).astype(np.float64) * (1.0 / (1 << 53))


def face_normals(triangles: np.ndarray) -> np.ndarray:
    """Unit geometric normals ``cross(V1 - V0, V2 - V0)`` (zero for degenerate triangles)."""
    n = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def facing(n: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Normals ``n`` (k, 3) turned to face the side rays of direction ``d`` arrive from."""
    return np.where((np.sum(n * d, axis=1) > 0)[:, None], -n, n)


def reflect(d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """Mirror direction of ``d`` about unit normal ``n`` (either orientation)."""
    return d - 2.0 * np.sum(d * n, axis=1, keepdims=True) * n


def refract(d: np.ndarray, n_out: np.ndarray, ior: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Snell refraction of unit ``d`` at a surface with outward unit normal ``n_out``.

    Returns the new unit direction and a mask of total internal reflection (where the
    returned direction is the mirror direction instead).
    """
    cos_dn = np.sum(d * n_out, axis=1)
    entering = cos_dn < 0.0
    eta = np.where(entering, 1.0 / ior, ior)
    n = np.where(entering[:, None], n_out, -n_out)
    cos_i = -np.sum(d * n, axis=1)
    k = 1.0 - eta * eta * (1.0 - cos_i * cos_i)
    tir = k < 0.0
    t = eta[:, None] * d + (eta * cos_i - np.sqrt(np.maximum(k, 0.0)))[:, None] * n
    out = np.where(tir[:, None], reflect(d, n), t)
    out /= np.linalg.norm(out, axis=1, keepdims=True)
    return out, tir


def fresnel_dielectric(cos_i: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact Fresnel reflectance of unpolarised light and the transmitted cosine.

    cos_i : (k,) cosine of incidence, >= 0. eta : (k,) ratio ``n_incident / n_transmitted``.
    Returns ``F`` (1 under total internal reflection; exactly 0 for ``eta == 1``) and
    ``cos_t`` (0 under total internal reflection).
    """
    sin2_t = eta * eta * np.maximum(0.0, 1.0 - cos_i * cos_i)
    tir = sin2_t >= 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    with np.errstate(divide="ignore", invalid="ignore"):
        rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t)
        rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t)
    f = np.where(tir, 1.0, np.nan_to_num(0.5 * (rs * rs + rp * rp), nan=1.0))
    return np.clip(f, 0.0, 1.0), np.where(tir, 0.0, cos_t)


def scatter_specular(d: np.ndarray, shading: np.ndarray, geometric: np.ndarray,
                     ior: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Mirror and Snell directions of unit rays ``d`` at a surface, and the Fresnel reflectance.

    shading, geometric : (k, 3) unit shading and geometric normals on the same side (either
    side: the side the ray arrives from decides entering or leaving, by the *geometric*
    normal). ior : (k,) the dielectric's index (None: a mirror, no refraction).
    Returns ``reflected`` (k, 3), ``refracted`` (k, 3) and ``F`` (k,) (1 for a mirror and
    under total internal reflection, where ``refracted`` is meaningless). A direction the
    shading normal would send to the wrong side of the geometric surface (a reflection
    into it, a refraction that stays outside) is taken about the geometric normal instead.
    """
    k = d.shape[0]
    front = np.sum(d * geometric, axis=1) < 0.0  # arriving on the side the normals point to
    ng = np.where(front[:, None], geometric, -geometric)  # towards the arriving side
    ns = np.where(front[:, None], shading, -shading)
    bad = np.sum(d * ns, axis=1) >= 0.0  # the shading normal faces away from the ray
    ns = np.where(bad[:, None], ng, ns)
    refl = reflect(d, ns)
    wrong = np.sum(refl * ng, axis=1) <= 0.0
    refl = np.where(wrong[:, None], reflect(d, ng), refl)
    if ior is None:
        return refl, np.zeros_like(d), np.ones(k)
    eta = np.where(front, 1.0 / ior, ior)  # entering through the geometric normal's side
    refr, f = _snell(d, ns, eta)
    stays = np.sum(refr * ng, axis=1) >= 0.0
    if stays.any():
        r2, f2 = _snell(d[stays], ng[stays], eta[stays])
        refr[stays], f[stays] = r2, f2
    return refl, refr, f


def _snell(d: np.ndarray, n: np.ndarray, eta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    cos_i = np.clip(-np.sum(d * n, axis=1), 0.0, 1.0)
    f, cos_t = fresnel_dielectric(cos_i, eta)
    t = eta[:, None] * d + (eta * cos_i - cos_t)[:, None] * n
    length = np.linalg.norm(t, axis=1, keepdims=True)
    t = np.divide(t, length, out=d.copy(), where=length > 0)
    return t, f



def final_gather_bounce(key: int, bounce: int, last: bool, j: np.ndarray, r: np.ndarray, owner: np.ndarray,
                        pkeys: np.ndarray, medium: np.ndarray, med: np.ndarray, w: np.ndarray, origin: np.ndarray,
                        d: np.ndarray, hits, seen: np.ndarray, table: dict[str, np.ndarray], fresnel: bool,
                        fragments: np.ndarray, specular_bounces: np.ndarray):
    """Final-gather rays ``(j, r)`` (gather point, ray index) of bounce ``bounce`` after their
    trace (``hits``; ``seen``: a light nearer than the hit, where the ray ends): the rays that
    end on a Lambertian surface, gathered there, and the rays that go on through a mirror or
    glass (one branch: glass reflects with the Fresnel probability by the ray's own hash,
    ``key`` and dimension ``2 + bounce``; ``last``: none goes on).

    owner, pkeys, medium : per gather point (its pixel, hash key and index of refraction).
    med, w, origin, d : per ray (the index around it, the weight its path carries, its origin
    and direction). table : the frame's per-triangle ``kind``, ``normals`` (unit geometric),
    ``shading`` (corner normals), ``reflectance``, ``transmittance`` and ``ior``.
    fragments, specular_bounces : per pixel, added to (a gather; a bounce that goes on).

    Returns the gathers ``(j, r, point, normal facing the arriving side, weight as it arrives:
    w (n_point / n_ray)^2, triangle)`` and the rays that go on ``(j, r, med, w, origin,
    direction, the triangle each leaves)``. Compiled unless ``TLM_KERNELS=numpy``
    (:mod:`tlm.kernels._jit_fgather`: the same bits).
    """
    kind, normals, ior = table["kind"], table["normals"], table["ior"]
    if engine() == "numba":
        from tlm.kernels import _jit_fgather

        return _jit_fgather.fg_bounce(
            np.uint64(key & 0xFFFFFFFFFFFFFFFF), bounce, last, j, r, owner, pkeys, medium, med, w, origin, d,
            hits.triangle, hits.t, hits.u, hits.v, seen, kind, normals, table["shading"], table["reflectance"],
            table["transmittance"], ior, KIND["lambertian"], KIND["mirror"], fresnel, fragments, specular_bounces)
    hit = (hits.triangle >= 0) & ~seen
    th = np.maximum(hits.triangle, 0)
    lam = hit & (kind[th] == KIND["lambertian"])
    x = origin + hits.t[:, None] * d
    # radiance over n^2 is what a path carries: from a point in a medium of index n_y, a
    # point in one of index n_x receives (n_x / n_y)^2 of it (the floor under water, seen
    # from above, 1 / n^2; the walls, seen from under the water, n^2)
    arrive = w * ((medium[j] / med) ** 2)[:, None]
    found = tuple(val[lam] for val in (j, r, x, facing(normals[th], d), arrive, hits.triangle))
    fragments += np.bincount(owner[found[0]], minlength=fragments.shape[0])
    go = hit & ~lam & (not last)
    ts, ds = hits.triangle[go], d[go]
    geo = normals[ts]
    ns = interpolate(table["shading"], ts, hits.u[go], hits.v[go], geo)
    mirror = kind[ts] == KIND["mirror"]
    refl, refr, f = scatter_specular(ds, ns, geo, np.where(mirror, 1.0, ior[ts]))
    if not fresnel:
        f = np.where(f < 1.0, 0.0, 1.0)
    j, r, med = j[go], r[go], med[go]
    take_refl = mirror | (hash_uniform(key, pkeys[j], r, 2 + bounce) < f)
    # a refraction enters the glass (against its outward normal) or leaves it, into air
    entering = np.sum(ds * geo, axis=1) < 0
    med = np.where(take_refl, med, np.where(entering, ior[ts], 1.0))
    w = w[go] * np.where(mirror[:, None], table["reflectance"][ts],
                         np.where(take_refl[:, None], 1.0, table["transmittance"][ts]))
    specular_bounces += np.bincount(owner[j], minlength=specular_bounces.shape[0])
    return found, (j, r, med, w, x[go], np.where(take_refl[:, None], refl, refr), ts)


def triangle_choice(light: Light, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Triangles of a mesh light picked by ``u`` in [0, 1) in proportion to their power
    (the sum of RGB ``Le * area``) and each pick's probability: (k,) int64, (k,) float64.

    The hardware would read an alias table (one table read and one compare a sample, as
    cheap as a quad light's two lerps); the inverse CDF here draws from the same
    distribution.
    """
    w = light.radiance.sum(axis=1) * light.areas
    cdf = np.cumsum(w)
    j = np.searchsorted(cdf, u * cdf[-1], side="right")
    j = np.minimum(j, w.shape[0] - 1)
    j = np.where(w[j] > 0, j, np.argmax(w))  # never a triangle of zero weight
    return j, w[j] / cdf[-1]


def point_on_triangles(tri: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Uniform points on triangles (k, 3, 3) from two uniforms each (k,)."""
    su = np.sqrt(u1)
    b0, b1 = 1.0 - su, u2 * su
    return b0[:, None] * tri[:, 0] + b1[:, None] * tri[:, 1] + (1.0 - b0 - b1)[:, None] * tri[:, 2]


def surface_emission(emission: np.ndarray | None, normals: np.ndarray, triangle: np.ndarray,
                     d: np.ndarray) -> np.ndarray | None:
    """(k, 3) radiance ``Le`` of emitting triangles that rays ``d`` hit on their front
    side (a mesh light seen directly), zero elsewhere; None when nothing emits.

    emission, normals : (n, 3) per-triangle ``Le`` and unit geometric normals;
    triangle : (k,) the rays' hit triangles (-1: a miss).
    """
    if emission is None:
        return None
    t = np.maximum(triangle, 0)
    front = (triangle >= 0) & (np.sum(normals[t] * d, axis=1) < 0)
    return np.where(front[:, None], emission[t], 0.0)


def dot3(v: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(k,) the dot products of the rows of ``v`` (k, 3) with ``w`` (3,), written out. ``v @ w``
    is a BLAS call (OpenBLAS's ``dgemv``) which, for more than some 200 rows, takes a buffer of
    OpenBLAS's (32 MiB of address space, mapped at the first call and at each call under way at
    once on the render's threads): under a limit on the address space (``ulimit -v``) a mapping
    that fails ends the process in OpenBLAS itself (``OpenBLAS error: Memory allocation still
    failed ...``, exit 1), where numpy's own allocation raises a MemoryError (``tlm: error: out
    of memory: ...``). Equal to ``v @ w`` up to rounding (OpenBLAS fuses the multiply-adds, as
    its kernel for the CPU does)."""
    return v[:, 0] * w[0] + v[:, 1] * w[1] + v[:, 2] * w[2]


def solve2(a: np.ndarray, r0: np.ndarray, r1: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(x0, x1)`` with ``a @ (x0, x1) = (r0, r1)`` for a 2x2 matrix ``a`` and (k,) right-hand
    sides: LAPACK's ``dgesv`` written out (an LU factorisation with partial pivoting, its
    reciprocals of the pivots, as OpenBLAS computes it), without its call: ``np.linalg.solve``
    takes OpenBLAS's buffer at every call, of any size (:func:`dot3`). Equal to it up to the rounding of
    OpenBLAS's fused multiply-adds; a singular ``a`` gives non-finite values, not a LinAlgError."""
    (a00, a01), (a10, a11) = (float(a[0, 0]), float(a[0, 1])), (float(a[1, 0]), float(a[1, 1]))
    if abs(a10) > abs(a00):  # (the larger pivot first: the rows swapped)
        a00, a01, a10, a11, r0, r1 = a10, a11, a00, a01, r1, r0
    inv00 = 1.0 / a00 if a00 != 0.0 else math.inf
    low = a10 * inv00
    u11 = a11 - low * a01
    x1 = (r1 - low * r0) * (1.0 / u11 if u11 != 0.0 else math.inf)
    return (r0 - a01 * x1) * inv00, x1


def emitted(lights: tuple[Light, ...], o: np.ndarray, d: np.ndarray, t_hit: np.ndarray,
            eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Radiance of quad lights seen directly along rays, where nearer than ``t_hit + eps``.

    Lights are not geometry; a ray sees a quad light's emitting side when it crosses
    the quad no farther than its surface hit. Returns (radiance (k, 3), seen (k,) bool).
    """
    k = o.shape[0]
    radiance = np.zeros((k, 3))
    seen = np.zeros(k, dtype=bool)
    quads = [light for light in lights if light.kind == "quad" and light.area != 0.0]
    if not quads:
        return radiance, seen
    best = t_hit
    dist_eps = eps / np.linalg.norm(d, axis=1)
    for light in quads:
        q = light.quad  # the light's arrays, Gram matrix and radiance, made once (tlm.scenes.model.QuadFrame)
        nl = light.normal
        dn = dot3(d, nl)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = dot3(q.corner - o, nl) / dn
        p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - q.corner
        # coordinates of p in the (eu, ev) frame
        with np.errstate(divide="ignore", invalid="ignore"):  # (a singular Gram matrix: no hit, as for NaN)
            a, b = solve2(q.gram, dot3(p, q.edge_u), dot3(p, q.edge_v))
        hit = (dn < 0) & (t > dist_eps) & (t <= best + dist_eps) & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)
        radiance[hit] = q.radiance
        seen |= hit
        best = np.where(hit, t, best)
    return radiance, seen


def direct_light(
    accel: TriangleAccel,
    lights: tuple[Light, ...],
    points: np.ndarray,
    normals: np.ndarray,
    triangles: np.ndarray,
    albedo: np.ndarray,
    keys: np.ndarray,
    seed: int,
    samples: int,
    eps: float,
    batch: int = 2,
    record: bool = False,
    page_words: int = PAGE_WORDS,
    geometric: np.ndarray | None = None,
    transparent: np.ndarray | None = None,
) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, Accesses] | None]:
    """Direct light reflected by Lambertian points, with one shadow ray per light sample.

    points, normals : (k, 3); normals (the shading normals) face the side being shaded.
    triangles : (k,) int64, the triangle each point lies on (shadow rays ignore it).
    geometric : (k, 3) the geometric normals facing the same side (default ``normals``):
        a sample is cast only where the light is in front of both, so that a shading
        normal never lets a surface light itself through its own back.
    transparent : (n_triangles, 3) per-triangle transmittance of the triangles a shadow
        ray passes through (index-matched dielectrics, ``ior == 1``: a straight line is
        a light path through them), zero for the rest; None when there are none. Such
        shadow rays are traced closest-hit, segment by segment (each segment counts as a
        shadow ray), and carry the product of the transmittances crossed.
    albedo : (k, 3). keys : (k,) int64 random-stream key of each point (pixel and bounce).
    Returns radiance (k, 3), per-point work: ``shadow_rays``, ``shadow_hits`` and the
    traversal counts of the shadow rays (``shadow_node_visits``, ...): the thesis traces
    shadow rays in passes of their own, so the timing model keeps them apart; and, with
    ``record``, the shadow rays' reads (:func:`~tlm.kernels.recording.traversal_accesses`:
    ``nodes``, ``indices``, ``vertices``, compacted for ``page_words``-word pages) with
    owner = the point, point-major (a point's rays light by light, sample by sample),
    else None.
    """
    k = points.shape[0]
    rec = Recorder(page_words) if record else None
    irradiance = np.zeros((k, 3))
    work = {name: np.zeros(k, dtype=np.int64) for name in
            ("shadow_rays", "shadow_hits", *(f"shadow_{c}" for c in TRAVERSAL_COUNTS))}
    g = round(np.sqrt(samples))
    for li, light in enumerate(lights):
        far = False  # a directional light: no distance falloff, the shadow ray leaves the scene
        if light.kind in ("point", "spot"):
            target = np.broadcast_to(np.asarray(light.position), (k, 1, 3))
            weight = np.full((k, 1), 1.0)
            scale = np.asarray(light.power) / (4.0 * np.pi)
            nl = None
        elif light.kind == "directional":
            # a point on the shadow ray twice the scene's diagonal away: past every triangle
            reach = 2.0 * accel.scale if accel.scale > 0 else 1.0
            target = (points - reach * light.axis[None, :])[:, None, :]
            weight = np.full((k, 1), 1.0)
            scale = np.asarray(light.irradiance, dtype=np.float64)
            nl = None
            far = True
        elif light.kind == "mesh":
            # stratified over the power CDF of the emitting triangles, a uniform point on each
            s = np.arange(g * g)
            ju = hash_uniform(seed, keys[:, None], 1, li, s[None, :], 0)
            pick = (s[None, :] + ju) / (g * g)
            j, prob = triangle_choice(light, pick.ravel())
            r1 = hash_uniform(seed, keys[:, None], 1, li, s[None, :], 1).ravel()
            r2 = hash_uniform(seed, keys[:, None], 1, li, s[None, :], 2).ravel()
            target = point_on_triangles(light.triangles[j], r1, r2).reshape(k, g * g, 3)
            weight = np.full((k, g * g), 1.0 / (g * g))
            # Le / pdf per sample, pdf = prob / area: RGB, per sample
            rgb = (light.radiance[j] * (light.areas[j] / prob)[:, None]).reshape(k, g * g, 3)
            scale = None
            nl = face_normals(light.triangles[j]).reshape(k, g * g, 3)
        else:
            s = np.arange(g * g)
            ju = hash_uniform(seed, keys[:, None], 1, li, s[None, :], 0)
            jv = hash_uniform(seed, keys[:, None], 1, li, s[None, :], 1)
            a = ((s % g)[None, :] + ju) / g
            b = ((s // g)[None, :] + jv) / g
            q = light.quad  # its corner and edges as arrays, made once
            target = q.corner[None, None, :] + a[..., None] * q.edge_u + b[..., None] * q.edge_v
            weight = np.full((k, g * g), 1.0 / (g * g))
            scale = np.asarray(light.power) / np.pi  # Le * A
            nl = light.normal
        dirs = target - points[:, None, :]
        dist2 = np.sum(dirs * dirs, axis=2)
        dist = np.sqrt(dist2)
        with np.errstate(divide="ignore", invalid="ignore"):
            if light.kind == "spot":  # the falloff about its axis of the direction from the light to the point
                ci, co = light.cone_cosines
                weight = np.where(dist2 > 0, spot_falloff(-(dirs @ light.axis) / dist, ci, co), 0.0)
            cos_x = np.sum(dirs * normals[:, None, :], axis=2) / dist
            if nl is None:
                cos_l = 1.0
            elif nl.ndim == 1:
                cos_l = -(dirs @ nl) / dist
            else:
                cos_l = -np.sum(dirs * nl, axis=2) / dist
            if far:  # E = irradiance x cos
                geo = np.where(dist2 > 0, weight * cos_x, 0.0)
            else:
                geo = np.where(dist2 > 0, weight * cos_x * cos_l / dist2, 0.0)
            front = np.sum(dirs * geometric[:, None, :], axis=2) > 0 if geometric is not None else True
        cast = (cos_x > 0) & front & (np.asarray(cos_l) > 0) & (dist2 > 0)
        if light.kind == "spot":
            cast &= weight > 0  # (outside its outer cone a spot sends nothing: no shadow ray)
        pi, si = np.nonzero(cast)
        if pi.shape[0] == 0:
            continue
        rel = eps / dist[pi, si]
        lit = np.zeros((*cast.shape, 3))
        if transparent is None:
            occ = any_hit(accel, points[pi], dirs[pi, si], tmin=rel, tmax=1.0 - rel,
                          ignore=triangles[pi], batch=batch, record=record)
            if rec is not None:
                for name, acc in traversal_accesses(occ.touched, accel.leaf_first, accel.leaf_last,
                                                    page_words).items():
                    rec.add(name, acc, pi)
            lit[pi, si] = (~occ.occluded)[:, None]
            _add_counts(work, pi, occ.counts)
            work["shadow_rays"] += np.bincount(pi, minlength=k)
            work["shadow_hits"] += np.bincount(pi[occ.occluded], minlength=k)
        else:
            lit[pi, si] = _transmitted(accel, points[pi], dirs[pi, si], rel, triangles[pi], pi, transparent,
                                       batch, work, rec, page_words)
        contrib = np.where(lit > 0, geo[..., None] * lit, 0.0)
        if scale is None:  # a mesh light: each sample's own Le / pdf
            contrib = np.where(lit > 0, contrib * rgb, 0.0)
        total = np.zeros((k, 3))
        for j in range(contrib.shape[1]):  # a fixed order per point: packet invariant
            total += contrib[:, j]
        irradiance += total if scale is None else total * scale[None, :]
    return albedo / np.pi * irradiance, work, (None if rec is None else rec.collect())


def _transmitted(accel: TriangleAccel, o: np.ndarray, d: np.ndarray, rel: np.ndarray, ignore: np.ndarray,
                 owner: np.ndarray, transparent: np.ndarray, batch: int, work: dict[str, np.ndarray],
                 rec: Recorder | None, page_words: int, max_segments: int = 64) -> np.ndarray:
    """(r, 3) transmittance of shadow rays ``o + t d``, t in (rel, 1 - rel), through the
    triangles with a non-zero ``transparent`` row; 0 where anything else blocks them.
    Each segment is one closest-hit shadow ray of point ``owner[i]``, counted as such."""
    r = o.shape[0]
    k = work["shadow_rays"].shape[0]
    out = np.ones((r, 3))
    live = np.arange(r)
    tmin, skip = rel.copy(), ignore.copy()
    tmax = 1.0 - rel
    for _ in range(max_segments):
        if live.shape[0] == 0:
            break
        hits = closest_hit(accel, o[live], d[live], tmin=tmin, tmax=tmax[live], ignore=skip, batch=batch,
                           record=rec is not None)
        if rec is not None:
            for name, acc in traversal_accesses(hits.touched, accel.leaf_first, accel.leaf_last, page_words).items():
                rec.add(name, acc, owner[live])
        _add_counts(work, owner[live], hits.counts)
        work["shadow_rays"] += np.bincount(owner[live], minlength=k)
        hit = hits.triangle >= 0
        tri = np.maximum(hits.triangle, 0)
        passes = hit & np.any(transparent[tri] > 0, axis=1)
        blocked = hit & ~passes
        work["shadow_hits"] += np.bincount(owner[live[blocked]], minlength=k)
        out[live[blocked]] = 0.0
        out[live[passes]] *= transparent[tri[passes]]
        live, tmin, skip = live[passes], hits.t[passes], hits.triangle[passes]
    out[live] = 0.0  # still crossing after max_segments: treated as blocked
    return out


def _add_counts(work: dict[str, np.ndarray], index: np.ndarray, counts: Counts) -> None:
    k = next(iter(work.values())).shape[0]
    for name in TRAVERSAL_COUNTS:
        work[f"shadow_{name}"] += np.bincount(index, weights=getattr(counts, name), minlength=k).astype(np.int64)
