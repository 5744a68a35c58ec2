"""Photon emission (thesis §III.A, Fig. 4): where the photons of the photon map start.

The photon count is shared among the lights in proportion to the power they emit
(:attr:`~tlm.scenes.model.Light.flux`); each photon of light ``l`` carries ``P_l / N_l``. A
quad light emits from a uniform point on the quad in a cosine-weighted direction about its
normal; a point light uniformly over the sphere; a spot light within its outer cone in
proportion to its falloff (:func:`spot_directions`), so its photons carry equal parts of the
flux it emits; a directional light from uniform points on the disc that covers the scene's
bounding sphere, perpendicular to its direction and just outside the sphere
(:data:`~tlm.scenes.model.DISC_MARGIN`), each photon ``irradiance x pi R^2 / N``. With
mirrors or dielectrics, a *caustic group* of each light's photons
(``photons.caustic_fraction`` of them, or a budget of its own,
``photons.caustic_count``, beside ``count``) is aimed at the specular objects, its
power divided by the aiming density so the estimate stays unbiased (Jensen's
projection maps): ``photons.aim: parts`` cuts each specular part into boxes of at
most ``aim_triangles`` triangles (:func:`aim_boxes`) and draws a direction from the
mixture of the cones bounding them, a cone in proportion to its solid angle
(:func:`cone_mixture`); ``box`` (the thesis study's) one cone about every specular
triangle, which wastes most photons when the objects lie apart. A spot's caustic
photons are drawn from where its outer cone and those cones meet (:func:`spot_aimed`), so a
narrow spot wastes none on the parts of the cones it does not light.

Random numbers: a counter-based hash (:func:`tlm.kernels.shade.hash_uniform`) keyed by
:func:`photon_key` of the run's seed and indexed by (photon, light, dimension), so every
photon's start is the same whichever photons it is emitted with. Tracing them is
:mod:`tlm.kernels.photons`.
"""

from __future__ import annotations

import math

import numpy as np

from tlm.kernels import threads
from tlm.kernels.engine import engine
from tlm.kernels.shade import face_normals, hash_uniform, point_on_triangles, triangle_choice
from tlm.scenes.model import DISC_MARGIN, KIND, Light, bounding_sphere, directional_power, spot_falloff


def photon_key(seed: int) -> int:
    """The hash key of a run's photon streams, from a SeedSequence of its seed."""
    return int(np.random.SeedSequence([seed, 0x9E0704]).generate_state(1, dtype=np.uint64)[0] >> 1)


def split_photons(lights: tuple[Light, ...], n: int, box: tuple[np.ndarray, np.ndarray] | None = None
                  ) -> np.ndarray:
    """Photons per light in proportion to the power it emits (:attr:`~tlm.scenes.model.Light.flux`:
    a spot's is less than its ``power``; a directional light's, given the scene's ``box``, its
    irradiance over the disc covering the box's bounding sphere, as :func:`emit` emits it)
    (largest remainder), (len(lights),) int."""
    weight = np.array([sum(directional_power(lt.irradiance, *box)) if lt.kind == "directional" and box is not None
                       else sum(lt.flux) for lt in lights], dtype=np.float64)
    if n <= 0 or weight.sum() <= 0:
        return np.zeros(len(lights), dtype=np.int64)
    share = weight / weight.sum() * n
    count = np.floor(share).astype(np.int64)
    rest = n - int(count.sum())
    order = np.argsort(-(share - count), kind="stable")
    count[order[:rest]] += 1
    return count


