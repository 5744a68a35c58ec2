"""The specular walk: eye paths through mirrors and glass to the Lambertian points where they end.

:func:`specular_walk` follows the eye paths whose first surface is a mirror or a dielectric
(each glass hit split into its Fresnel reflection and refraction) through up to the
config's depth of specular bounces, in pieces of at most :func:`~tlm.render.frame.ray_budget`
rays (:func:`walk_pieces`), and returns the :class:`Walk`: the lights seen along the way
and the :class:`Ends` where the paths meet a Lambertian surface. The reflect and refract
frames (:mod:`tlm.render.passes`) light those ends directly; the photon-map frame
(:mod:`tlm.render.pmap`) gathers photons there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tlm.kernels.memory import Accesses
from tlm.kernels.recording import Recorder
from tlm.kernels.shade import (
    emitted,
    scatter_specular,
    surface_emission,
)
from tlm.render.frame import (
    Frame,
    GBuffer,
    new_streams,
    ray_budget,
    shading_normals,
    trace_secondary,
)
from tlm.scenes.model import KIND


@dataclass(frozen=True)
class Ends:
    """Lambertian points where specular paths end: sample index, point, arriving
    direction, triangle, barycentrics, path weight (k, 3), bounce (1 = after the first
    specular surface) and the index of refraction of the medium the point lies in (1: air;
    the floor under a water surface: the water's)."""

    sample: np.ndarray
    point: np.ndarray
    direction: np.ndarray
    triangle: np.ndarray
    u: np.ndarray
    v: np.ndarray
    weight: np.ndarray
    bounce: np.ndarray
    medium: np.ndarray


@dataclass(frozen=True)
class Walk:
    """The specular paths of a packet that first meet one kind of surface.

    ``emitted`` (sample, radiance) lights seen along the way (already weighted), ``ends``
    the Lambertian points the paths reach, ``work`` the rays' work per pixel and
    ``reads`` their traversal reads (stream name, accesses with owner = packet pixel).
    The walk a packet keeps (:func:`specular_walk`) holds no reads: :func:`~tlm.render.passes._walk_pass`
    charges them piece by piece (:func:`walk_pieces`), and a piece's walk holds its own
    (and no work: the pieces of a packet add to one work dict).
    """

    emitted_sample: np.ndarray
    emitted_radiance: np.ndarray
    ends: Ends
    work: dict[str, np.ndarray] | None
    reads: list


WALK_WORK = ("secondary_rays", "node_visits", "leaves_crossed", "leaf_visits", "tri_tests", "specular_bounces")


@dataclass
class _Piece:
    """A run of a packet's pixels (``lo`` .. ``hi - 1``) on its specular walk: the bounce its
    paths take next, their state (``sidx`` sample, ``tri`` triangle at the current point,
    ``x`` point, ``d`` arriving direction, ``u``, ``v``, ``weight``, ``medium``; in sample
    order) and what the bounces so far found: reads (a :class:`Recorder`'s), ends (one dict
    of :class:`Ends` fields per bounce) and lights seen (sample, radiance), in that order."""

    lo: int
    hi: int
    bounce: int
    state: dict[str, np.ndarray]
    rec: Recorder
    ends: list = field(default_factory=list)
    emitted: list = field(default_factory=list)

    def cut(self, m: int, spp: int) -> tuple[_Piece, _Piece]:
        """The pixels before ``m`` and from ``m`` on, each with its paths and findings."""
        below = self.state["sidx"] < m * spp
        rec_a, rec_b = Recorder(self.rec.page_words), Recorder(self.rec.page_words)
        for name, acc in self.rec.added:
            a = acc.owner < m
            rec_a.added.append((name, Accesses(acc.words[a], acc.owner[a], acc.page_words)))
            rec_b.added.append((name, Accesses(acc.words[~a], acc.owner[~a], acc.page_words)))
        halves = []
        for keep, (lo, hi), rec in ((below, (self.lo, m), rec_a), (~below, (m, self.hi), rec_b)):
            halves.append(_Piece(lo, hi, self.bounce, {k: v[keep] for k, v in self.state.items()}, rec))
        for e in self.ends:
            a = e["sample"] < m * spp
            halves[0].ends.append({k: v[a] for k, v in e.items()})
            halves[1].ends.append({k: v[~a] for k, v in e.items()})
        for s, r in self.emitted:
            a = s < m * spp
            halves[0].emitted.append((s[a], r[a]))
            halves[1].emitted.append((s[~a], r[~a]))
        return halves[0], halves[1]

    def walk(self, reads: bool) -> Walk:
        """What the piece found, bounce by bounce."""
        return Walk(
            emitted_sample=_cat([s for s, _ in self.emitted], (0,), np.int64),
            emitted_radiance=_cat([r for _, r in self.emitted], (0, 3)),
            ends=Ends(**{name: _cat([e[name] for e in self.ends], *_END_SHAPE[name])
                         for name in Ends.__dataclass_fields__}),
            work=None, reads=list(self.rec.added) if reads else [],
        )


_END_SHAPE = {name: ((0, 3) if name in ("point", "direction", "weight") else (0,),
                     np.int64 if name in ("sample", "triangle", "bounce") else np.float64)
              for name in Ends.__dataclass_fields__}


def _cat(parts: list[np.ndarray], shape: tuple, dtype=np.float64) -> np.ndarray:
    return np.concatenate(parts) if parts else np.zeros(shape, dtype=dtype)


def _branches(frame: Frame, st: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The rays a bounce traces from the paths' current points: a mirror's reflection, glass's
    Fresnel reflection and refraction (each sample's reflection before its refraction; a
    branch whose weight falls below ``render.min_weight`` is not traced). Returns each ray's
    sample, the triangle it leaves, origin, direction, weight and medium, in sample order."""
    tri, d, weight, medium = st["tri"], st["d"], st["weight"], st["medium"]
    kind = frame.kind[tri]
    geo = frame.normals[tri]
    n_sh = shading_normals(frame, tri, st["u"], st["v"])
    mirror = kind == KIND["mirror"]
    refl, refr, f = scatter_specular(d, n_sh, geo, np.where(mirror, 1.0, frame.ior[tri]))
    if not frame.cfg.render.fresnel:  # Snell only: glass refracts all but what it reflects totally
        f = np.where(f < 1.0, 0.0, 1.0)
    w_refl = np.where(mirror[:, None], weight * frame.reflectance[tri], weight * f[:, None])
    w_refr = np.where(mirror[:, None], 0.0, weight * (1.0 - f)[:, None] * frame.transmittance[tri])
    # the branches, each sample's reflection before its refraction
    min_w = max(frame.cfg.render.min_weight, np.finfo(float).tiny)
    n = tri.shape[0]
    take = np.empty((n, 2), dtype=bool)  # (sample, branch): reflection 0, refraction 1
    np.greater_equal(w_refl.max(axis=1), min_w, out=take[:, 0])
    np.greater_equal(w_refr.max(axis=1), min_w, out=take[:, 1])
    at = np.flatnonzero(take.ravel())  # the branches taken, in (sample, branch) order
    src = at >> 1
    # a refraction enters the glass (against its outward normal: the medium becomes its
    # ior) or leaves it (into air); a reflection stays where it is
    entering = np.sum(d * geo, axis=1) < 0
    refracted_medium = np.where(entering, np.where(mirror, 1.0, frame.ior[tri]), 1.0)
    return {"sidx": st["sidx"][src], "tri": tri[src], "x": st["x"][src],
            "d": _interleave(refl, refr)[at], "weight": _interleave(w_refl, w_refr)[at],
            "medium": _interleave(medium, refracted_medium)[at]}


def _interleave(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a[0], b[0], a[1], b[1], ...`` (rows of (n,) or (n, 3) arrays): the branches of each sample
    in a row each, reflection before refraction (a selection: the values themselves)."""
    out = np.empty((a.shape[0], 2, *a.shape[1:]), dtype=np.result_type(a, b))
    out[:, 0] = a
    out[:, 1] = b
    return out.reshape(-1, *a.shape[1:])


def _bounce(frame: Frame, g: GBuffer, piece: _Piece, rays: dict[str, np.ndarray], work: dict[str, np.ndarray],
            record: bool) -> None:
    """Trace one bounce's ``rays`` (:func:`_branches`) of ``piece``: lights and emitting
    triangles they see, Lambertian points where they end; the rest is the piece's new state."""
    sidx, origin, new_d, new_w, medium = rays["sidx"], rays["x"], rays["d"], rays["weight"], rays["medium"]
    bounce = piece.bounce
    owner = g.owner[sidx]
    work["specular_bounces"] += np.bincount(owner, minlength=work["specular_bounces"].shape[0])
    hits = trace_secondary(frame, origin, new_d, rays["tri"], owner, work, piece.rec if record else None)
    le, seen = emitted(frame.scene.lights, origin, new_d, hits.t, frame.eps)
    # radiance over n^2 is what a path carries unchanged: seen from the eye (in air), what
    # lies inside glass of index n is 1 / n^2 as bright (Mitsuba's dielectric alike);
    # a path that has left the glass again carries its weight unscaled
    inside = medium != 1.0
    seen_w = new_w
    if inside.any():
        seen_w = new_w.copy()
        seen_w[inside] /= (medium[inside] ** 2)[:, None]
    piece.emitted.append((sidx[seen], seen_w[seen] * le[seen]))
    surf = surface_emission(frame.emission, frame.normals, hits.triangle, new_d)
    if surf is not None:  # emitting triangles the path meets (it goes on from them)
        glow = ~seen & (surf.max(axis=1) > 0)
        piece.emitted.append((sidx[glow], seen_w[glow] * surf[glow]))
    hit = (hits.triangle >= 0) & ~seen
    kind_hit = frame.kind[np.maximum(hits.triangle, 0)]
    lam = hit & (kind_hit == KIND["lambertian"])
    pts = origin + hits.t[:, None] * new_d
    piece.ends.append({name: val[lam] for name, val in (
        ("sample", sidx), ("point", pts), ("direction", new_d), ("triangle", hits.triangle), ("u", hits.u),
        ("v", hits.v), ("weight", seen_w), ("bounce", np.full(sidx.shape[0], bounce)), ("medium", medium))})
    go = hit & ~lam
    piece.state = {"sidx": sidx[go], "tri": hits.triangle[go], "x": pts[go], "d": new_d[go], "u": hits.u[go],
                   "v": hits.v[go], "weight": new_w[go], "medium": medium[go]}
    piece.bounce += 1


def walk_pieces(frame: Frame, g: GBuffer, first_kind: str, depth: int, work: dict[str, np.ndarray],
                page_words: int | None = None, record: bool = True):
    """The walk of :func:`specular_walk` in pieces: runs of the packet's pixels, in pixel
    order, each followed through all its bounces and holding the paths and reads of at
    most :func:`~tlm.render.frame.ray_budget` rays (a single pixel whose paths are more goes alone).

    A piece starts as the whole packet; before a bounce that would take its rays over the
    budget it is cut in two at a pixel (each half with its paths and what they found so far)
    and the first half goes on first. A path's rays do not depend on the other paths, so the
    pieces together are the walk of the whole packet, ray for ray; their reads, charged
    piece by piece in pixel order, are the packet's pixel-major stream. Yields each piece's
    :class:`Walk` (its reads when ``record``, recorded for ``page_words``-word pages; none
    otherwise) and adds the rays' work per pixel to ``work`` (:data:`WALK_WORK`)."""
    page_words = new_streams(frame).page_words if page_words is None else page_words
    budget = ray_budget(frame)
    spp = g.spp
    start = (g.triangle >= 0) & ~g.sees_light
    start &= frame.kind[np.maximum(g.triangle, 0)] == KIND[first_kind]
    sidx = np.flatnonzero(start)
    d = g.direction[sidx]
    state = {"sidx": sidx, "tri": g.triangle[sidx], "x": g.origin[sidx] + g.t[sidx, None] * d, "d": d,
             "u": g.hits.u[sidx], "v": g.hits.v[sidx], "weight": np.ones((sidx.shape[0], 3)),
             # the index of refraction around the path's current point (the eye's: 1)
             "medium": np.ones(sidx.shape[0])}
    stack = [_Piece(0, g.pixels.shape[0], 1, state, Recorder(page_words))]
    while stack:
        piece = stack.pop()
        while piece.bounce <= depth and piece.state["sidx"].shape[0]:
            rays = _branches(frame, piece.state)
            n = rays["sidx"].shape[0]
            if n == 0:
                break
            pix = rays["sidx"] // spp  # (non-decreasing: paths stay in sample order)
            traced = int(work["secondary_rays"][piece.lo:piece.hi].sum())
            if traced + n > budget and pix[0] != pix[-1]:
                m = int(pix[n // 2])
                if m == pix[0]:
                    m = int(pix[np.searchsorted(pix, m, side="right")])
                first, second = piece.cut(m, spp)
                stack += [second, first]
                piece = None
                break
            _bounce(frame, g, piece, rays, work, record)
        if piece is not None:
            yield piece.walk(record)


def join_walk(pieces: list[Walk], work: dict[str, np.ndarray]) -> Walk:
    """The pieces' walks as the packet's, without reads: pieces in pixel order, each
    bounce by bounce, so each sample's lights and ends are in the order one walk of the
    whole packet finds them (what the passes' sums and the gather points' order follow)."""
    return Walk(
        emitted_sample=_cat([w.emitted_sample for w in pieces], (0,), np.int64),
        emitted_radiance=_cat([w.emitted_radiance for w in pieces], (0, 3)),
        ends=Ends(**{name: _cat([getattr(w.ends, name) for w in pieces], *_END_SHAPE[name])
                     for name in Ends.__dataclass_fields__}),
        work=work, reads=[])


def specular_walk(frame: Frame, g: GBuffer, first_kind: str, depth: int) -> Walk:
    """Eye paths whose first surface is of ``first_kind``, followed ``depth`` specular bounces.

    Mirrors reflect (times reflectance). Glass splits every path in two, Whitted's way:
    the reflection (times the exact Fresnel ``F``; all of it under total internal
    reflection) and the refraction (times ``(1 - F)`` and the transmittance); a branch
    whose path weight falls below ``render.min_weight`` is not traced (with
    ``render.fresnel: false``, F is 0 but under total internal reflection: one ray per
    path, Snell's law alone). Directions are taken about the interpolated shading normal
    (the geometric one where it would send a ray to the wrong side); a new ray starts at
    the hit, ignores the triangle it leaves and accepts hits from ``eps`` on (a relative
    epsilon: the scene's diagonal x SPAWN_EPS), so neither the surface it leaves nor a
    coplanar neighbour can stop it. What a path meets while inside glass of index n (it
    entered a dielectric and has not left it: the floor under a water surface) reaches the
    eye 1 / n^2 as bright, radiance over n^2 being what a path carries unchanged; the
    emitted radiance and the ends' weights say so (a path that leaves the glass again is
    unscaled, so closed glass objects change nothing).

    Traced in pieces of at most :func:`~tlm.render.frame.ray_budget` rays (:func:`walk_pieces`), so the
    memory it takes is the batch's whatever the depth. Remembered in ``g.memo`` without
    its reads: the reflect, refract and photon-map passes share one walk (the first of
    them to need it, :func:`~tlm.render.passes._walk_pass`, traces it and charges its reads piece by piece).
    """
    key = walk_key(frame, first_kind, depth)
    if key not in g.memo:
        work = {k: np.zeros(g.pixels.shape[0], dtype=np.int64) for k in WALK_WORK}
        g.memo[key] = join_walk(list(walk_pieces(frame, g, first_kind, depth, work, record=False)), work)
    return g.memo[key]


def walk_key(frame: Frame, first_kind: str, depth: int) -> tuple:
    return ("walk", first_kind, depth, frame.cfg.render.min_weight, frame.cfg.render.fresnel)
