"""The frames of one image, in pipeline order: ray cast, then reflection and refraction.

"At the end of the ray-cast operation, we store the intersection points, and normals.
... The shadow, reflective and refractive (indirect illumination) rays are then created
and traversed in separate passes through the acceleration data structure. These
separate frames are summed for the final rendering output." (§III.B)

* :func:`cast` traces the eye rays of a packet of pixels and keeps their hits (the
  stored intersection points and normals every later pass starts from);
* :func:`rcast_pass`: direct light with shadow rays at Lambertian eye hits, and quad
  lights seen directly;
* :func:`reflect_pass`: eye paths whose first surface is a mirror, followed through up
  to ``reflect_depth`` specular bounces to a Lambertian surface, lit directly;
* :func:`refract_pass`: the same for eye paths whose first surface is a dielectric
  (Snell refraction, total internal reflection), up to ``refract_depth`` bounces;
* :func:`pmap_pass`: the photon-mapped term (caustics and indirect light) at
  Lambertian eye hits, from the photon map with the configured filter (eqs. 3.2–3.5).

Each eye path belongs to exactly one frame, so the composite is their sum. Every
function works on any packet of pixel ids and returns, with the radiance, the per-pixel
work (:data:`WORK_KEYS`); a pixel's results and work do not depend on the rest of its
packet, except its page misses, which depend on the pixels before it (below).

Page misses (the ``*_misses`` keys) are the data cache's (:mod:`tlm.arch.cache`) on
the kernels' real address streams (:data:`STREAM_KEYS`): the Traversal PM's node heap
and leaf triangle indices (``trav_misses``), the Intersection PM's vertex data
(``isect_misses``), the same three for the shadow rays, a phase of their own (the
thesis traces them in passes of their own), and the Fragment PM's shading records, one
per fragment (``frag_misses``). The run config's ``cache`` section sets the block (page)
size and the pairs per PM: with the thesis's 4 pairs every stream has a pair of its
own; with 1 the node heap and the leaf indices share one and evict each other's pages
(:mod:`tlm.arch.cache` has the reading). A miss depends on the accesses before it, so
the streams are in pixel-major program order (a pixel's rays bounce by bounce, its
shadow rays light by light, sample by sample) and each pass function takes a
:class:`~tlm.arch.cache.Streams` holding the pairs' states (default: a fresh one of the
frame's ``cache`` settings, :func:`new_streams`): packets run in pixel order with one
such object give exactly the misses of the whole image (a fresh one per packet charges
each packet from cold pairs).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tlm.arch.cache import SHADING_WORDS, Accesses, Recorder, Streams, traversal_accesses
from tlm.config import RunConfig
from tlm.kernels import estimate
from tlm.kernels.camera import primary_rays
from tlm.kernels.photons import PhotonMap, PhotonTrace, trace_photons
from tlm.kernels.shade import SPAWN_EPS, direct_light, emitted, face_normals, facing, reflect, refract
from tlm.kernels.traverse import Hits, TriangleAccel, closest_hit
from tlm.render.planner import photon_count
from tlm.scenes.model import KIND, Scene

WORK_KEYS = (
    "primary_rays",  # eye rays traced
    "secondary_rays",  # reflected / refracted rays traced
    "shadow_rays",  # shadow rays traced (any-hit)
    "shadow_hits",  # shadow rays that found an occluder
    "node_visits",  # traversal of the eye and secondary rays: inner nodes entered
    "leaves_crossed",  # ... leaves on the rays' lists
    "leaf_visits",  # ... leaves tested before stopping
    "tri_tests",  # ... ray-triangle tests (the Intersection PM)
    "shadow_node_visits",  # the same four for the shadow rays, which the thesis
    "shadow_leaves_crossed",  # traces in passes of their own
    "shadow_leaf_visits",
    "shadow_tri_tests",
    "fragments",  # Lambertian points shaded
    "specular_bounces",  # mirror reflections, refractions and total internal reflections
    "trav_misses",  # page misses of the eye and secondary rays: node heap + leaf indices
    "isect_misses",  # ... triangle vertex data (the Intersection PM)
    "shadow_trav_misses",  # the same two for the shadow rays, on pairs of their own
    "shadow_isect_misses",
    "frag_misses",  # ... shading records read per fragment (the Fragment PM)
)
GATHER_KEYS = (
    "gathers",  # radiance estimates made (Lambertian eye hits)
    "node_visits",  # photon BSP: inner nodes on the search lists (Fig. 8)
    "leaves_visited",  # photon BSP leaves searched
    "photons_tested",  # photons compared against the search radius
    "photons_accepted",  # photons inside it, from the front, that were filtered
    "gather_misses",  # page misses reading the searched leaves' photons (0 for knn)
)
# the keys that depend on the accesses before the pixel (the pairs' carried state): equal
# for a pixel only when the pixels before it ran too, in order, with one Streams
MISS_KEYS = ("trav_misses", "isect_misses", "shadow_trav_misses", "shadow_isect_misses", "frag_misses",
             "gather_misses")
# each stream of a pass and the work key its misses go to (the pairs they take:
# tlm.arch.cache.PM_STREAMS; streams sharing a pair always go to one key)
STREAM_KEYS = {
    "nodes": "trav_misses", "indices": "trav_misses", "vertices": "isect_misses",
    "shadow_nodes": "shadow_trav_misses", "shadow_indices": "shadow_trav_misses",
    "shadow_vertices": "shadow_isect_misses", "shading": "frag_misses",
}


@dataclass(frozen=True)
class Frame:
    """What every pass reads: the scene, its BSP, per-triangle material tables, settings."""

    scene: Scene
    accel: TriangleAccel
    cfg: RunConfig
    normals: np.ndarray  # (n, 3) unit geometric normals
    kind: np.ndarray  # (n,) int8, KIND of each triangle's material
    albedo: np.ndarray  # (n, 3)
    reflectance: np.ndarray  # (n, 3)
    transmittance: np.ndarray  # (n, 3)
    ior: np.ndarray  # (n,)
    eps: float  # spawn epsilon in scene units

    @classmethod
    def create(cls, scene: Scene, accel: TriangleAccel, cfg: RunConfig) -> Frame:
        return cls(
            scene=scene,
            accel=accel,
            cfg=cfg,
            normals=face_normals(scene.triangles),
            eps=SPAWN_EPS * max(accel.scale, np.finfo(float).tiny),
            **scene.material_table(),
        )


def new_streams(frame: Frame) -> Streams:
    """Cold cache pairs of the frame's ``cache`` settings (block size, pairs per PM)."""
    return Streams(frame.cfg.cache.block_words, frame.cfg.cache.pairs)


