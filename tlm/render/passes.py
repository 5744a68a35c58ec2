"""The frames of one image, in pipeline order: ray cast, then reflection and refraction.

"At the end of the ray-cast operation, we store the intersection points, and normals.
... The shadow, reflective and refractive (indirect illumination) rays are then created
and traversed in separate passes through the acceleration data structure. These
separate frames are summed for the final rendering output." (§III.B)

* :func:`~tlm.render.frame.cast` traces the eye rays of a packet of pixels, ``render.spp`` per pixel, and
  keeps their hits (the stored intersection points and normals every later pass starts
  from);
* :func:`rcast_pass`: direct light with shadow rays at Lambertian eye hits, and quad
  lights seen directly;
* :func:`reflect_pass`: eye paths whose first surface is a mirror, followed through up
  to ``reflect_depth`` specular bounces to Lambertian surfaces, lit directly;
* :func:`refract_pass`: the same for eye paths whose first surface is a dielectric (each
  glass hit split into its Fresnel reflection and refraction), up to ``refract_depth``
  bounces (:func:`~tlm.render.walk.specular_walk`, shared by the two and the photon-map frame);
* :func:`~tlm.render.pmap.pmap_pass` (:mod:`tlm.render.pmap`): the photon-mapped term
  (caustics and indirect light, two maps) at the Lambertian eye hits and the ends of the
  mirror and glass paths, with the configured filter (eqs. 3.2–3.5).

Each eye path belongs to exactly one frame, so the composite is their sum. Every
function works on any packet of pixel ids and returns, with the radiance (each pixel's
samples averaged), the per-pixel work (:data:`~tlm.kernels.work.WORK_KEYS`, a pixel's samples summed); a
pixel's results and work do not depend on the rest of its packet, except its page
misses, which depend on the pixels before it (below).

Page misses (the ``*_misses`` keys) are the data cache's (:mod:`tlm.kernels.memory`) on
the kernels' real address streams (:data:`~tlm.kernels.work.STREAM_KEYS`): the Traversal PM's node heap
and leaf triangle indices (``trav_misses``), the Intersection PM's vertex data
(``isect_misses``), the same three for the shadow rays, a phase of their own (the
thesis traces them in passes of their own), and the Fragment PM's shading records, one
per fragment (``frag_misses``). The run config's ``cache`` section sets the block (page)
size and the pairs per PM: with the thesis's 4 pairs every stream has a pair of its
own; with 1 the node heap and the leaf indices share one and evict each other's pages
(:mod:`tlm.kernels.memory` has the reading). A miss depends on the accesses before it, so
the streams are in pixel-major program order (a pixel's rays bounce by bounce, then the
shadow rays of the points they reach, light by light, sample by sample) and each pass
function takes a
:class:`~tlm.kernels.memory.Streams` holding the pairs' states (default: a fresh one of the
frame's ``cache`` settings, :func:`~tlm.render.frame.new_streams`): packets run in pixel order with one
such object give exactly the misses of the whole image (a fresh one per packet charges
each packet from cold pairs).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tlm.kernels.memory import Streams
from tlm.kernels.recording import Recorder
from tlm.kernels.shade import (
    facing,
)
from tlm.render.frame import (
    Frame,
    GBuffer,
    add_work,
    charge,
    new_streams,
    new_work,
    pixel_mean,
    record_rays,
    shade_lambertian,
    trace_counts,
)
from tlm.render.walk import WALK_WORK, join_walk, specular_walk, walk_key, walk_pieces
from tlm.scenes.model import KIND


def rcast_pass(frame: Frame, g: GBuffer, streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Ray cast + shadows: direct light at Lambertian eye hits; visible quad lights.

    The eye rays' traversal (counts and misses) is charged here, from ``g`` (cast with
    ``record=True``). streams : the cache pairs' states before this packet (default:
    empty pairs of ``frame.cfg.cache``), left in the state after it. Returns the pixels'
    radiance (p, 3) (the mean of their samples) and work (p,) per key.
    """
    p = g.pixels.shape[0]
    work = new_work(p)
    streams = new_streams(frame) if streams is None else streams
    rec = Recorder(streams.page_words)
    owner = g.owner
    radiance = np.zeros((owner.shape[0], 3))
    add_work(work, owner, {"primary_rays": np.ones(owner.shape[0], dtype=np.int64), **trace_counts(g.hits)})
    record_rays(frame, rec, g.hits, owner)
    radiance[g.sees_light] = g.light[g.sees_light]
    idx = _lambertian(frame, g)
    if idx.shape[0]:
        tri = g.triangle[idx]
        pts = g.origin[idx] + g.t[idx, None] * g.direction[idx]
        keys = g.sample_keys[idx] * 64
        radiance[idx] = shade_lambertian(frame, owner[idx], keys, pts, g.direction[idx], tri,
                                          g.hits.u[idx], g.hits.v[idx], work, rec)
    if g.surface_light is not None:  # emitting triangles seen directly (not behind a quad light)
        radiance += np.where(g.sees_light[:, None], 0.0, g.surface_light)
    charge(rec, streams, work)
    return pixel_mean(frame, radiance), work


