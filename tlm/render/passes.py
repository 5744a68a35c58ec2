"""The frames of one image, in pipeline order: ray cast, then reflection and refraction.

"At the end of the ray-cast operation, we store the intersection points, and normals.
... The shadow, reflective and refractive (indirect illumination) rays are then created
and traversed in separate passes through the acceleration data structure. These
separate frames are summed for the final rendering output." (§III.B)

* :func:`cast` traces the eye rays of a packet of pixels, ``render.spp`` per pixel, and
  keeps their hits (the stored intersection points and normals every later pass starts
  from);
* :func:`rcast_pass`: direct light with shadow rays at Lambertian eye hits, and quad
  lights seen directly;
* :func:`reflect_pass`: eye paths whose first surface is a mirror, followed through up
  to ``reflect_depth`` specular bounces to Lambertian surfaces, lit directly;
* :func:`refract_pass`: the same for eye paths whose first surface is a dielectric (each
  glass hit split into its Fresnel reflection and refraction), up to ``refract_depth``
  bounces (:func:`specular_walk`, shared by the two and the photon-map frame);
* :func:`pmap_pass`: the photon-mapped term (caustics and indirect light, two maps) at
  the Lambertian eye hits and the ends of the mirror and glass paths, with the
  configured filter (eqs. 3.2–3.5).

Each eye path belongs to exactly one frame, so the composite is their sum. Every
function works on any packet of pixel ids and returns, with the radiance (each pixel's
samples averaged), the per-pixel work (:data:`WORK_KEYS`, a pixel's samples summed); a
pixel's results and work do not depend on the rest of its packet, except its page
misses, which depend on the pixels before it (below).

Page misses (the ``*_misses`` keys) are the data cache's (:mod:`tlm.kernels.memory`) on
the kernels' real address streams (:data:`STREAM_KEYS`): the Traversal PM's node heap
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
frame's ``cache`` settings, :func:`new_streams`): packets run in pixel order with one
such object give exactly the misses of the whole image (a fresh one per packet charges
each packet from cold pairs).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from tlm.config import RunConfig
from tlm.kernels import threads
from tlm.kernels.camera import primary_rays
from tlm.kernels.emission import cosine_directions
from tlm.kernels.estimate import GATHER_STREAM
from tlm.kernels.memory import SHADING_WORDS, Accesses, Recorder, Streams, traversal_accesses
from tlm.kernels.photons import PhotonMap, PhotonMaps, PhotonTrace, trace_photons
from tlm.kernels.shade import (
    SPAWN_EPS,
    direct_light,
    emitted,
    face_normals,
    facing,
    final_gather_bounce,
    hash_uniform,
    scatter_specular,
    surface_emission,
)
from tlm.kernels.traverse import Hits, TriangleAccel, closest_hit
from tlm.kernels.work import GATHER_KEYS, STREAM_KEYS, WORK_KEYS  # the work schema, declared once
from tlm.registry import ESTIMATORS
from tlm.render.estimators import Gather
from tlm.render.planner import photon_count
from tlm.scenes.model import KIND, Scene
from tlm.scenes.normals import crease_normals, interpolate

# the caustic map's leaf reads: a stream not in tlm.kernels.memory.PM_STREAMS, so a pair of its own
# (the two maps' gathers of consecutive packets then miss as the whole image's do)
CAUSTIC_STREAM = "caustic_photons"


@dataclass(frozen=True)
class Frame:
    """What every pass reads: the scene, its BSP, per-triangle material tables, settings."""

    scene: Scene
    accel: TriangleAccel
    cfg: RunConfig
    normals: np.ndarray  # (n, 3) unit geometric normals
    shading: np.ndarray  # (n, 3, 3) unit shading normal of every corner (tlm.scenes.normals)
    kind: np.ndarray  # (n,) int8, KIND of each triangle's material
    albedo: np.ndarray  # (n, 3)
    reflectance: np.ndarray  # (n, 3)
    transmittance: np.ndarray  # (n, 3)
    ior: np.ndarray  # (n,)
    emission: np.ndarray | None  # (n, 3) radiance Le of emitting triangles (a mesh light); None: none emits
    eps: float  # spawn epsilon in scene units
    transparent: np.ndarray | None  # (n, 3) transmittance shadow rays pass through (ior 1), None: none

    @staticmethod
    def tables(scene: Scene) -> dict:
        """What a frame holds of ``scene`` beside its BSP: the material table, face and
        shading normals, the transmittance shadow rays pass through (made while the BSP
        is built: :func:`tlm.experiments.loading.load_frame`)."""
        table = scene.material_table()
        matched = (table["kind"] == KIND["dielectric"]) & (table["ior"] == 1.0)
        transparent = np.where(matched[:, None], table["transmittance"], 0.0) if matched.any() else None
        shading = scene.normals if scene.normals is not None else crease_normals(scene.triangles, scene.part)
        if not (table["emission"] > 0).any():
            table["emission"] = None
        return {**table, "normals": face_normals(scene.triangles), "shading": shading, "transparent": transparent}

    @classmethod
    def create(cls, scene: Scene, accel: TriangleAccel, cfg: RunConfig, tables: dict | None = None) -> Frame:
        """The frame of ``scene``, its BSP and ``cfg`` (``tables``: :meth:`tables` of the
        scene, when made already)."""
        return cls(scene=scene, accel=accel, cfg=cfg, eps=SPAWN_EPS * max(accel.scale, np.finfo(float).tiny),
                   **(cls.tables(scene) if tables is None else tables))

    @property
    def spp(self) -> int:
        return self.cfg.render.spp


def new_streams(frame: Frame) -> Streams:
    """Cold cache pairs of the frame's ``cache`` settings (block size, pairs per PM)."""
    return Streams(frame.cfg.cache.block_words, frame.cfg.cache.pairs)