def new_work(p: int) -> dict[str, np.ndarray]:
    return {k: np.zeros(p, dtype=np.int64) for k in WORK_KEYS}


def _add(work: dict[str, np.ndarray], index: np.ndarray, values: dict[str, np.ndarray]) -> None:
    p = work["fragments"].shape[0]
    for k, v in values.items():
        work[k] += np.bincount(index, weights=v, minlength=p).astype(np.int64)


def _record_rays(frame: Frame, rec: Recorder, hits: Hits, owners: np.ndarray | None = None) -> None:
    """Add a traversal's reads (node heap, leaf indices, vertices) to ``rec``; ray i is owner ``owners[i]``."""
    if hits.touched is None:
        raise ValueError("the rays were traced without record=True: their reads are unknown")
    accel = frame.accel
    for name, acc in traversal_accesses(hits.touched, accel.leaf_first, accel.leaf_last, rec.page_words).items():
        rec.add(name, acc, owners)


def _charge(rec: Recorder, streams: Streams, work: dict[str, np.ndarray]) -> None:
    """Charge the recorded streams, pixel-major, to ``streams``; add the misses to ``work``."""
    for name, counts in rec.charge(streams, work["fragments"].shape[0]).items():
        work[STREAM_KEYS[name]] += counts


def _trace_counts(hits: Hits) -> dict[str, np.ndarray]:
    c = hits.counts
    return {
        "node_visits": c.node_visits,
        "leaves_crossed": c.leaves_crossed,
        "leaf_visits": c.leaf_visits,
        "tri_tests": c.tri_tests,
    }