def _lambertian(frame: Frame, g: GBuffer) -> np.ndarray:
    """Samples whose eye ray meets a Lambertian surface (not behind a light seen directly)."""
    lam = (g.triangle >= 0) & ~g.sees_light
    lam &= frame.kind[np.maximum(g.triangle, 0)] == KIND["lambertian"]
    return np.flatnonzero(lam)


def _walk_pass(frame: Frame, g: GBuffer, first_kind: str, depth: int, streams: Streams | None):
    """A specular frame: lights seen along the walk and direct light where it ends.

    Its reads are charged pixel-major: a pixel's rays bounce by bounce, then the shadow
    rays and shading records of the points they reach; packets in pixel order with a
    carried ``streams`` give the misses of the whole image. The walk goes piece by piece
    (:func:`~tlm.render.walk.walk_pieces`): each piece's ends are shaded and its reads charged before the
    next is traced, so the pass holds one piece's reads, whatever the depth.
    """
    p = g.pixels.shape[0]
    work = new_work(p)
    streams = new_streams(frame) if streams is None else streams
    walk_work = {k: np.zeros(p, dtype=np.int64) for k in WALK_WORK}
    radiance = np.zeros((g.origin.shape[0], 3))
    kept = []
    for piece in walk_pieces(frame, g, first_kind, depth, walk_work, streams.page_words):
        rec = Recorder(streams.page_words)
        rec.added = piece.reads
        np.add.at(radiance, piece.emitted_sample, piece.emitted_radiance)
        e = piece.ends
        if e.sample.shape[0]:
            keys = g.sample_keys[e.sample] * 64 + e.bounce
            direct = shade_lambertian(frame, g.owner[e.sample], keys, e.point, e.direction, e.triangle, e.u, e.v,
                                       work, rec)
            np.add.at(radiance, e.sample, direct * e.weight)
        charge(rec, streams, work)
        kept.append(replace(piece, reads=[]))
        del rec, piece
    for k, v in walk_work.items():
        work[k] += v
    g.memo.setdefault(walk_key(frame, first_kind, depth), join_walk(kept, walk_work))
    return pixel_mean(frame, radiance), work


