"""A frame's scene, its eye rays and the helpers every pass shares.

* :class:`Frame`: what every pass of one frame reads (the scene, its tree, the materials,
  the config);
* :func:`cast` traces the eye rays of a packet of pixels into a :class:`GBuffer` (the
  stored intersection points and normals every later pass starts from);
* the work and page-miss bookkeeping of the passes (:func:`new_work`, :func:`new_streams`,
  the recorders of traced rays), a secondary ray's trace, and the direct light at
  Lambertian points with its shadow rays (:func:`shade_lambertian`).

The passes themselves are :mod:`tlm.render.passes` (ray cast, reflection, refraction),
:mod:`tlm.render.walk` (the specular walk they share with the photon-map frame) and
:mod:`tlm.render.pmap` (the photon-map frame and final gathering).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from tlm.config import RunConfig
from tlm.kernels import threads
from tlm.kernels.camera import primary_rays
from tlm.kernels.memory import SHADING_WORDS, Accesses, Streams
from tlm.kernels.recording import Recorder, traversal_accesses
from tlm.kernels.shade import (
    SPAWN_EPS,
    direct_light,
    emitted,
    face_normals,
    surface_emission,
)
from tlm.kernels.traverse import Hits, TriangleAccel, closest_hit
from tlm.kernels.work import STREAM_KEYS, WORK_KEYS  # the work schema, declared once
from tlm.scenes.model import DELTA_KINDS, KIND, Scene
from tlm.scenes.normals import crease_normals, interpolate


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
    """Cold cache pairs of the frame's ``cache`` settings, every key (:meth:`Streams.of`)."""
    return Streams.of(frame.cfg.cache)


def new_work(p: int) -> dict[str, np.ndarray]:
    return {k: np.zeros(p, dtype=np.int64) for k in WORK_KEYS}


def add_work(work: dict[str, np.ndarray], index: np.ndarray, values: dict[str, np.ndarray]) -> None:
    p = next(iter(work.values())).shape[0]
    for k, v in values.items():
        work[k] += np.bincount(index, weights=v, minlength=p).astype(np.int64)


def record_rays(frame: Frame, rec: Recorder, hits: Hits, owners: np.ndarray | None = None) -> None:
    """Add a traversal's reads (node heap, leaf indices, vertices) to ``rec``; ray i is owner ``owners[i]``."""
    if hits.touched is None:
        raise ValueError("the rays were traced without record=True: their reads are unknown")
    accel = frame.accel
    for name, acc in traversal_accesses(hits.touched, accel.leaf_first, accel.leaf_last, rec.page_words).items():
        rec.add(name, acc, owners)


def charge(rec: Recorder, streams: Streams, work: dict[str, np.ndarray]) -> None:
    """Charge the recorded streams, pixel-major, to ``streams``; add the misses to ``work``
    (later corrected there when ``streams`` is a :class:`~tlm.kernels.recording.Deferred`)."""
    rec.charge(streams, work["fragments"].shape[0], {name: work[STREAM_KEYS[name]] for name, _ in rec.added})


def trace_counts(hits: Hits) -> dict[str, np.ndarray]:
    c = hits.counts
    return {
        "node_visits": c.node_visits,
        "leaves_crossed": c.leaves_crossed,
        "leaf_visits": c.leaf_visits,
        "tri_tests": c.tri_tests,
    }


def trace_secondary(frame: Frame, origin: np.ndarray, d: np.ndarray, ignore: np.ndarray, owner: np.ndarray,
                     work: dict[str, np.ndarray], rec: Recorder | None) -> Hits:
    """Trace rays that leave surfaces (closest hit from ``eps`` on, ignoring the triangle each
    leaves), adding one secondary ray each and their traversal work to their pixels ``owner``
    and their reads to ``rec`` (None: not recorded)."""
    p = work["secondary_rays"].shape[0]
    hits = closest_hit(frame.accel, origin, d, tmin=frame.eps, ignore=ignore, batch=frame.cfg.render.batch,
                       record=rec is not None)
    work["secondary_rays"] += np.bincount(owner, minlength=p)
    for name, c in trace_counts(hits).items():
        work[name] += np.bincount(owner, weights=c, minlength=p).astype(np.int64)
    if rec is not None:
        record_rays(frame, rec, hits, owner)
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
    (:func:`~tlm.render.walk.specular_walk`) that the reflect, refract and photon-map passes share.
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
        :func:`~tlm.render.passes.rcast_pass` charges the eye rays' page misses; the other passes do not
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
    (:func:`shade_lambertian`) and the rays of a specular walk, all its bounces
    (:func:`~tlm.render.walk.specular_walk`), go in runs of whole pixels of at most this many, so a pass
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


def shade_lambertian(frame: Frame, owner: np.ndarray, keys: np.ndarray, points: np.ndarray,
                      d: np.ndarray, tri: np.ndarray, u: np.ndarray, v: np.ndarray,
                      work: dict[str, np.ndarray], rec: Recorder) -> np.ndarray:
    """Direct light (k, 3) at Lambertian hits (the caller weights it); records fragment and
    shadow work and reads (the shadow rays' and one shading record per fragment) under the
    pixels ``owner``.

    The points are shaded in runs of whole pixels of at most :func:`ray_budget` shadow rays
    (one per light sample), so the shadow rays' traversal buffers stay within the batch's.
    A point's light and work do not depend on its run, and a pixel's reads keep their order
    (all of a pixel's points are in one run), so the misses are those of one run."""
    per_point = sum(1 if light.kind in DELTA_KINDS else frame.cfg.render.light_samples
                    for light in frame.scene.lights)
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
    """:func:`shade_lambertian` of one run of points."""
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
    add_work(work, owner, w)
    add_work(work, owner, {"fragments": np.ones(owner.shape[0], dtype=np.int64)})
    for name, acc in reads.items():
        rec.add(f"shadow_{name}", acc, owner)
    rec.add("shading", Accesses.of_words(tri * SHADING_WORDS, owner, rec.page_words))
    return radiance