def new_work(p: int) -> dict[str, np.ndarray]:
    return {k: np.zeros(p, dtype=np.int64) for k in WORK_KEYS}


def _add(work: dict[str, np.ndarray], index: np.ndarray, values: dict[str, np.ndarray]) -> None:
    p = next(iter(work.values())).shape[0]
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
    """Charge the recorded streams, pixel-major, to ``streams``; add the misses to ``work``
    (later corrected there when ``streams`` is a :class:`~tlm.kernels.memory.Deferred`)."""
    rec.charge(streams, work["fragments"].shape[0], {name: work[STREAM_KEYS[name]] for name, _ in rec.added})


def _trace_counts(hits: Hits) -> dict[str, np.ndarray]:
    c = hits.counts
    return {
        "node_visits": c.node_visits,
        "leaves_crossed": c.leaves_crossed,
        "leaf_visits": c.leaf_visits,
        "tri_tests": c.tri_tests,
    }


def _trace_secondary(frame: Frame, origin: np.ndarray, d: np.ndarray, ignore: np.ndarray, owner: np.ndarray,
                     work: dict[str, np.ndarray], rec: Recorder | None) -> Hits:
    """Trace rays that leave surfaces (closest hit from ``eps`` on, ignoring the triangle each
    leaves), adding one secondary ray each and their traversal work to their pixels ``owner``
    and their reads to ``rec`` (None: not recorded)."""
    p = work["secondary_rays"].shape[0]
    hits = closest_hit(frame.accel, origin, d, tmin=frame.eps, ignore=ignore, batch=frame.cfg.render.batch,
                       record=rec is not None)
    work["secondary_rays"] += np.bincount(owner, minlength=p)
    for name, c in _trace_counts(hits).items():
        work[name] += np.bincount(owner, weights=c, minlength=p).astype(np.int64)
    if rec is not None:
        _record_rays(frame, rec, hits, owner)
    return hits


def pixel_mean(frame: Frame, values: np.ndarray) -> np.ndarray:
    """(p * spp, 3) per-sample radiance -> (p, 3), each pixel's samples summed in order
    (the box filter; a pixel's value never depends on its packet)."""
    spp = frame.spp
    v = values.reshape(-1, spp, values.shape[-1])
    total = v[:, 0].copy()
    for s in range(1, spp):
        total += v[:, s]
    return total / spp if spp > 1 else total


@dataclass(frozen=True)
class GBuffer:
    """The ray-cast frame's stored hits for a packet of pixels: ``spp`` eye rays each.

    Sample ``i`` (rows of ``origin``, ``direction``, ``hits``, ...) belongs to pixel
    ``pixels[i // spp]`` and is sample ``i % spp`` of it; ``memo`` keeps the specular walks
    (:func:`specular_walk`) that the reflect, refract and photon-map passes share.
    """

    pixels: np.ndarray  # (p,) int64
    spp: int
    origin: np.ndarray  # (p * spp, 3)
    direction: np.ndarray  # (p * spp, 3) unit
    hits: Hits
    light: np.ndarray  # (p * spp, 3) radiance of a quad light seen before the surface
    sees_light: np.ndarray  # (p * spp,) bool
    surface_light: np.ndarray | None = None  # (p * spp, 3) Le of the emitting triangle hit; None: none emits
    memo: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def sees_emitter(self) -> np.ndarray:
        """(p * spp,) bool: the sample sees a light directly, a quad light or an emitting triangle."""
        if self.surface_light is None:
            return self.sees_light
        return self.sees_light | (self.surface_light.max(axis=1) > 0)

    @property
    def t(self) -> np.ndarray:
        return self.hits.t

    @property
    def triangle(self) -> np.ndarray:
        return self.hits.triangle

    @property
    def owner(self) -> np.ndarray:
        """(p * spp,) the packet index of each sample's pixel."""
        return np.arange(self.origin.shape[0], dtype=np.int64) // self.spp

    @property
    def sample_keys(self) -> np.ndarray:
        """(p * spp,) a stable id of each sample: ``pixel * spp + s``."""
        s = np.arange(self.origin.shape[0], dtype=np.int64) % self.spp
        return self.pixels[self.owner] * self.spp + s

    def every(self, values: np.ndarray) -> np.ndarray:
        """(p,) bool: whether a per-sample condition holds for all of each pixel's samples."""
        return np.asarray(values, dtype=bool).reshape(-1, self.spp).all(axis=1)

    def first(self, values: np.ndarray) -> np.ndarray:
        """Each pixel's first sample of a per-sample array (what the AOVs hold)."""
        return values[:: self.spp]

    def normal(self, frame: Frame) -> np.ndarray:
        """(p * spp, 3) geometric normals of the hit triangles (zero on a miss)."""
        n = frame.normals[np.maximum(self.triangle, 0)]
        return np.where(self.triangle[:, None] >= 0, n, 0.0)