def reflect_pass(frame: Frame, g: GBuffer, streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Eye paths that first meet a mirror (``streams`` as in :func:`rcast_pass`)."""
    return _walk_pass(frame, g, "mirror", frame.cfg.render.reflect_depth, streams)


def refract_pass(frame: Frame, g: GBuffer, streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Eye paths that first meet a dielectric (``streams`` as in :func:`rcast_pass`)."""
    return _walk_pass(frame, g, "dielectric", frame.cfg.render.refract_depth, streams)


def sees_a_light(frame: Frame, g: GBuffer) -> np.ndarray:
    """(p,) bool: the pixels with a sample that sees a light, directly or along its mirror
    and glass paths (a highlight): where a few samples carry a light's radiance, hundreds
    of times a wall's, and one more or fewer of them changes the pixel the most."""
    seen = g.sees_emitter.copy()
    render = frame.cfg.render
    for kind, depth in (("mirror", render.reflect_depth), ("dielectric", render.refract_depth)):
        if depth and np.any(frame.kind == KIND[kind]):
            seen[specular_walk(frame, g, kind, depth).emitted_sample] = True
    return ~g.every(~seen)


def diffuse_pixels(frame: Frame, g: GBuffer) -> np.ndarray:
    """(p,) bool: the pixels whose eye rays all meet a Lambertian surface (no light seen)."""
    hit = np.zeros(g.origin.shape[0], dtype=bool)
    hit[_lambertian(frame, g)] = True
    return g.every(hit)


def lambertian_hits(frame: Frame, g: GBuffer) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Eye hits on Lambertian surfaces (not behind a light seen directly): their sample
    indices, triangles, points and normals facing the eye, where photons are gathered."""
    idx = _lambertian(frame, g)
    tri = g.triangle[idx]
    pts = g.origin[idx] + g.t[idx, None] * g.direction[idx]
    n = facing(frame.normals[tri], g.direction[idx])
    return idx, tri, pts, n


def gather_points(frame: Frame, g: GBuffer) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Every Lambertian point whose photon-map radiance the image shows: the eye hits
    (weight 1) and, when the scene has mirrors or glass, the ends of the reflect and
    refract walks (weighted by their paths). Returns sample indices, triangles, points,
    normals facing the arriving ray and weights (k, 3)."""
    return gather_points_full(frame, g)[:5]  # type: ignore[return-value]


def gather_points_full(frame: Frame, g: GBuffer) -> tuple[np.ndarray, ...]:
    """:func:`gather_points`, each point's bounce (0: the eye hit; j: the end of a walk after j) and
    the index of refraction of the medium it lies in (:class:`~tlm.render.walk.Ends`)."""
    idx, tri, pts, n = lambertian_hits(frame, g)
    parts = [(idx, tri, pts, n, np.ones((idx.shape[0], 3)), np.zeros(idx.shape[0], dtype=np.int64),
              np.ones(idx.shape[0]))]
    render = frame.cfg.render
    for kind, depth in (("mirror", render.reflect_depth), ("dielectric", render.refract_depth)):
        if depth == 0 or not np.any(frame.kind == KIND[kind]):
            continue
        e = specular_walk(frame, g, kind, depth).ends
        parts.append((e.sample, e.triangle, e.point, facing(frame.normals[e.triangle], e.direction), e.weight,
                      e.bounce, e.medium))
    if len(parts) == 1:
        return parts[0]
    sample = np.concatenate([q[0] for q in parts])
    order = np.argsort(sample, kind="stable")  # sample-major: the Fragment PM gathers pixel by pixel
    return tuple(np.concatenate([q[i] for q in parts])[order] for i in range(7))


def fgather_pass(frame: Frame, g: GBuffer, streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The final-gather rays' work (a ray pass of the Traversal, Intersection and Fragment
    PMs: rays, triangle tests, the shading record of each hit), traced by
    :func:`~tlm.render.pmap.pmap_pass` of the same packet (which must run first, with ``fg_streams``); its
    radiance is the photon-map frame's, so this pass's own is zero. Its host seconds
    (``pass_fgather``) are the final gathering's, which pmap_pass books to this pass's stage."""
    if "fgather_work" not in g.memo:
        raise ValueError("fgather_pass: run pmap_pass on this packet first (final gathering traces its rays)")
    return np.zeros((g.pixels.shape[0], 3)), g.memo.pop("fgather_work")


PASS_FUNCTIONS = {"rcast": rcast_pass, "reflect": reflect_pass, "refract": refract_pass,
                  "fgather": fgather_pass}  # (after pmap_pass of the same packet, which traces its rays)
# the passes whose work is traced by another (pmap_pass traces the final-gather rays)
TRACED_BY = {"fgather": "pmap"}
