"""The Fragment PM's arithmetic: direct light with shadow rays, mirror and Snell directions.

* Lambertian direct light: ``L = albedo / pi * sum_lights E``. A point light of power
  ``P`` gives ``E = P / (4 pi) * cos / d**2``; a quad light of power ``P`` and area
  ``A`` has radiance ``Le = P / (pi A)`` and is sampled with ``n x n`` stratified
  points, ``E ~= Le * A / S * sum cos_x cos_l / d**2``. Each sample is one shadow ray
  (any-hit), cast only where both cosines are positive.
* Mirror: ``R = D - 2 (D.N) N``. Dielectric: Snell's law with total internal
  reflection (``k < 0``), entering when ``D.N < 0`` for the outward geometric normal.
* Random numbers are a counter-based hash of (seed, pixel, stream, ...), so a pixel's
  samples never depend on which other pixels share its packet.

Secondary and shadow rays leave a surface with ``ignore`` set to the triangle they
leave (they can never re-hit it) and ``tmin`` a relative epsilon (scene diagonal x
``SPAWN_EPS``), so coplanar neighbours do not shadow their own surface.
"""

from __future__ import annotations

import numpy as np

from tlm.arch.cache import PAGE_WORDS, Accesses, Recorder, traversal_accesses
from tlm.kernels.traverse import Counts, TriangleAccel, any_hit
from tlm.scenes.model import Light

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


def hash_uniform(seed: int, *keys: np.ndarray | int) -> np.ndarray:
    """Uniform [0, 1) numbers, one per element of the broadcast ``keys``."""
    arrays = np.broadcast_arrays(*[np.asarray(k, dtype=np.int64) for k in keys])
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


def emitted(lights: tuple[Light, ...], o: np.ndarray, d: np.ndarray, t_hit: np.ndarray,
            eps: float) -> tuple[np.ndarray, np.ndarray]:
    """Radiance of quad lights seen directly along rays, where nearer than ``t_hit + eps``.

    Lights are not geometry; a ray sees a quad light's emitting side when it crosses
    the quad no farther than its surface hit. Returns (radiance (k, 3), seen (k,) bool).
    """
    k = o.shape[0]
    radiance = np.zeros((k, 3))
    seen = np.zeros(k, dtype=bool)
    best = t_hit.copy()
    for light in lights:
        if light.kind != "quad" or light.area == 0.0:
            continue
        nl = light.normal
        dn = d @ nl
        c = np.asarray(light.corner)
        eu, ev = np.asarray(light.edge_u), np.asarray(light.edge_v)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((c - o) @ nl) / dn
        p = o + np.where(np.isfinite(t), t, 0.0)[:, None] * d - c
        # coordinates of p in the (eu, ev) frame
        g = np.array([[eu @ eu, eu @ ev], [eu @ ev, ev @ ev]])
        a, b = np.linalg.solve(g, np.stack([p @ eu, p @ ev]))
        dist_eps = eps / np.linalg.norm(d, axis=1)
        hit = (dn < 0) & (t > dist_eps) & (t <= best + dist_eps) & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)
        le = np.asarray(light.power) / (np.pi * light.area)
        radiance[hit] = le
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
) -> tuple[np.ndarray, dict[str, np.ndarray], dict[str, Accesses] | None]:
    """Direct light reflected by Lambertian points, with one shadow ray per light sample.

    points, normals : (k, 3); normals face the side being shaded.
    triangles : (k,) int64, the triangle each point lies on (shadow rays ignore it).
    albedo : (k, 3). keys : (k,) int64 random-stream key of each point (pixel and bounce).
    Returns radiance (k, 3), per-point work: ``shadow_rays``, ``shadow_hits`` and the
    traversal counts of the shadow rays (``shadow_node_visits``, ...): the thesis traces
    shadow rays in passes of their own, so the timing model keeps them apart; and, with
    ``record``, the shadow rays' reads (:func:`~tlm.arch.cache.traversal_accesses`:
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
        if light.kind == "point":
            target = np.broadcast_to(np.asarray(light.position), (k, 1, 3))
            weight = np.full((k, 1), 1.0)
            scale = np.asarray(light.power) / (4.0 * np.pi)
            nl = None
        else:
            s = np.arange(g * g)
            ju = hash_uniform(seed, keys[:, None], 1, li, s[None, :], 0)
            jv = hash_uniform(seed, keys[:, None], 1, li, s[None, :], 1)
            a = ((s % g)[None, :] + ju) / g
            b = ((s // g)[None, :] + jv) / g
            target = (np.asarray(light.corner)[None, None, :] + a[..., None] * np.asarray(light.edge_u)
                      + b[..., None] * np.asarray(light.edge_v))
            weight = np.full((k, g * g), 1.0 / (g * g))
            scale = np.asarray(light.power) / np.pi  # Le * A
            nl = light.normal
        dirs = target - points[:, None, :]
        dist2 = np.sum(dirs * dirs, axis=2)
        dist = np.sqrt(dist2)
        with np.errstate(divide="ignore", invalid="ignore"):
            cos_x = np.sum(dirs * normals[:, None, :], axis=2) / dist
            cos_l = 1.0 if nl is None else -(dirs @ nl) / dist
            geo = np.where(dist2 > 0, weight * cos_x * cos_l / dist2, 0.0)
        cast = (cos_x > 0) & (np.asarray(cos_l) > 0) & (dist2 > 0)
        pi, si = np.nonzero(cast)
        if pi.shape[0] == 0:
            continue
        rel = eps / dist[pi, si]
        occ = any_hit(accel, points[pi], dirs[pi, si], tmin=rel, tmax=1.0 - rel,
                      ignore=triangles[pi], batch=batch, record=record)
        if rec is not None:
            for name, acc in traversal_accesses(occ.touched, accel.leaf_first, accel.leaf_last,
                                                page_words).items():
                rec.add(name, acc, pi)
        lit = np.zeros(cast.shape, dtype=bool)
        lit[pi, si] = ~occ.occluded
        contrib = np.where(lit, geo, 0.0)
        total = np.zeros(k)
        for j in range(contrib.shape[1]):  # a fixed order per point: packet invariant
            total += contrib[:, j]
        irradiance += total[:, None] * scale[None, :]
        _add_counts(work, pi, occ.counts)
        work["shadow_rays"] += np.bincount(pi, minlength=k)
        work["shadow_hits"] += np.bincount(pi[occ.occluded], minlength=k)
    return albedo / np.pi * irradiance, work, (None if rec is None else rec.collect())


def _add_counts(work: dict[str, np.ndarray], index: np.ndarray, counts: Counts) -> None:
    k = next(iter(work.values())).shape[0]
    for name in TRAVERSAL_COUNTS:
        work[f"shadow_{name}"] += np.bincount(index, weights=getattr(counts, name), minlength=k).astype(np.int64)