def _frame(n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit tangents completing unit normals ``n`` (k, 3) to an orthonormal frame."""
    a = np.where(np.abs(n[:, :1]) > 0.9, np.array([[0.0, 1.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]))
    t = np.cross(n, a)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    return t, np.cross(n, t)


def _around(axis: np.ndarray, cos_t: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit directions at polar cosine ``cos_t`` and azimuth ``phi`` about unit ``axis``
    (compiled from float64 inputs unless ``TLM_KERNELS=numpy``: the same bits, but for the
    sign or payload of a NaN; the sines and cosines stay numpy's,
    :func:`tlm.kernels._jit_photons.around`)."""
    if (engine() == "numba" and axis.dtype == np.float64 and cos_t.dtype == np.float64 and phi.dtype == np.float64
            and axis.ndim == 2 and axis.shape[1] == 3 and cos_t.shape == phi.shape == axis.shape[:1]):
        from tlm.kernels import _jit_photons

        return _jit_photons.around(np.ascontiguousarray(axis), cos_t, np.cos(phi), np.sin(phi))
    t, b = _frame(axis)
    s = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    d = (s * np.cos(phi))[:, None] * t + (s * np.sin(phi))[:, None] * b + cos_t[:, None] * axis
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def cosine_directions(n: np.ndarray, u1: np.ndarray, u2: np.ndarray) -> np.ndarray:
    """Cosine-weighted unit directions about unit normals ``n`` (k, 3)."""
    return _around(n, np.sqrt(np.maximum(0.0, 1.0 - u1)), 2.0 * np.pi * u2)


def bounding_cone(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, float]:
    """Axis and cosine of the half-angle of a cone from ``p`` holding the box [lo, hi].

    A point inside the box sees all of it: the whole sphere (cosine -1).
    """
    if np.all(p >= lo) and np.all(p <= hi):
        return np.array([0.0, 0.0, 1.0]), -1.0
    centre = 0.5 * (lo + hi)
    axis = centre - p
    axis /= np.linalg.norm(axis)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    to = corners - p
    cos = (to @ axis) / np.linalg.norm(to, axis=1)
    return axis, float(max(-1.0, min(cos.min(), 1.0)))


def bounding_cones(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`bounding_cone` of every point of ``p`` (m, 3): axes (m, 3) and cosines (m,)."""
    centre = 0.5 * (lo + hi)
    axis = centre[None, :] - p
    length = np.linalg.norm(axis, axis=1, keepdims=True)
    axis = np.divide(axis, length, out=np.tile([0.0, 0.0, 1.0], (p.shape[0], 1)), where=length > 0)
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    to = corners[None, :, :] - p[:, None, :]
    dist = np.linalg.norm(to, axis=2)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = np.sum(to * axis[:, None, :], axis=2) / dist
    cos = np.where(dist > 0, cos, -1.0).min(axis=1)
    inside = np.all((p >= lo) & (p <= hi), axis=1)
    return axis, np.where(inside, -1.0, np.clip(cos, -1.0, 1.0))


def _box_cones(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """:func:`box_cones` with the axes as three (m, K) components (no reductions over
    short axes: the eight corners' dot products and squared lengths are sums of one
    term per coordinate, ``lo`` or ``hi``, kept on leading axes)."""
    e = [np.stack([lo[None, :, j] - p[:, j, None], hi[None, :, j] - p[:, j, None]]) for j in range(3)]
    a = [0.5 * (x[0] + x[1]) for x in e]  # centre - p
    length = np.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    inside = (e[0][0] <= 0) & (e[0][1] >= 0) & (e[1][0] <= 0) & (e[1][1] >= 0) & (e[2][0] <= 0) & (e[2][1] >= 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / length
        a = [np.where(length > 0, x * inv, float(j == 2)) for j, x in enumerate(a)]
        dot = (a[0] * e[0])[:, None, None] + (a[1] * e[1])[None, :, None] + (a[2] * e[2])[None, None, :]
        sq = (e[0] * e[0])[:, None, None] + (e[1] * e[1])[None, :, None] + (e[2] * e[2])[None, None, :]
        cos = (dot / np.sqrt(sq)).reshape((8, *length.shape)).min(axis=0)
    # a point on a corner (0 / 0) or at the centre is in the box: the whole sphere
    return tuple(a), np.where(inside, -1.0, np.clip(cos, -1.0, 1.0))


def box_cones(p: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`bounding_cone` of every box [lo_k, hi_k] (``lo``, ``hi``: (K, 3)) from every
    point of ``p`` (m, 3): axes (m, K, 3) and cosines (m, K) (-1 where the point is in the box)."""
    a, cos = _box_cones(p, lo, hi)
    return np.stack(a, axis=-1), cos


def aim_boxes(triangles: np.ndarray, kind: np.ndarray, part: np.ndarray, aim_triangles: int = 64) -> np.ndarray:
    """The boxes a caustic group aims at (``photons.aim: parts``): (K, 2, 3) lo/hi.

    The specular triangles (``kind`` != Lambertian, one code a triangle) of each scene
    part (``part``, one index a triangle; parts in increasing order) are cut recursively
    at the median of their centroids along the longest axis of their box, until a box
    holds at most ``aim_triangles`` triangles (depth first, lower half first).
    """
    if aim_triangles < 1:
        raise ValueError(f"aim_triangles (={aim_triangles}) must be >= 1")
    spec = np.asarray(kind) != KIND["lambertian"]
    part = np.asarray(part)
    out: list[np.ndarray] = []

    def cut(tri: np.ndarray) -> None:
        v = tri.reshape(-1, 3)
        lo, hi = v.min(axis=0), v.max(axis=0)
        if tri.shape[0] <= aim_triangles:
            out.append(np.stack([lo, hi]))
            return
        order = np.argsort(tri[:, :, int(np.argmax(hi - lo))].mean(axis=1), kind="stable")
        half = tri.shape[0] // 2
        cut(tri[order[:half]])
        cut(tri[order[half:]])

    for p in np.unique(part[spec]).tolist():
        cut(triangles[spec & (part == p)])
    return np.array(out, dtype=np.float64).reshape(-1, 2, 3)


CONE_CHUNK = 1 << 16  # photons x boxes a chunk of cone mixture sampling holds (memory and speed only)
# photons x boxes a chunk of the compiled cone mixture holds (memory and speed only): their
# cones, 32 bytes each, between the pick and the count of the cones holding the draw
CONE_CHUNK_COMPILED = 1 << 17


def cone_mixture(o: np.ndarray, boxes: np.ndarray, u_pick: np.ndarray, u_cos: np.ndarray,
                 u_phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Directions from a mixture of the cones bounding ``boxes`` (K, 2, 3) and their 1 / pdf.

    ``o``: the origins, (m, 3), or (1, 3) for one shared by all (a point light); ``u_*``:
    (m,) uniforms. Cone k (:func:`box_cones`) is picked with probability
    ``Omega_k / sum Omega`` (``Omega = 2 pi (1 - cos_max)``, its solid angle), the
    direction is uniform in it; the density of the mixture is ``#{k: d in cone k} / sum
    Omega``, so where cones overlap a direction is not counted twice. Returns (m, 3) unit
    directions and (m,) ``sum Omega / #cones holding d`` (steradians).
    """
    m = u_pick.shape[0]
    if o.ndim != 2 or o.shape[1] != 3 or o.shape[0] not in (1, m) or boxes.ndim != 3 or boxes.shape[1:] != (2, 3):
        raise ValueError(f"cone_mixture: origins {o.shape} and boxes {boxes.shape} for {m} photons "
                         f"(expected (1, 3) or ({m}, 3), and (K, 2, 3))")
    lo, hi = boxes[:, 0], boxes[:, 1]
    k_n = boxes.shape[0]
    d = np.empty((m, 3))
    inv_pdf = np.empty(m)
    shared = o.shape[0] == 1
    # (float64 only: the numpy code computes in its inputs' type; emit's are float64)
    if k_n and o.dtype == np.float64 and boxes.dtype == np.float64 and engine() == "numba":
        _cone_mixture_compiled(o, lo, hi, u_pick, u_cos, u_phi, d, inv_pdf)
        return d, inv_pdf
    if shared:
        cones = _box_cones(o, lo, hi)
    step = max(1, CONE_CHUNK // max(k_n, 1))

    def chunk(s: int) -> None:  # photons s .. e - 1, each on its own: chunks run on the threads
        e = min(m, s + step)
        a, cos = cones if shared else _box_cones(o[s:e], lo, hi)  # (1 or e - s, K) each
        cum = np.cumsum(2.0 * np.pi * (1.0 - cos), axis=1)  # solid angles, summed
        total = cum[:, -1]
        pick = np.minimum(np.sum(cum <= (u_pick[s:e] * total)[:, None], axis=1), k_n - 1)
        row = np.zeros(e - s, dtype=np.int64) if shared else np.arange(e - s)
        c = cos[row, pick]
        dd = _around(np.stack([x[row, pick] for x in a], axis=1), 1.0 - u_cos[s:e] * (1.0 - c),
                     2.0 * np.pi * u_phi[s:e])
        holds = dd[:, 0, None] * a[0] + dd[:, 1, None] * a[1] + dd[:, 2, None] * a[2] >= cos
        holds[np.arange(e - s), pick] = True  # the picked cone holds d, whatever the rounding
        d[s:e] = dd
        inv_pdf[s:e] = total[row] / holds.sum(axis=1)

    for _ in threads.ordered(chunk, range(0, m, step)):
        pass
    return d, inv_pdf


def _cone_mixture_compiled(o, lo, hi, u_pick, u_cos, u_phi, d, inv_pdf) -> None:
    """:func:`cone_mixture` with the cones compiled (:mod:`tlm.kernels._jit_cones`: the
    same values from float64 inputs), into ``d`` and ``inv_pdf``; chunks of photons run
    on the threads."""
    from tlm.kernels import _jit_cones

    m, k_n = u_pick.shape[0], lo.shape[0]
    o = np.ascontiguousarray(o)
    box = np.ascontiguousarray(np.concatenate([lo.T, hi.T]))  # (6, K): a row per coordinate
    u_pick = np.ascontiguousarray(u_pick, dtype=np.float64)
    # chunks of at most CONE_CHUNK_COMPILED photons x boxes, about four a thread (speed only:
    # each photon's numbers are its own)
    step = max(1, min(CONE_CHUNK_COMPILED // k_n, -(-m // (4 * threads.current()))))

    def chunk(s: int) -> None:
        e = min(m, s + step)
        oc = o if o.shape[0] == 1 else o[s:e]
        cones = np.empty((oc.shape[0], 4, k_n))  # each origin's cones, between the two calls
        pick, axis, c, total = _jit_cones.cone_pick(oc, box, u_pick[s:e], cones)
        dd = _around(axis, 1.0 - u_cos[s:e] * (1.0 - c), 2.0 * np.pi * u_phi[s:e])
        d[s:e] = dd
        inv_pdf[s:e] = total / _jit_cones.cones_holding(cones, dd, pick)

    for _ in threads.ordered(chunk, range(0, m, step)):
        pass


def spot_directions(axis: np.ndarray, cos_inner: float, cos_outer: float, u_cos: np.ndarray,
                    u_phi: np.ndarray) -> np.ndarray:
    """Unit directions about a spot's unit ``axis`` drawn in proportion to its falloff
    (:func:`~tlm.scenes.model.spot_falloff`), so that every photon carries the same power: the
    inner cap (uniform in the cosine) with probability ``(1 - ci) / S``, else the ring between
    the cones with the cosine ``co + (ci - co) v**(1/3)`` (the density of the falloff's square),
    where ``S = 1 - ci + (ci - co) / 3``."""
    ci, co = cos_inner, cos_outer
    total = (1.0 - ci) + (ci - co) / 3.0
    p_in = (1.0 - ci) / total
    inner = u_cos < p_in
    with np.errstate(divide="ignore", invalid="ignore"):
        c_in = 1.0 - (u_cos / p_in) * (1.0 - ci)
        c_ring = co + (ci - co) * np.cbrt((u_cos - p_in) / (1.0 - p_in))
    cos_t = np.where(inner, c_in, c_ring)
    return _around(np.broadcast_to(axis, (u_cos.shape[0], 3)).copy(), cos_t, 2.0 * np.pi * u_phi)


def cap_overlap(cos_a: np.ndarray, cos_b: float, cos_g: np.ndarray) -> np.ndarray:
    """The solid angle (steradians) the spherical caps of half-angles ``a`` (one a cap, (K,))
    and ``b`` share, their axes ``g`` apart, from the cosines: 0 when they are apart, the
    smaller cap when one holds the other, ``4 pi`` less the two caps' complements when those
    are apart, else Mazonka's closed form (2012, "Solid angle of conical surfaces, polyhedral
    cones, and intersecting spherical caps", eq. 41)."""
    a, g = np.arccos(np.clip(cos_a, -1.0, 1.0)), np.arccos(np.clip(cos_g, -1.0, 1.0))
    b = math.acos(min(1.0, max(-1.0, cos_b)))
    ca, cb, cg = np.cos(a), math.cos(b), np.cos(g)
    sa, sb, sg = np.sin(a), math.sin(b), np.sin(g)
    with np.errstate(divide="ignore", invalid="ignore"):  # (the cases that divide by 0 are the others)
        x0 = np.arccos(np.clip((cg - ca * cb) / (sa * sb), -1.0, 1.0))
        x1 = np.arccos(np.clip((cb - cg * ca) / (sg * sa), -1.0, 1.0))
        x2 = np.arccos(np.clip((ca - cg * cb) / (sg * sb), -1.0, 1.0))
        part = 2.0 * (np.pi - x0 - ca * x1 - cb * x2)
    cap_a, cap_b = 2.0 * np.pi * (1.0 - ca), 2.0 * np.pi * (1.0 - cb)
    return np.where(g >= a + b, 0.0, np.where(g <= np.abs(a - b), np.minimum(cap_a, cap_b),
                                              np.where(g >= 2.0 * np.pi - a - b, cap_a + cap_b - 4.0 * np.pi,
                                                       np.clip(part, 0.0, np.minimum(cap_a, cap_b)))))


SPOT_DRAWS = 32  # draws a spot's caustic photon may take to fall inside its lens (one aim cone and its outer cone)
# photons a chunk of a spot's caustic draws holds (memory and speed only: each photon's numbers are its own)
SPOT_CHUNK = 1 << 15
LENS_MARGIN = 1e-7  # radians the sector bounding a lens is widened by on every side (against rounding only)


def lens_sectors(axis: np.ndarray, cos_outer: float, cone_axes: np.ndarray, cone_cos: np.ndarray
                 ) -> tuple[np.ndarray, ...]:
    """For each aim cone k (unit ``cone_axes`` (K, 3), cosines ``cone_cos`` (K,)), the *lens*
    it shares with a spot's outer cone (unit ``axis``, ``cos_outer``), and a region on the
    sphere that holds the lens and that directions are drawn from uniformly: the sector
    ``theta_lo <= theta <= theta_hi``, ``|phi| <= Phi`` about the axis ``s`` of the smaller
    of the two cones (its half-angle ``sigma``), ``phi`` measured from the direction towards
    the other's axis ``o`` (``gamma`` from ``s``; its half-angle ``omega``). The lens lies
    within ``gamma - omega <= theta <= min(sigma, gamma + omega)`` (the triangle inequality),
    and at ``theta`` within ``|phi| <= acos(t(theta))``, ``t = (cos omega - cos theta cos gamma)
    / (sin theta sin gamma)`` (the spherical law of cosines), whose least ``t`` on that range is
    at an end or where ``cos theta = cos gamma / cos omega`` (``dt/dtheta = 0``); ``Phi = pi``
    when ``s`` is inside the other cone. The sector holds the lens with room to spare of a
    fraction of it, not of a whole cone: a draw falls in the lens with a chance of 0.39 or
    more in the pairs of cones tried (narrow and wide, apart, cutting, one inside the other,
    slivers), however narrow the spot.

    Returns (K,) arrays: the lens's solid angle (:func:`cap_overlap`; 0: cone k misses the
    spot's cone), ``s`` (K, 3), ``psi``: the azimuth of ``o`` about ``s`` in the frame
    :func:`_around` turns azimuths into directions with, ``1 - cos`` of ``theta_lo`` and
    ``theta_hi``, ``Phi`` and the sector's solid angle ``2 Phi (cos theta_lo - cos theta_hi)``."""
    k_n = cone_cos.shape[0]
    lens = np.asarray(cap_overlap(cone_cos, cos_outer, cone_axes @ axis), dtype=np.float64).reshape(k_n)
    spot_smaller = (1.0 - cos_outer) <= (1.0 - cone_cos)
    s = np.where(spot_smaller[:, None], axis[None, :], cone_axes)
    o = np.where(spot_smaller[:, None], cone_axes, axis[None, :])
    sigma = np.arccos(np.clip(np.where(spot_smaller, cos_outer, cone_cos), -1.0, 1.0))
    omega = np.arccos(np.clip(np.where(spot_smaller, cone_cos, cos_outer), -1.0, 1.0))
    across = np.cross(s, o)
    sin_g = np.linalg.norm(across, axis=1)
    gamma = np.arctan2(sin_g, np.sum(s * o, axis=1))  # (accurate for small angles too)
    # the azimuth of o about s in the frame the directions are made in (_frame, as _around makes them)
    t0, b0 = _frame(s)
    psi = np.arctan2(np.sum(o * b0, axis=1), np.sum(o * t0, axis=1))
    lo = np.maximum(0.0, gamma - omega)
    hi = np.minimum(sigma, gamma + omega)

    def tee(th: np.ndarray) -> np.ndarray:
        with np.errstate(divide="ignore", invalid="ignore"):
            return (np.cos(omega) - np.cos(th) * np.cos(gamma)) / (np.sin(th) * sin_g)

    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.cos(gamma) / np.cos(omega)
    star = np.arccos(np.clip(ratio, -1.0, 1.0))
    has_star = (np.abs(ratio) <= 1.0) & (star > lo) & (star < hi)
    least = np.minimum(tee(lo), tee(hi))
    least = np.where(has_star, np.minimum(least, tee(star)), least)
    # s inside the other cone (or numbers that say nothing): the whole circle of azimuths
    whole = (gamma <= omega) | ~np.isfinite(least) | (sin_g <= 1e-12)
    phi = np.where(whole, np.pi, np.minimum(np.pi, np.arccos(np.clip(least, -1.0, 1.0)) + LENS_MARGIN))
    lo = np.maximum(0.0, lo - LENS_MARGIN)
    hi = np.minimum(np.pi, hi + LENS_MARGIN)
    v_lo, v_hi = 2.0 * np.sin(0.5 * lo) ** 2, 2.0 * np.sin(0.5 * hi) ** 2  # 1 - cos, without cancelling
    sector = 2.0 * phi * (v_hi - v_lo)
    lens = np.where((lens > 0.0) & (sector > 0.0) & (lo < hi), lens, 0.0)
    return lens, s, psi, v_lo, v_hi, phi, sector


def spot_aimed(pos: np.ndarray, axis: np.ndarray, cos_outer: float, key: int, ids: np.ndarray, li: int,
               u_cos: np.ndarray, u_phi: np.ndarray, boxes: np.ndarray | None = None,
               box: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A spot's caustic directions, drawn from where its outer cone and the aim cones meet:
    the cones bounding ``boxes`` (:func:`box_cones`; ``photons.aim: parts``) or the one cone
    bounding ``box`` (``aim: box``). Cone k's lens (its part inside the outer cone,
    :func:`lens_sectors`) is picked in proportion to its solid angle ``L_k`` (hash dimension 5;
    a cone that misses the outer cone never), and the direction is uniform in it: uniform in a
    sector that holds the lens (dimensions 2 and 3), drawn again (6 and 7, 8 and 9, ...) while
    it falls outside the lens, at most :data:`SPOT_DRAWS` times. A draw falls inside with the
    chance ``r_k = L_k / sector_k`` (0.39 or more in the cases tried), so a photon uses up its draws as seldom
    as ``(1 - r_k)^SPOT_DRAWS`` (it then carries nothing), and the others' ``1 / density`` is
    ``sum_k L_k / #lenses holding d`` (overlapping cones do not count a direction twice) over
    ``1 - (1 - r_k)^SPOT_DRAWS``: the spot's estimate stays unbiased, and a narrow spot costs
    what a wide one does. Returns the (m, 3) directions and their (m,) 1 / density (0 for a
    photon that used up its draws). When no cone meets the outer cone the directions are drawn
    from the aim cones (:func:`cone_mixture`, or uniformly in the one cone) and carry nothing."""
    m = ids.shape[0]
    if boxes is not None:
        cone_axes, cone_cos = (x[0] for x in box_cones(pos[None, :], boxes[:, 0], boxes[:, 1]))
    else:
        a, c = bounding_cone(pos, *box)
        cone_axes, cone_cos = a[None, :], np.array([c])
    lens, s, psi, v_lo, v_hi, phi, sector = lens_sectors(axis, cos_outer, cone_axes, cone_cos)
    total = float(lens.sum())
    if not total > 0.0:  # nothing of the aim cones is lit: directions there, carrying nothing
        if boxes is not None:
            d, _ = cone_mixture(pos[None, :], boxes, hash_uniform(key, ids, -1, li, 5), u_cos, u_phi)
        else:
            d = _around(np.broadcast_to(cone_axes[0], (m, 3)).copy(), 1.0 - u_cos * (1.0 - cone_cos[0]),
                        2.0 * np.pi * u_phi)
        return d, np.zeros(m)
    live = np.flatnonzero(lens > 0.0)  # (only these can hold a direction inside the outer cone)
    cum = np.cumsum(lens[live])
    rate = np.minimum(1.0, lens / np.where(sector > 0.0, sector, 1.0))  # a draw's chance to fall in the lens
    with np.errstate(divide="ignore"):
        kept = -np.expm1(SPOT_DRAWS * np.log1p(-rate))  # 1 - (1 - r_k)^SPOT_DRAWS
    kept = np.where(kept > 0.0, kept, 1.0)
    live_axes, live_cos = cone_axes[live], cone_cos[live]
    d = np.empty((m, 3))
    inv_pdf = np.empty(m)

    def chunk(first: int) -> None:  # photons first .. e - 1, each on its own: chunks run on the threads
        e = min(m, first + SPOT_CHUNK)
        own = ids[first:e]
        j = np.minimum(np.searchsorted(cum, hash_uniform(key, own, -1, li, 5) * cum[-1], side="right"), live.size - 1)
        k = live[j]

        def draw(sel: np.ndarray, uc: np.ndarray, uf: np.ndarray) -> np.ndarray:
            kk = k[sel]
            v = v_lo[kk] + uc * (v_hi[kk] - v_lo[kk])  # 1 - cos(theta), uniform: uniform in the solid angle
            return _around(np.take(s, kk, axis=0), 1.0 - v, psi[kk] + (2.0 * uf - 1.0) * phi[kk])

        def outside(dd: np.ndarray, sel: np.ndarray) -> np.ndarray:
            kk = k[sel]
            return (dd @ axis <= cos_outer) | (np.einsum("ij,ij->i", dd, np.take(cone_axes, kk, axis=0)) < cone_cos[kk])

        every = np.arange(e - first)
        dc = draw(every, u_cos[first:e], u_phi[first:e])
        left = every[outside(dc, every)]
        for r in range(1, SPOT_DRAWS):
            if left.size == 0:
                break
            dim = 6 + 2 * (r - 1)
            dd = draw(left, hash_uniform(key, own[left], -1, li, dim), hash_uniform(key, own[left], -1, li, dim + 1))
            dc[left] = dd
            left = left[outside(dd, left)]
        # how many of the lenses hold each direction (the picked one does, whatever the rounding)
        inside = dc @ live_axes.T >= live_cos[None, :]
        inside[every, j] = True
        ip = total / np.count_nonzero(inside, axis=1) / kept[k]
        ip[left] = 0.0  # (used up its draws)
        d[first:e], inv_pdf[first:e] = dc, ip

    for _ in threads.ordered(chunk, range(0, m, SPOT_CHUNK)):
        pass
    return d, inv_pdf


def disc_mixture(plane: np.ndarray, t: np.ndarray, b: np.ndarray, centres: np.ndarray, radii: np.ndarray,
                 u_pick: np.ndarray, u_r: np.ndarray, u_phi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points on the plane through ``plane`` spanned by the unit ``t`` and ``b``, from a mixture
    of the discs about the projections of ``centres`` (K, 3) of ``radii`` (K,), a disc picked in
    proportion to its area and the point uniform on it; and their 1 / density
    (``pi sum r^2 / #discs holding the point``: where discs overlap a point is not counted
    twice). A directional light's caustic photons start there."""
    m = u_pick.shape[0]
    x = (centres - plane) @ t
    y = (centres - plane) @ b
    cum = np.cumsum(radii * radii)
    total = float(cum[-1])
    pick = np.minimum(np.searchsorted(cum, u_pick * total, side="right"), radii.shape[0] - 1)
    r = radii[pick] * np.sqrt(u_r)
    px = x[pick] + r * np.cos(2.0 * np.pi * u_phi)
    py = y[pick] + r * np.sin(2.0 * np.pi * u_phi)
    holds = np.zeros(m, dtype=np.int64)
    step = max(1, CONE_CHUNK // max(radii.shape[0], 1))
    for s in range(0, m, step):  # (photons x discs in chunks: memory only)
        e = min(m, s + step)
        inside = (px[s:e, None] - x[None, :]) ** 2 + (py[s:e, None] - y[None, :]) ** 2 <= (radii * radii)[None, :]
        inside[np.arange(e - s), pick[s:e]] = True  # the picked disc holds the point, whatever the rounding
        holds[s:e] = inside.sum(axis=1)
    o = plane[None, :] + px[:, None] * t[None, :] + py[:, None] * b[None, :]
    return o, math.pi * total / holds


def _directional_frame(light: Light, box: tuple[np.ndarray, np.ndarray]) -> tuple[np.ndarray, ...]:
    """A directional light's unit direction ``w``, two unit tangents ``t``, ``b`` and the centre
    of its photons' disc: on the side the light comes from, :data:`~tlm.scenes.model.DISC_MARGIN`
    beyond the sphere around ``box``; and the sphere's radius."""
    w = light.axis
    t, b = _frame(w[None, :])
    centre, radius = bounding_sphere(*box)
    return w, t[0], b[0], centre - w * radius * (1.0 + DISC_MARGIN), radius


def emit(
    lights: tuple[Light, ...],
    n: int,
    key: int,
    scene_box: tuple[np.ndarray, np.ndarray] | None = None,
    specular_box: tuple[np.ndarray, np.ndarray] | None = None,
    caustic_fraction: float = 0.0,
    with_source: bool = False,
    caustic_boxes: np.ndarray | None = None,
    caustic_count: int | None = None,
) -> tuple[np.ndarray, ...]:
    """Origins, unit directions, RGB powers (n, 3) and caustic-group flags (n,); with
    ``with_source`` also the triangle each photon leaves (n,) int64 (-1: not geometry).

    Each light's photons are split into a *global* group and, when ``specular_box`` or
    ``caustic_boxes`` is given, a *caustic* group: ``caustic_fraction`` of the light's
    share of ``n`` (the global group the rest); or, with ``caustic_count``, a budget of
    its own, ``caustic_count`` shared among the lights by power (:func:`split_photons`)
    beside the global group's ``n`` (``n + caustic_count`` photons in all). Each group
    carries its light's power over its own count. A point light aims the global group
    at the cone that bounds the scene's box, and the photons' power is scaled by the
    cone's share of the sphere, so no photon is wasted on empty space. A quad light
    emits the global group over its cosine-weighted hemisphere. A mesh light picks a
    triangle for each photon in proportion to its power (:func:`triangle_choice`), a
    uniform point on it and a direction as a quad light does about the triangle's
    normal; the photon's power is the chosen triangle's power over its probability and
    the count. A spot light emits the global group in proportion to its falloff
    (:func:`spot_directions`: equal powers, its flux over the count); a directional light
    from the disc that covers the sphere around ``scene_box`` (required), along its direction.

    The caustic group is aimed at the specular objects (Jensen's projection maps, with
    boxes for maps): with ``specular_box`` (``photons.aim: box``), uniformly in the one
    cone that bounds that box; with ``caustic_boxes`` ((K, 2, 3), :func:`aim_boxes`;
    ``photons.aim: parts``), from a mixture of the cones bounding each box, picked in
    proportion to their solid angles (:func:`cone_mixture`). A point light's cones are
    the same for all its photons; a quad's or a mesh's are those seen from each photon's
    origin, which emits on its front side only (power times the cosine there). The power
    is divided by the direction's density (the mixture's, so overlapping cones do not
    count a direction twice) against the light's (isotropic, or cosine-weighted), so the
    estimate stays unbiased however the cones are drawn. A spot aims at the cones' parts
    inside its outer cone only (:func:`spot_aimed`: a part in proportion to its solid angle,
    the direction uniform in it), and its photons' power is times its falloff in their
    direction. A
    directional light's caustic group starts on the discs the specular objects' bounding
    spheres cast on its photons' plane: the one disc of ``specular_box``'s sphere, or a
    mixture of the discs of ``caustic_boxes`` in proportion to their areas
    (:func:`disc_mixture`), the power its irradiance over the density of the start.
    """
    counts = split_photons(lights, n, scene_box)
    if caustic_boxes is not None and len(caustic_boxes) == 0:
        caustic_boxes = None  # nothing to aim at
    aimed = specular_box is not None or caustic_boxes is not None
    own = split_photons(lights, caustic_count, scene_box) if aimed and caustic_count is not None else None
    out: list[tuple[np.ndarray, ...]] = []
    first = 0
    for li, (light, c) in enumerate(zip(lights, counts.tolist(), strict=True)):
        if own is not None:  # a caustic budget of its own beside the global group's
            n_g, n_c = c, int(own[li])
        else:
            n_c = round(c * caustic_fraction) if aimed else 0
            n_g = c - n_c
        for group, m, box in ((False, n_g, scene_box), (True, n_c, specular_box)):
            if m == 0:
                continue
            ids = np.arange(first, first + m)
            first += m
            u = [hash_uniform(key, ids, -1, li, dim) for dim in range(4)]
            power = np.asarray(light.power, dtype=np.float64) / m
            src = np.full(m, -1, dtype=np.int64)
            if light.kind in ("quad", "mesh"):
                if light.kind == "quad":
                    o = (np.asarray(light.corner)[None, :] + u[0][:, None] * np.asarray(light.edge_u)
                         + u[1][:, None] * np.asarray(light.edge_v))
                    nl = np.broadcast_to(light.normal, (m, 3)).copy()
                else:
                    j, prob = triangle_choice(light, hash_uniform(key, ids, -1, li, 4))
                    o = point_on_triangles(light.triangles[j], u[0], u[1])
                    nl = face_normals(light.triangles[j])
                    src = light.ids[j]
                    # the triangle's power pi Le A over its probability, shared by the m photons
                    power = light.radiance[j] * (np.pi * light.areas[j] / (prob * m))[:, None]
                if group and caustic_boxes is not None:  # a mixture of the cones of the specular parts
                    d, inv_pdf = cone_mixture(o, caustic_boxes, hash_uniform(key, ids, -1, li, 5), u[2], u[3])
                    cos_l = np.maximum(0.0, d @ light.normal if light.kind == "quad" else np.sum(d * nl, axis=1))
                    # flux Le cos dA dw, sampled with pdf (1 / A) (#cones holding d / sum Omega)
                    power = np.atleast_2d(power) * (cos_l * inv_pdf / np.pi)[:, None]
                elif group and box is not None:  # uniform in the cone bounding the specular objects
                    axis, cos_max = bounding_cones(o, *box)
                    d = _around(axis, 1.0 - u[2] * (1.0 - cos_max), 2.0 * np.pi * u[3])
                    # a quad (a triangle) emits on its normal's side only
                    cos_l = np.maximum(0.0, d @ light.normal if light.kind == "quad" else np.sum(d * nl, axis=1))
                    # flux Le cos dA dw over the cone, sampled with pdf 1 / (A * solid angle)
                    power = np.atleast_2d(power) * (cos_l * 2.0 * (1.0 - cos_max))[:, None]
                else:
                    d = cosine_directions(nl, u[2], u[3])
            elif light.kind == "directional":
                if scene_box is None:
                    raise ValueError("emit: a directional light's photons need the scene's box (scene_box)")
                w, t, b, plane, radius = _directional_frame(light, scene_box)
                e0 = np.asarray(light.irradiance, dtype=np.float64)
                d = np.broadcast_to(w, (m, 3)).copy()
                if group and caustic_boxes is not None:  # a mixture of the discs the specular parts cast
                    lo, hi = caustic_boxes[:, 0], caustic_boxes[:, 1]
                    o, inv_pdf = disc_mixture(plane, t, b, 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo, axis=1),
                                              hash_uniform(key, ids, -1, li, 5), u[0], u[1])
                    power = e0[None, :] * (inv_pdf / m)[:, None]  # irradiance over the sampled density
                else:  # the disc covering the sphere around the scene (or around the specular objects)
                    c, r = (bounding_sphere(*box) if group else (plane, radius))
                    if group:  # (the specular objects' disc, on the scene's plane)
                        c = plane + ((c - plane) @ t) * t + ((c - plane) @ b) * b
                    rr = r * np.sqrt(u[0])
                    phi = 2.0 * np.pi * u[1]
                    o = c[None, :] + (rr * np.cos(phi))[:, None] * t[None, :] + (rr * np.sin(phi))[:, None] * b[None, :]
                    power = e0 * (np.pi * r * r / m)
            elif light.kind == "spot":
                pos = np.asarray(light.position, dtype=np.float64)
                o = np.broadcast_to(pos, (m, 3)).copy()
                axis = light.axis
                ci, co = light.cone_cosines
                if group:  # aimed as a point light's, inside the outer cone only, weighted by the falloff
                    d, inv_pdf = spot_aimed(pos, axis, co, key, ids, li, u[2], u[3], boxes=caustic_boxes,
                                            box=None if caustic_boxes is not None else box)
                    power = power[None, :] * (spot_falloff(d @ axis, ci, co) * inv_pdf / (4.0 * np.pi))[:, None]
                else:  # in proportion to the falloff: each photon an equal part of the flux it emits
                    d = spot_directions(axis, ci, co, u[2], u[3])
                    power = np.asarray(light.flux, dtype=np.float64) / m
            else:
                pos = np.asarray(light.position, dtype=np.float64)
                o = np.broadcast_to(pos, (m, 3)).copy()
                if group and caustic_boxes is not None:  # a mixture of the cones of the specular parts
                    d, inv_pdf = cone_mixture(pos[None, :], caustic_boxes, hash_uniform(key, ids, -1, li, 5),
                                              u[2], u[3])
                    power = power[None, :] * (inv_pdf / (4.0 * np.pi))[:, None]  # 1 / (4 pi pdf)
                else:
                    axis, cos_max = bounding_cone(pos, *box) if box is not None else (np.array([0.0, 0, 1]), -1.0)
                    d = _around(np.broadcast_to(axis, (m, 3)).copy(), 1.0 - u[2] * (1.0 - cos_max),
                                2.0 * np.pi * u[3])
                    power = power * (1.0 - cos_max) / 2.0  # the cone's share of the sphere
            out.append((o, d, np.broadcast_to(power, (m, 3)).copy(), np.full(m, group), src))
    if not out:
        empty = np.zeros((0, 3))
        arrays = (empty, empty.copy(), empty.copy(), np.zeros(0, dtype=bool), np.zeros(0, dtype=np.int64))
    else:
        arrays = tuple(np.concatenate(x) for x in zip(*out, strict=True))
    return arrays if with_source else arrays[:4]