@dataclass(frozen=True)
class GBuffer:
    """The ray-cast frame's stored hits for a packet of pixels."""

    pixels: np.ndarray  # (p,) int64
    origin: np.ndarray  # (p, 3)
    direction: np.ndarray  # (p, 3) unit
    hits: Hits
    light: np.ndarray  # (p, 3) radiance of a quad light seen before the surface
    sees_light: np.ndarray  # (p,) bool

    @property
    def t(self) -> np.ndarray:
        return self.hits.t

    @property
    def triangle(self) -> np.ndarray:
        return self.hits.triangle

    def normal(self, frame: Frame) -> np.ndarray:
        """(p, 3) geometric normals of the hit triangles (zero on a miss)."""
        n = frame.normals[np.maximum(self.triangle, 0)]
        return np.where(self.triangle[:, None] >= 0, n, 0.0)


def cast(frame: Frame, pixels: np.ndarray, record: bool = True) -> GBuffer:
    """Trace the eye rays of ``pixels`` (the ray-cast operation).

    record : keep the nodes and leaves each ray touched (``hits.touched``), from which
        :func:`rcast_pass` charges the eye rays' page misses; the other passes do not
        need them.
    """
    pixels = np.asarray(pixels, dtype=np.int64)
    o, d = primary_rays(frame.scene.camera, pixels)
    hits = closest_hit(frame.accel, o, d, tmin=0.0, batch=frame.cfg.render.batch, shared_origin=True,
                       record=record)
    le, seen = emitted(frame.scene.lights, o, d, hits.t, frame.eps)
    return GBuffer(pixels, o, d, hits, le, seen)


def _shade_lambertian(frame: Frame, pix_local: np.ndarray, keys: np.ndarray, points: np.ndarray,
                      d: np.ndarray, tri: np.ndarray, weight: np.ndarray,
                      work: dict[str, np.ndarray], rec: Recorder) -> np.ndarray:
    """Direct light at Lambertian hits, weighted; records fragment and shadow work and reads
    (the shadow rays' and one shading record per fragment) under the pixels ``pix_local``."""
    n = facing(frame.normals[tri], d)
    radiance, w, reads = direct_light(
        frame.accel, frame.scene.lights, points, n, tri, frame.albedo[tri], keys,
        frame.cfg.seed, frame.cfg.render.light_samples, frame.eps, record=True, page_words=rec.page_words,
    )
    _add(work, pix_local, w)
    _add(work, pix_local, {"fragments": np.ones(pix_local.shape[0], dtype=np.int64)})
    for name, acc in reads.items():
        rec.add(f"shadow_{name}", acc, pix_local)
    rec.add("shading", Accesses.of_words(tri * SHADING_WORDS, pix_local, rec.page_words))
    return radiance * weight