def cast(frame: Frame, pixels: np.ndarray, record: bool = True) -> GBuffer:
    """Trace the eye rays of ``pixels`` (the ray-cast operation), ``render.spp`` per pixel.

    record : keep the nodes and leaves each ray touched (``hits.touched``), from which
        :func:`rcast_pass` charges the eye rays' page misses; the other passes do not
        need them.
    """
    pixels = np.asarray(pixels, dtype=np.int64)
    o, d = primary_rays(frame.scene.camera, pixels, frame.spp)
    hits = closest_hit(frame.accel, o, d, tmin=0.0, batch=frame.cfg.render.batch, shared_origin=True,
                       record=record)
    le, seen = emitted(frame.scene.lights, o, d, hits.t, frame.eps)
    return GBuffer(pixels, frame.spp, o, d, hits, le, seen,
                   surface_emission(frame.emission, frame.normals, hits.triangle, d))


def pixel_batches(n_pixels: int, spp: int, batch_rays: int) -> list[slice]:
    """The image's pixels ``0 .. n_pixels - 1`` cut into runs of consecutive ids, in pixel
    order, of at most ``batch_rays`` eye rays each (at least one pixel: ``spp`` rays).

    Cast and passed one after another with one :class:`~tlm.kernels.memory.Streams` per
    pass, the batches give the whole image's radiance and work exactly (a pixel's results
    never depend on its packet; its misses only on the pixels before it, in order), in
    memory bounded by the batch instead of the image.
    """
    if n_pixels < 0 or spp < 1 or batch_rays < 1:
        raise ValueError(f"n_pixels (={n_pixels}) must be >= 0, spp (={spp}) and batch_rays (={batch_rays}) >= 1")
    step = max(1, batch_rays // spp)
    return [slice(lo, min(lo + step, n_pixels)) for lo in range(0, n_pixels, step)]


class ImageGBuffer:
    """The whole image's :class:`GBuffer` for a render done in several batches.

    A batched render keeps none of its batches' G-buffers (that is the memory it saves):
    ``pixels`` and ``spp`` are at hand, and any other attribute casts the whole image
    again (:func:`cast`, the same rays, bit for bit) on first use and keeps it.
    """

    def __init__(self, frame: Frame, n_pixels: int):
        self.frame = frame
        self.pixels = np.arange(n_pixels, dtype=np.int64)
        self.spp = frame.spp
        self._whole: GBuffer | None = None

    @property
    def whole(self) -> GBuffer:
        if self._whole is None:
            self._whole = cast(self.frame, self.pixels)
        return self._whole

    def __getattr__(self, name: str):  # only for what the instance does not hold
        if name.startswith("__") or name == "_whole":
            raise AttributeError(name)
        return getattr(self.whole, name)


def shading_normals(frame: Frame, tri: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Interpolated unit shading normals at hits, on the side of the winding's geometric normal."""
    return interpolate(frame.shading, tri, u, v, frame.normals[tri])


def ray_budget(frame: Frame) -> int:
    """Rays a pass traces and keeps the reads of together: ``render.batch_rays``, the eye rays
    of a batch (on a worker of whole batches run at once, its share of them,
    :func:`tlm.kernels.threads.share`). The shadow rays of shaded points
    (:func:`_shade_lambertian`) and the rays of a specular walk, all its bounces
    (:func:`specular_walk`), go in runs of whole pixels of at most this many, so a pass
    holds no more than the batch's cast, whatever the number of lights or the specular
    depth (a pixel whose own rays are more goes alone), and the passes in flight on the
    threads no more than one batch's."""
    return max(1, frame.cfg.render.batch_rays // threads.share())


def _pixel_runs(owner: np.ndarray, size: int) -> list[np.ndarray]:
    """``owner``'s indices in runs of whole owners (pixels), owners in order, each run of at
    most ``size`` indices (an owner with more alone); an owner's indices keep their order."""
    k = owner.shape[0]
    if k <= size:
        return [np.arange(k)]
    order = np.argsort(owner, kind="stable")
    counts = np.bincount(owner)
    ends = np.cumsum(counts)
    runs, lo = [], 0
    while lo < counts.shape[0]:
        base = ends[lo] - counts[lo]
        hi = max(lo + 1, int(np.searchsorted(ends, base + size, side="right")))
        runs.append(order[base:ends[hi - 1]])
        lo = hi
    return [r for r in runs if r.shape[0]]


def _shade_lambertian(frame: Frame, owner: np.ndarray, keys: np.ndarray, points: np.ndarray,
                      d: np.ndarray, tri: np.ndarray, u: np.ndarray, v: np.ndarray,
                      work: dict[str, np.ndarray], rec: Recorder) -> np.ndarray:
    """Direct light (k, 3) at Lambertian hits (the caller weights it); records fragment and
    shadow work and reads (the shadow rays' and one shading record per fragment) under the
    pixels ``owner``.

    The points are shaded in runs of whole pixels of at most :func:`ray_budget` shadow rays
    (one per light sample), so the shadow rays' traversal buffers stay within the batch's.
    A point's light and work do not depend on its run, and a pixel's reads keep their order
    (all of a pixel's points are in one run), so the misses are those of one run."""
    per_point = sum(1 if light.kind == "point" else frame.cfg.render.light_samples for light in frame.scene.lights)
    runs = _pixel_runs(owner, max(1, ray_budget(frame) // max(1, per_point)))
    if len(runs) == 1:
        return _shade_run(frame, owner, keys, points, d, tri, u, v, work, rec)
    radiance = np.zeros((owner.shape[0], 3))
    for run in runs:
        radiance[run] = _shade_run(frame, owner[run], keys[run], points[run], d[run], tri[run], u[run], v[run],
                                   work, rec)
    return radiance


def _shade_run(frame: Frame, owner: np.ndarray, keys: np.ndarray, points: np.ndarray,
               d: np.ndarray, tri: np.ndarray, u: np.ndarray, v: np.ndarray,
               work: dict[str, np.ndarray], rec: Recorder) -> np.ndarray:
    """:func:`_shade_lambertian` of one run of points."""
    geo = frame.normals[tri]
    towards = np.sum(geo * d, axis=1) > 0  # the ray meets the back of the winding
    n_geo = np.where(towards[:, None], -geo, geo)
    n_sh = shading_normals(frame, tri, u, v)
    n_sh = np.where(towards[:, None], -n_sh, n_sh)
    radiance, w, reads = direct_light(
        frame.accel, frame.scene.lights, points, n_sh, tri, frame.albedo[tri], keys,
        frame.cfg.seed, frame.cfg.render.light_samples, frame.eps, record=True, page_words=rec.page_words,
        geometric=n_geo, transparent=frame.transparent,
    )
    _add(work, owner, w)
    _add(work, owner, {"fragments": np.ones(owner.shape[0], dtype=np.int64)})
    for name, acc in reads.items():
        rec.add(f"shadow_{name}", acc, owner)
    rec.add("shading", Accesses.of_words(tri * SHADING_WORDS, owner, rec.page_words))
    return radiance


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
    _add(work, owner, {"primary_rays": np.ones(owner.shape[0], dtype=np.int64), **_trace_counts(g.hits)})
    _record_rays(frame, rec, g.hits, owner)
    radiance[g.sees_light] = g.light[g.sees_light]
    idx = _lambertian(frame, g)
    if idx.shape[0]:
        tri = g.triangle[idx]
        pts = g.origin[idx] + g.t[idx, None] * g.direction[idx]
        keys = g.sample_keys[idx] * 64
        radiance[idx] = _shade_lambertian(frame, owner[idx], keys, pts, g.direction[idx], tri,
                                          g.hits.u[idx], g.hits.v[idx], work, rec)
    if g.surface_light is not None:  # emitting triangles seen directly (not behind a quad light)
        radiance += np.where(g.sees_light[:, None], 0.0, g.surface_light)
    _charge(rec, streams, work)
    return pixel_mean(frame, radiance), work


def _lambertian(frame: Frame, g: GBuffer) -> np.ndarray:
    """Samples whose eye ray meets a Lambertian surface (not behind a light seen directly)."""
    lam = (g.triangle >= 0) & ~g.sees_light
    lam &= frame.kind[np.maximum(g.triangle, 0)] == KIND["lambertian"]
    return np.flatnonzero(lam)


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
    The walk a packet keeps (:func:`specular_walk`) holds no reads: :func:`_walk_pass`
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
    take_l = w_refl.max(axis=1) >= min_w
    take_r = w_refr.max(axis=1) >= min_w
    order = np.argsort(np.r_[np.flatnonzero(take_l) * 2, np.flatnonzero(take_r) * 2 + 1], kind="stable")
    src = np.r_[np.flatnonzero(take_l), np.flatnonzero(take_r)][order]
    # a refraction enters the glass (against its outward normal: the medium becomes its
    # ior) or leaves it (into air); a reflection stays where it is
    entering = np.sum(d * geo, axis=1) < 0
    refracted_medium = np.where(entering, np.where(mirror, 1.0, frame.ior[tri]), 1.0)
    return {"sidx": st["sidx"][src], "tri": tri[src], "x": st["x"][src],
            "d": np.r_[refl[take_l], refr[take_r]][order], "weight": np.r_[w_refl[take_l], w_refr[take_r]][order],
            "medium": np.r_[medium[take_l], refracted_medium[take_r]][order]}


def _bounce(frame: Frame, g: GBuffer, piece: _Piece, rays: dict[str, np.ndarray], work: dict[str, np.ndarray],
            record: bool) -> None:
    """Trace one bounce's ``rays`` (:func:`_branches`) of ``piece``: lights and emitting
    triangles they see, Lambertian points where they end; the rest is the piece's new state."""
    sidx, origin, new_d, new_w, medium = rays["sidx"], rays["x"], rays["d"], rays["weight"], rays["medium"]
    bounce = piece.bounce
    owner = g.owner[sidx]
    work["specular_bounces"] += np.bincount(owner, minlength=work["specular_bounces"].shape[0])
    hits = _trace_secondary(frame, origin, new_d, rays["tri"], owner, work, piece.rec if record else None)
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
    most :func:`ray_budget` rays (a single pixel whose paths are more goes alone).

    A piece starts as the whole packet; before a bounce that would take its rays over the
    budget it is cut in two at a pixel (each half with its paths and what they found so far)
    and the first half goes on first. A path's rays do not depend on the other paths, so the
    pieces together are the walk of the whole packet, ray for ray; their reads, charged
    piece by piece in pixel order, are the packet's pixel-major stream. Yields each piece's
    :class:`Walk` (its reads when ``record``, recorded for ``page_words``-word pages; none
    otherwise) and adds the rays' work per pixel to ``work`` (:data:`WALK_WORK`)."""
    page_words = frame.cfg.cache.block_words if page_words is None else page_words
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


def _join_walk(pieces: list[Walk], work: dict[str, np.ndarray]) -> Walk:
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

    Traced in pieces of at most :func:`ray_budget` rays (:func:`walk_pieces`), so the
    memory it takes is the batch's whatever the depth. Remembered in ``g.memo`` without
    its reads: the reflect, refract and photon-map passes share one walk (the first of
    them to need it, :func:`_walk_pass`, traces it and charges its reads piece by piece).
    """
    key = _walk_key(frame, first_kind, depth)
    if key not in g.memo:
        work = {k: np.zeros(g.pixels.shape[0], dtype=np.int64) for k in WALK_WORK}
        g.memo[key] = _join_walk(list(walk_pieces(frame, g, first_kind, depth, work, record=False)), work)
    return g.memo[key]


def _walk_key(frame: Frame, first_kind: str, depth: int) -> tuple:
    return ("walk", first_kind, depth, frame.cfg.render.min_weight, frame.cfg.render.fresnel)


def _walk_pass(frame: Frame, g: GBuffer, first_kind: str, depth: int, streams: Streams | None):
    """A specular frame: lights seen along the walk and direct light where it ends.

    Its reads are charged pixel-major: a pixel's rays bounce by bounce, then the shadow
    rays and shading records of the points they reach; packets in pixel order with a
    carried ``streams`` give the misses of the whole image. The walk goes piece by piece
    (:func:`walk_pieces`): each piece's ends are shaded and its reads charged before the
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
            direct = _shade_lambertian(frame, g.owner[e.sample], keys, e.point, e.direction, e.triangle, e.u, e.v,
                                       work, rec)
            np.add.at(radiance, e.sample, direct * e.weight)
        _charge(rec, streams, work)
        kept.append(replace(piece, reads=[]))
        del rec, piece
    for k, v in walk_work.items():
        work[k] += v
    g.memo.setdefault(_walk_key(frame, first_kind, depth), _join_walk(kept, walk_work))
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
    return _gather_points(frame, g)[:5]  # type: ignore[return-value]


def _gather_points(frame: Frame, g: GBuffer) -> tuple[np.ndarray, ...]:
    """:func:`gather_points`, each point's bounce (0: the eye hit; j: the end of a walk after j) and
    the index of refraction of the medium it lies in (:class:`Ends`)."""
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


def trace_photon_map(frame: Frame, n: int | None = None, seed: int | None = None, warm: bool = False) -> PhotonTrace:
    """The frame's photon maps by its ``photons.*`` settings (``n``, ``seed``: overrides).
    ``warm``: with each map in leaf order and the density radii the frame asks for
    (:func:`density_wanted`), made with the maps' trees on the threads (before batches run
    at once: :func:`tlm.render.batches.render_batches`)."""
    cfg = frame.cfg
    return trace_photons(
        frame.scene, frame.accel, photon_count(frame.scene, cfg) if n is None else n,
        seed=cfg.seed if seed is None else seed, max_bounces=cfg.photons.max_bounces,
        russian_roulette=cfg.photons.russian_roulette, levels=cfg.photons.levels,
        leaf_photons=cfg.photons.leaf_photons,
        caustic_fraction=cfg.photons.caustic_fraction, caustic_count=cfg.photons.caustic_count,
        aim=cfg.photons.aim, aim_triangles=cfg.photons.aim_triangles, global_map=cfg.estimate.final_gather > 0,
        batch=cfg.render.batch, batch_rays=ray_budget(frame),
        page_words=cfg.cache.block_words, pairs=cfg.cache.pairs, fresnel=cfg.render.fresnel,
        normals=frame.normals, shading=frame.shading,
        table={"kind": frame.kind, "albedo": frame.albedo, "reflectance": frame.reflectance,
               "transmittance": frame.transmittance, "ior": frame.ior},
        prepare=warm, radii=density_wanted(frame) if warm else (),
    )


# the fractions of the scene's diagonal a map's radius falls back to when the density rule has
# nothing to measure (a map of fewer than 2 photons): the rule before it
FALLBACK_FRACTION = {"indirect": 0.04, "caustic": 0.01}


def _map_of(photons: PhotonMaps | PhotonMap | None, which: str) -> PhotonMap | None:
    if isinstance(photons, PhotonMaps):
        return photons.caustic_map if which == "caustic" else photons.indirect_map
    return photons  # a single map (or None) is gathered alone with either radius


def radius_rule(frame: Frame, which: str = "indirect") -> str:
    """How the ``which`` ("indirect" or "caustic") map's radius is chosen: ``radius`` (the
    scene units given), ``fraction`` (of the diagonal) or ``density`` (holds about k photons)."""
    est = frame.cfg.estimate
    given, fraction = ((est.caustic_radius, est.caustic_radius_fraction) if which == "caustic"
                       else (est.radius, est.radius_fraction))
    return "radius" if given is not None else "fraction" if fraction is not None else "density"


def _radius(frame: Frame, photons: PhotonMaps | PhotonMap | None, which: str) -> float:
    est = frame.cfg.estimate
    given, fraction, k = ((est.caustic_radius, est.caustic_radius_fraction, est.caustic_radius_photons)
                          if which == "caustic" else (est.radius, est.radius_fraction, est.radius_photons))
    rule = radius_rule(frame, which)
    if rule == "radius":
        return given
    if rule == "density":
        m = _map_of(photons, which)
        if m is None:
            raise ValueError(f"the {which} map's radius follows the density rule: pass the photon map")
        r = m.density_radius(k)
        if r is not None:
            return r
        fraction = FALLBACK_FRACTION[which]
    return fraction * frame.accel.scale


def search_radius(frame: Frame, photons: PhotonMaps | PhotonMap | None = None) -> float:
    """The global (indirect) map's fixed search radius r: ``estimate.radius``, else
    ``radius_fraction`` x the scene diagonal, else the density rule on ``photons``' indirect
    map (a single map: that map): the radius holding about ``radius_photons`` photons
    (:func:`tlm.kernels.estimate.density_radius`; 0.04 x the diagonal for a map too small
    to measure)."""
    return _radius(frame, photons, "indirect")


def caustic_radius(frame: Frame, photons: PhotonMaps | PhotonMap | None = None) -> float:
    """The caustic map's search radius: ``estimate.caustic_radius``, else
    ``caustic_radius_fraction`` x the diagonal, else the density rule on the caustic map
    (``caustic_radius_photons``; 0.01 x the diagonal for a map too small to measure)."""
    return _radius(frame, photons, "caustic")


def density_wanted(frame: Frame) -> list[tuple[str, int]]:
    """The ``(map, k)`` whose density radius the pmap frame's radii ask for (:func:`radii`,
    :func:`global_radius`, :func:`_radius`), from its settings alone: map "global" (final
    gathering's map, when the trace keeps one), "indirect" or "caustic" (the one map of a
    trace without the split stands for both: :func:`density_requests`)."""
    est = frame.cfg.estimate
    out = []
    if est.final_gather > 0 and est.radius is None and est.radius_fraction is None:
        out.append(("global", est.final_gather_photons))
    for which, k in (("indirect", est.radius_photons), ("caustic", est.caustic_radius_photons)):
        if radius_rule(frame, which) == "density":
            out.append((which, k))
    return out


def density_requests(frame: Frame, photons: PhotonMaps | PhotonMap) -> list[tuple[PhotonMap, int]]:
    """:func:`density_wanted` of ``photons``' maps: the ``(map, k)`` whose density radius
    (:meth:`PhotonMap.density_radius`) the pmap frame's radii ask for, each map once per ``k``."""
    once: list[tuple[PhotonMap, int]] = []
    for which, k in density_wanted(frame):
        m = (photons.global_map if final_gathering(frame, photons) else None) if which == "global" else _map_of(
            photons, which)
        if m is not None and not any(m is m2 and k == k2 for m2, k2 in once):
            once.append((m, k))
    return once


def radii(frame: Frame, photons: PhotonMaps | PhotonMap) -> dict:
    """The search radii a pmap frame used and how each was chosen (``results.json``)."""
    est = frame.cfg.estimate
    out = {}
    if final_gathering(frame, photons):
        explicit = est.radius is not None or est.radius_fraction is not None
        out["global_radius"] = global_radius(frame, photons)
        out["global_radius_rule"] = radius_rule(frame, "indirect") if explicit else "density"
        if not explicit:
            out["global_radius_photons"] = est.final_gather_photons
        out["final_gather"] = est.final_gather
    for which, key, k in (("indirect", "radius", est.radius_photons),
                          ("caustic", "caustic_radius", est.caustic_radius_photons)):
        rule = radius_rule(frame, which)
        out[key] = _radius(frame, photons, which)
        out[f"{key}_rule"] = rule
        if rule == "density":
            out[f"{key}_photons"] = k
    return out


def _estimate(frame: Frame, photons: PhotonMap, radius: float, pts, n, keys, streams, kdtree, stream: str):
    """One map's density at the gather points, by the estimator ``estimate.filter`` names."""
    est = ESTIMATORS[frame.cfg.estimate.filter](frame.cfg.estimate, seed=frame.cfg.seed)
    return est(Gather(photons.position, photons.power, photons.incoming, photons.tree, pts, n, radius, keys,
                      streams, stream, kdtree, photons.prepared()))


def global_radius(frame: Frame, photons: PhotonMaps) -> float:
    """The global map's search radius (final gathering): ``estimate.radius`` or
    ``radius_fraction`` when given (as the indirect map's), else the density rule with
    ``final_gather_photons`` on the global map."""
    est = frame.cfg.estimate
    if est.radius is not None or est.radius_fraction is not None:
        return search_radius(frame, photons)
    r = photons.global_map.density_radius(est.final_gather_photons) if photons.global_map is not None else None
    return FALLBACK_FRACTION["indirect"] * frame.accel.scale if r is None else r


def final_gathering(frame: Frame, photons: PhotonMaps | PhotonMap | None) -> bool:
    """Whether the photon-map frame gathers the indirect light by final gathering
    (``estimate.final_gather`` > 0 and the trace kept a global map)."""
    return (frame.cfg.estimate.final_gather > 0 and isinstance(photons, PhotonMaps)
            and photons.global_map is not None)


# final-gather rays traced together: their hits and reads are per chunk, so memory is bounded
# by it, not by the batch's gather points x estimate.final_gather
FG_CHUNK_RAYS = 1 << 16


def _fg_key(seed: int) -> int:
    return int(np.random.SeedSequence([seed, 0xF16A7]).generate_state(1, dtype=np.uint64)[0] >> 1)


def final_gather_directions(normals: np.ndarray, point_keys: np.ndarray, rays: int, seed: int):
    """``rays`` cosine-weighted unit directions about each unit normal (m, 3), stratified
    (``rays`` a square: a sqrt x sqrt grid over the two sample dimensions; otherwise strata
    of the polar dimension), seeded by each point's key and the ray's index, never by its
    neighbours. Returns the point of each ray (m * rays,), its index (m * rays,) and its
    direction (m * rays, 3), point-major."""
    m = normals.shape[0]
    j = np.repeat(np.arange(m, dtype=np.int64), rays)
    r = np.tile(np.arange(rays, dtype=np.int64), m)
    key = _fg_key(seed)
    x1 = hash_uniform(key, point_keys[j], r, 0)
    x2 = hash_uniform(key, point_keys[j], r, 1)
    side = math.isqrt(rays)
    if side * side == rays:
        u1, u2 = (r // side + x1) / side, (r % side + x2) / side
    else:
        u1, u2 = (r + x1) / rays, x2
    return j, r, cosine_directions(normals[j], u1, u2)


def _final_gather_chunk(frame: Frame, gmap: PhotonMap, radius: float, pts: np.ndarray, n: np.ndarray,
                        tri: np.ndarray, pkeys: np.ndarray, medium: np.ndarray, owner: np.ndarray, p: int,
                        ray_work: dict, gather_work: dict, ray_streams: Streams, gather_streams: Streams,
                        per_map: dict | None) -> np.ndarray:
    """Final gathering at a chunk of gather points (all of their pixels' points): returns
    each point's gathered flux density (m, 3), pi / N x the sum of the rays' radiance, so
    that ``albedo / pi`` of it is the reflected indirect radiance, as a map's density."""
    cfg = frame.cfg
    rays = cfg.estimate.final_gather
    j, r, d = final_gather_directions(n, pkeys, rays, cfg.seed)
    origin, ignore = pts[j], tri[j]
    w = np.ones((j.shape[0], 3))
    med = medium[j]  # the index of refraction around each ray
    key = _fg_key(cfg.seed)
    lights = tuple(lt for lt in frame.scene.lights if max(lt.power) > 0)
    rec = Recorder(ray_streams.page_words)
    found: dict[str, list[np.ndarray]] = {k: [] for k in ("j", "r", "x", "n", "w", "tri")}
    depth = cfg.render.refract_depth
    table = {"kind": frame.kind, "normals": frame.normals, "shading": frame.shading, "ior": frame.ior,
             "reflectance": frame.reflectance, "transmittance": frame.transmittance}
    for bounce in range(depth + 1):
        if j.shape[0] == 0:
            break
        o = owner[j]
        hits = _trace_secondary(frame, origin, d, ignore, o, ray_work, rec)
        # a light seen is direct light, the ray-cast frame's (shadow rays): the ray ends there (a
        # light without power emits nothing and hides nothing: the ray sees what lies behind it)
        _, seen = emitted(lights, origin, d, hits.t, frame.eps)
        # the gathers (rays that end on a Lambertian surface) and the rays that go on (mirrors, glass)
        got, (j, r, med, w, origin, d, ignore) = final_gather_bounce(
            key, bounce, bounce >= depth, j, r, owner, pkeys, medium, med, w, origin, d, hits, seen, table,
            cfg.render.fresnel, ray_work["fragments"], ray_work["specular_bounces"])
        for name, val in zip(("j", "r", "x", "n", "w", "tri"), got, strict=True):
            found[name].append(val)
        rec.add("shading", Accesses.of_words(got[5] * SHADING_WORDS, owner[got[0]], rec.page_words))
    _charge(rec, ray_streams, ray_work)
    m = pts.shape[0]
    flux = np.zeros((m, 3))
    lj = np.concatenate(found["j"])
    if lj.shape[0] == 0:
        return flux
    lr = np.concatenate(found["r"])
    order = np.lexsort((lr, lj))  # point-major, ray by ray: the Fragment PM gathers pixel by pixel
    lj, lr = lj[order], lr[order]
    lx, ln, lw, lt = (np.concatenate(found[k])[order] for k in ("x", "n", "w", "tri"))
    e = _estimate(frame, gmap, radius, lx, ln, pkeys[lj] * rays + lr, gather_streams, None, GATHER_STREAM)
    np.add.at(flux, lj, lw * frame.albedo[lt] / np.pi * e.density)
    lo = owner[lj]
    gather_work["gathers"] += np.bincount(lo, minlength=p)
    for k in GATHER_KEYS[1:]:
        _add_per_pixel(gather_work, k, lo, e, gather_streams)
    if per_map is not None:
        tally = per_map.setdefault("global", dict.fromkeys(("photons_tested", "photons_accepted", "leaves_visited",
                                                            "gathers"), 0))
        for k in ("photons_tested", "photons_accepted", "leaves_visited"):
            tally[k] += int(getattr(e, k).sum())
        tally["gathers"] += int(lj.shape[0])
    return flux * (np.pi / rays)


def _add_per_pixel(work: dict, k: str, owner: np.ndarray, e, streams: Streams) -> None:
    """Add the gathers' count ``k`` of ``e`` to their pixels ``owner`` (the misses through
    ``streams.fold``, which a :class:`~tlm.kernels.memory.Deferred` corrects later)."""
    if k == "gather_misses":
        streams.fold(e.gather_misses, owner, work[k])
    else:
        work[k] += np.bincount(owner, weights=getattr(e, k), minlength=work[k].shape[0]).astype(np.int64)


def fgather_pass(frame: Frame, g: GBuffer, streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The final-gather rays' work (a ray pass of the Traversal, Intersection and Fragment
    PMs: rays, triangle tests, the shading record of each hit), traced by
    :func:`pmap_pass` of the same packet (which must run first, with ``fg_streams``); its
    radiance is the photon-map frame's, so this pass's own is zero."""
    if "fgather_work" not in g.memo:
        raise ValueError("fgather_pass: run pmap_pass on this packet first (final gathering traces its rays)")
    return np.zeros((g.pixels.shape[0], 3)), g.memo.pop("fgather_work")


def pmap_pass(frame: Frame, g: GBuffer, photons: PhotonMaps | PhotonMap, kdtree=None,
              streams: Streams | None = None, per_map: dict | None = None,
              fg_streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The photon-map frame: ``albedo / pi * density`` at every gather point (:func:`gather_points`).

    ``density`` is the reflected flux density by the configured filter: the caustic map's
    within :func:`caustic_radius` plus the indirect map's within :func:`search_radius`
    (a single :class:`PhotonMap` is gathered alone with the latter). ``kdtree``: optional
    prebuilt ``cKDTree`` of a single map's positions for the exact k-nearest estimate.
    ``gather_misses``: the photon-leaf stream's misses, gathers in pixel order (the
    caustic map's leaves on a pair of their own, :data:`CAUSTIC_STREAM`; the indirect map's
    on the Fragment PM's ``photons`` pair), ``streams`` as in :func:`rcast_pass`.
    ``per_map``: a dict to which each map's totals are added (``"caustic"``, ``"indirect"``
    or, for a single map, ``"photons"`` -> ``photons_tested``, ``photons_accepted``,
    ``leaves_visited``), the split of the work's sums between the two maps.

    With final gathering (:func:`final_gathering`), the indirect map is not gathered: at
    every gather point ``estimate.final_gather`` stratified cosine-weighted rays (through
    mirrors and glass, one Fresnel branch each, up to ``render.refract_depth``) reach
    Lambertian points where the global map (:attr:`PhotonMaps.global_map`, direct light
    included) is gathered (within :func:`global_radius`, on the indirect map's pair); the
    point's indirect density is pi / N x the sum of their radiance (Jensen). Those
    gathers are this pass's work (``per_map["global"]``); the rays' work (a ray pass's
    keys, charged to ``fg_streams``) is left in ``g.memo["fgather_work"]`` for
    :func:`fgather_pass`.
    """
    p = g.pixels.shape[0]
    work = {k: np.zeros(p, dtype=np.int64) for k in GATHER_KEYS}
    radiance = np.zeros((g.origin.shape[0], 3))
    fg = final_gathering(frame, photons)
    if fg:
        g.memo["fgather_work"] = new_work(p)
    sidx, tri, pts, n, weight, bounce, medium = _gather_points(frame, g)
    if isinstance(photons, PhotonMap):
        maps = [("photons", photons, search_radius(frame, photons), kdtree, GATHER_STREAM)]
    else:  # (with final gathering the indirect map is not gathered here: its radius is not needed)
        maps = [("caustic", photons.caustic_map, caustic_radius(frame, photons), None, CAUSTIC_STREAM)]
        if not fg:
            maps.append(("indirect", photons.indirect_map, search_radius(frame, photons), None, GATHER_STREAM))
    maps = [m for m in maps if m[1].n > 0]
    if sidx.shape[0] == 0 or not (maps or fg):
        return pixel_mean(frame, radiance), work
    streams = new_streams(frame) if streams is None else streams
    owner = g.owner[sidx]
    keys = g.sample_keys[sidx]
    density = np.zeros((sidx.shape[0], 3))
    if fg and photons.global_map.n > 0:
        fg_streams = new_streams(frame) if fg_streams is None else fg_streams
        radius = global_radius(frame, photons)
        pkeys = keys * 64 + bounce
        # chunks of whole pixels, in pixel order, of at most FG_CHUNK_RAYS rays
        step = max(1, FG_CHUNK_RAYS // frame.cfg.estimate.final_gather)
        bounds = np.r_[np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]]), sidx.shape[0]]
        lo = 0
        while lo < sidx.shape[0]:
            hi = bounds[np.searchsorted(bounds, lo + step, side="right") - 1]
            if hi <= lo:  # one pixel's points are more than a chunk: that pixel alone
                hi = bounds[np.searchsorted(bounds, lo, side="right")]
            sl = slice(lo, int(hi))
            density[sl] += _final_gather_chunk(frame, photons.global_map, radius, pts[sl], n[sl], tri[sl],
                                               pkeys[sl], medium[sl], owner[sl], p, g.memo["fgather_work"], work,
                                               fg_streams, streams, per_map)
            lo = hi
    for name, ph, radius, tree, stream in maps:
        e = _estimate(frame, ph, radius, pts, n, keys, streams, tree, stream)
        density += e.density
        if per_map is not None:
            tally = per_map.setdefault(name, dict.fromkeys(("photons_tested", "photons_accepted", "leaves_visited"), 0))
            for k in ("photons_tested", "photons_accepted", "leaves_visited"):
                tally[k] += int(getattr(e, k).sum())
            tally["gathers"] = tally.get("gathers", 0) + int(sidx.shape[0])
        for k in GATHER_KEYS[1:]:
            _add_per_pixel(work, k, owner, e, streams)
    np.add.at(radiance, sidx, weight * frame.albedo[tri] / np.pi * density)
    if maps:  # (the points' own searches; final gathering's lookups are counted where they land)
        work["gathers"] += np.bincount(owner, minlength=p)
    return pixel_mean(frame, radiance), work


PASS_FUNCTIONS = {"rcast": rcast_pass, "reflect": reflect_pass, "refract": refract_pass,
                  "fgather": fgather_pass}  # (after pmap_pass of the same packet, which traces its rays)
# the passes whose work is traced by another (pmap_pass traces the final-gather rays)
TRACED_BY = {"fgather": "pmap"}