def rcast_pass(frame: Frame, g: GBuffer, streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Ray cast + shadows: direct light at Lambertian eye hits; visible quad lights.

    The eye rays' traversal (counts and misses) is charged here, from ``g`` (cast with
    ``record=True``). streams : the cache pairs' states before this packet (default:
    empty pairs of ``frame.cfg.cache``), left in the state after it.
    """
    p = g.pixels.shape[0]
    work = new_work(p)
    streams = new_streams(frame) if streams is None else streams
    rec = Recorder(streams.page_words)
    radiance = np.zeros((p, 3))
    local = np.arange(p)
    _add(work, local, {"primary_rays": np.ones(p, dtype=np.int64), **_trace_counts(g.hits)})
    _record_rays(frame, rec, g.hits)
    radiance[g.sees_light] = g.light[g.sees_light]
    hit = (g.triangle >= 0) & ~g.sees_light
    lam = hit & (frame.kind[np.maximum(g.triangle, 0)] == KIND["lambertian"])
    idx = np.flatnonzero(lam)
    if idx.shape[0]:
        tri = g.triangle[idx]
        pts = g.origin[idx] + g.t[idx, None] * g.direction[idx]
        keys = g.pixels[idx] * 64
        radiance[idx] = _shade_lambertian(frame, idx, keys, pts, g.direction[idx], tri,
                                          np.ones((idx.shape[0], 1)), work, rec)
    _charge(rec, streams, work)
    return radiance, work


def _specular_walk(frame: Frame, g: GBuffer, first_kind: str, depth: int, streams: Streams | None):
    """Paths whose first surface is of ``first_kind``, followed ``depth`` specular bounces.

    The walk runs bounce by bounce over the packet; its reads are charged afterwards in
    pixel-major order (a pixel's bounces in order), so that packets in pixel order with
    a carried ``streams`` give the misses of the whole image.
    """
    p = g.pixels.shape[0]
    work = new_work(p)
    streams = new_streams(frame) if streams is None else streams
    rec = Recorder(streams.page_words)
    radiance = np.zeros((p, 3))
    start = (g.triangle >= 0) & (frame.kind[np.maximum(g.triangle, 0)] == KIND[first_kind])
    start &= ~g.sees_light
    idx = np.flatnonzero(start)
    tri = g.triangle[idx]
    d = g.direction[idx]
    x = g.origin[idx] + g.t[idx, None] * d
    weight = np.ones((idx.shape[0], 3))
    for bounce in range(1, depth + 1):
        if idx.shape[0] == 0:
            break
        kind = frame.kind[tri]
        n = frame.normals[tri]
        mirror = kind == KIND["mirror"]
        new_d = np.empty_like(d)
        if mirror.any():
            new_d[mirror] = reflect(d[mirror], n[mirror])
            weight[mirror] *= frame.reflectance[tri[mirror]]
        diel = ~mirror
        if diel.any():
            rd, tir = refract(d[diel], n[diel], frame.ior[tri[diel]])
            new_d[diel] = rd
            wd = weight[diel]
            wd[~tir] *= frame.transmittance[tri[diel]][~tir]
            weight[diel] = wd
        _add(work, idx, {"specular_bounces": np.ones(idx.shape[0], dtype=np.int64)})
        d = new_d
        hits = closest_hit(frame.accel, x, d, tmin=frame.eps, ignore=tri, batch=frame.cfg.render.batch,
                           record=True)
        _add(work, idx, {"secondary_rays": np.ones(idx.shape[0], dtype=np.int64), **_trace_counts(hits)})
        _record_rays(frame, rec, hits, idx)
        le, seen = emitted(frame.scene.lights, x, d, hits.t, frame.eps)
        radiance[idx[seen]] += weight[seen] * le[seen]
        hit = (hits.triangle >= 0) & ~seen
        kind_hit = frame.kind[np.maximum(hits.triangle, 0)]
        lam = hit & (kind_hit == KIND["lambertian"])
        if lam.any():
            li = np.flatnonzero(lam)
            pts = x[li] + hits.t[li, None] * d[li]
            keys = g.pixels[idx[li]] * 64 + bounce
            radiance[idx[li]] += _shade_lambertian(frame, idx[li], keys, pts, d[li],
                                                   hits.triangle[li], weight[li], work, rec)
        go = hit & ~lam
        x = x[go] + hits.t[go, None] * d[go]
        idx, tri, d, weight = idx[go], hits.triangle[go], d[go], weight[go]
    _charge(rec, streams, work)
    return radiance, work


def reflect_pass(frame: Frame, g: GBuffer, streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Eye paths that first meet a mirror (``streams`` as in :func:`rcast_pass`)."""
    return _specular_walk(frame, g, "mirror", frame.cfg.render.reflect_depth, streams)


def refract_pass(frame: Frame, g: GBuffer, streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """Eye paths that first meet a dielectric (``streams`` as in :func:`rcast_pass`)."""
    return _specular_walk(frame, g, "dielectric", frame.cfg.render.refract_depth, streams)


def lambertian_hits(frame: Frame, g: GBuffer) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Eye hits on Lambertian surfaces (not behind a light seen directly): their packet
    indices, triangles, points and normals facing the eye, where photons are gathered."""
    lam = (g.triangle >= 0) & ~g.sees_light
    lam &= frame.kind[np.maximum(g.triangle, 0)] == KIND["lambertian"]
    idx = np.flatnonzero(lam)
    tri = g.triangle[idx]
    pts = g.origin[idx] + g.t[idx, None] * g.direction[idx]
    n = facing(frame.normals[tri], g.direction[idx])
    return idx, tri, pts, n


def trace_photon_map(frame: Frame, n: int | None = None, seed: int | None = None) -> PhotonTrace:
    """The frame's photon map by its ``photons.*`` settings (``n``, ``seed``: overrides)."""
    cfg = frame.cfg
    return trace_photons(
        frame.scene, frame.accel, photon_count(frame.scene, cfg) if n is None else n,
        seed=cfg.seed if seed is None else seed, max_bounces=cfg.photons.max_bounces,
        russian_roulette=cfg.photons.russian_roulette, levels=cfg.photons.levels,
        caustic_fraction=cfg.photons.caustic_fraction, batch=cfg.render.batch,
        page_words=cfg.cache.block_words, pairs=cfg.cache.pairs,
    )


def search_radius(frame: Frame) -> float:
    """The fixed search radius r: ``estimate.radius`` or a fraction of the scene diagonal."""
    est = frame.cfg.estimate
    return est.radius if est.radius is not None else est.radius_fraction * frame.accel.scale


def pmap_pass(frame: Frame, g: GBuffer, photons: PhotonMap, kdtree=None,
              streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The photon-map frame: ``albedo / pi * density`` at Lambertian eye hits.

    ``density`` is the reflected flux density from the photon map by the configured
    filter; ``kdtree`` is an optional prebuilt ``cKDTree`` of the photon positions for
    the exact k-nearest estimate. ``gather_misses``: the photon-leaf stream's misses,
    gathers in pixel order (``streams`` as in :func:`rcast_pass`).
    """
    p = g.pixels.shape[0]
    work = {k: np.zeros(p, dtype=np.int64) for k in GATHER_KEYS}
    radiance = np.zeros((p, 3))
    idx, tri, pts, n = lambertian_hits(frame, g)
    if idx.shape[0] == 0 or photons.n == 0:
        return radiance, work
    est = frame.cfg.estimate
    streams = new_streams(frame) if streams is None else streams
    args = (photons.position, photons.power, photons.incoming)
    if est.filter == "knn":
        e = estimate.knn_estimate(*args, pts, n, k_nearest=est.k_nearest, cone_k=est.cone_k, kdtree=kdtree)
    elif est.filter == "kvoxel":
        e = estimate.kvoxel_estimate(*args, photons.tree, pts, n, search_radius(frame), k=est.k,
                                     cone_k=est.cone_k, seed=frame.cfg.seed, keys=g.pixels[idx], streams=streams)
    elif est.filter == "disk":
        e = estimate.disk_estimate(*args, photons.tree, pts, n, search_radius(frame), streams=streams)
    else:
        e = estimate.mvoxel_estimate(*args, photons.tree, pts, n, search_radius(frame), cone_k=est.cone_k,
                                     streams=streams)
    radiance[idx] = frame.albedo[tri] / np.pi * e.density
    work["gathers"][idx] = 1
    for k in GATHER_KEYS[1:]:
        work[k][idx] = getattr(e, k)
    return radiance, work


PASS_FUNCTIONS = {"rcast": rcast_pass, "reflect": reflect_pass, "refract": refract_pass}
