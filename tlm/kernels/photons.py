"""Photon emission and tracing (thesis §III.A, Fig. 4): the photon map's raw data.

"The first step in creating a photon map is backward ray tracing, i.e. tracing rays
from a light source. When the path of the photon is obstructed by a Lambertian surface,
we store that photon. Russian roulette method is used to eliminate photons depending on
the absorbance of the surface and construct secondary reflected/refracted photon path
arrays."

* **Emission** (:mod:`tlm.kernels.emission`): the photons' origins, directions and
  powers, the caustic group aimed at the specular objects.
* **Tracing** runs through the geometry BSP with the same traversal kernel as eye
  rays, all photons of a bounce at once. A Lambertian hit stores the photon (position,
  normal facing the arriving side, RGB power, incoming direction), then Russian
  roulette on the albedo decides whether it is reflected diffusely (probability
  ``max(albedo)``, power scaled by ``albedo / p``) or absorbed. Mirrors reflect (power
  times reflectance); glass reflects with the Fresnel probability ``F`` (Russian
  roulette: power unchanged) or refracts (power times transmittance), total internal
  reflection included; directions about the interpolated shading normals, as for eye
  rays. Paths stop at ``max_bounces`` surface hits; the power the global group's photons
  still carried then is :attr:`PhotonMaps.cut_power` (:func:`cut_power`), its share that of
  the power that reached the scene (:attr:`PhotonMaps.cut_share`).
* **What the maps hold.** The ray-cast frame already renders direct light (shadow
  rays), so a photon's *first* surface hit, straight from the light, is not stored (nor
  after crossing only index-matched glass, which shadow rays pass too): the caustic map
  holds light that reached the Lambertian surface through mirrors or glass only
  (L S+ D), the indirect map light after at least one diffuse bounce (L D ... D) — the
  two effects the thesis's PMap column adds (:class:`PhotonMaps`, a BSP each).

Work per emitted photon (:data:`PHOTON_WORK`) includes the page misses of its rays'
reads (:mod:`tlm.kernels.memory`), all its bounces: ``trav_misses`` (the Traversal PM's
node-heap and leaf-index streams, on pairs of their own or, with ``pairs`` = 1, on one
pair: a photon's node reads then its leaf indices, bounce by bounce) and
``isect_misses`` (the Intersection PM's vertex stream), on ``page_words``-word pages.
The bounces are traced for all photons at once, but the streams are charged
photon-major (a photon's rays bounce by bounce, photons in emission order), so the
misses of consecutive photons are those of the photons traced as packets in order.

Random numbers: a :class:`numpy.random.SeedSequence` of the run's seed gives the key
of a counter-based hash (:func:`tlm.kernels.shade.hash_uniform`) indexed by (photon,
bounce, dimension), so every photon's path is the same whichever photons it is traced
with, and a run repeats exactly.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from tlm.kernels import threads
from tlm.kernels.bsp import BSPTree, bounds, build_point_tree
from tlm.kernels.emission import aim_boxes, cosine_directions, emit, photon_key
from tlm.kernels.engine import engine
from tlm.kernels.estimate import density_radius, leaf_photons
from tlm.kernels.memory import PAGE_WORDS, PAIRS, Streams
from tlm.kernels.recording import Deferred, Recorder, traversal_accesses
from tlm.kernels.shade import SPAWN_EPS, face_normals, facing, hash_uniform, scatter_specular
from tlm.kernels.traverse import TriangleAccel, closest_hit
from tlm.kernels.work import PHOTON_WORK, PhotonWork, stream_keys
from tlm.progress import checkpoint
from tlm.scenes.model import KIND, Scene
from tlm.scenes.normals import crease_normals, interpolate

_MISS_KEYS = stream_keys(PhotonWork)  # each stream's work key (tlm.kernels.work)
STORED = ("position", "normal", "incoming", "power", "caustic")  # what a stored photon holds
# what every emitted photon holds at once, at the least, while the photons are traced: its
# origin, direction and power (float64), its source light and its work counts (int64)
PHOTON_BYTES = 9 * 8 + 8 + 8 * len(PHOTON_WORK)
PHOTON_MIN_CHUNK = 4096  # photons a chunk traces at the least when they are cut between threads
# the photons a chunk may hold whatever ``render.batch_rays``: chunks of at most
# max(PHOTON_MIN_BATCH, batch_rays // max_bounces) photons (the last of a thread's span
# shorter). Each chunk has a fixed cost (its kernel calls, bounce by bounce, and its
# charges), so a small budget (chunks of a few hundred photons) traced the conference
# room's photons 3.3x slower (benchmarks/bench_photon_chunks.py). The price: a chunk may
# hold the reads of up to 4,096 x max_bounces rays (32k at 8 bounces) whatever the
# budget, and twice the threads' chunks are in flight at once
PHOTON_MIN_BATCH = 4096

# the maps the pipeline keeps and gathers, by whether the trace keeps a global map (final
# gathering's): the Vertex PM builds their trees (:attr:`PhotonMaps.gathered`) and a trace asked to
# ``prepare`` puts them in leaf order; with a global map the indirect map is the software's only (its
# statistics and the reference), never gathered (:func:`tlm.render.pmap.gathered_maps`, the render's
# rule, says which of them a frame gathers: not an empty one)
PIPELINE_MAPS = {False: ("caustic", "indirect"), True: ("caustic", "global")}
LUMINANCE = (0.2126, 0.7152, 0.0722)  # Rec. 709: the weights of :attr:`PhotonMaps.cut_share`


def cut_power(powers: Sequence[np.ndarray]) -> tuple[float, float, float]:
    """The RGB sum of the (k, 3) ``powers`` (the photons ``max_bounces`` cut, chunk by chunk),
    each channel by :func:`math.fsum`: correctly rounded, so the same whichever chunks (threads,
    ``render.batch_rays``) the photons were traced in and in what order."""
    return tuple(math.fsum(v for a in powers for v in a[:, c].tolist()) for c in range(3))


def cut_share(cut: Sequence[float], emitted: Sequence[float]) -> float:
    """``cut``'s luminance (:data:`LUMINANCE`) over ``emitted``'s (the trace's: the power that reached the scene,
    :func:`reached`): the share of it the photons still carried when ``max_bounces`` ended their paths (0.0 where
    nothing was emitted)."""
    total = math.fsum(w * x for w, x in zip(LUMINANCE, emitted, strict=True))
    return math.fsum(w * x for w, x in zip(LUMINANCE, cut, strict=True)) / total if total > 0 else 0.0


def reached(work: dict[str, np.ndarray]) -> np.ndarray:
    """Which photons reached the scene, by their ``work`` (:data:`~tlm.kernels.work.PHOTON_WORK`, per photon): all
    but those whose first ray hit nothing (no ``bounces``, a ray ``lost``), whose power left the scene at once (an
    open scene's sky; most of a directional light's disc, which covers the scene's bounding sphere). A photon that
    ``max_bounces`` 0 stops before its first ray is counted: its power is cut, not gone. The denominator of
    :attr:`PhotonMaps.cut_share`, the same rule for every light (h529)."""
    return (work["bounces"] > 0) | (work["lost"] == 0)


def photon_spans(n: int, max_bounces: int, batch_rays: int | None) -> list[tuple[int, int]]:
    """The chunks ``(start, stop)`` the photons ``0 .. n - 1`` are traced in, in order: cut
    between the threads (:func:`tlm.kernels.threads.spans`), then into chunks of at most
    ``max(PHOTON_MIN_BATCH, batch_rays // max_bounces)`` photons (all bounces of
    ``batch_rays`` rays, unless that is fewer than :data:`PHOTON_MIN_BATCH` photons; the
    last chunk of a thread's span may be shorter; None: no bound)."""
    spans = threads.spans(n, PHOTON_MIN_CHUNK)
    if batch_rays is not None:  # chunks of at most batch_rays rays, all bounces
        most = max(PHOTON_MIN_BATCH, batch_rays // max(1, max_bounces))
        spans = [(x, min(hi, x + most)) for lo, hi in spans for x in range(lo, hi, most)]
    return spans


@dataclass(frozen=True)
class PhotonMap:
    """Stored photons and their BSP (Algorithm 1).

    position, normal, incoming : (n, 3) float64 (normal faces the arriving side;
    incoming is the unit direction of travel). power : (n, 3) float64 RGB watts.
    caustic : (n,) bool, the photon reached its surface through specular bounces only.
    tree : the photon BSP over ``position``.
    """

    position: np.ndarray
    normal: np.ndarray
    incoming: np.ndarray
    power: np.ndarray
    caustic: np.ndarray
    tree: BSPTree
    emitted: int
    _memo: dict = field(default_factory=dict, compare=False, repr=False)

    @property
    def n(self) -> int:
        return int(self.position.shape[0])

    def prepared(self):
        """The map in its tree's leaf order (:func:`tlm.kernels.estimate.leaf_photons`), made once."""
        if "leaf_order" not in self._memo:
            self._memo["leaf_order"] = leaf_photons(self.position, self.power, self.incoming, self.tree)
        return self._memo["leaf_order"]

    def density_radius(self, k: int) -> float | None:
        """:func:`tlm.kernels.estimate.density_radius` of this map, computed once per ``k``."""
        if k not in self._memo:
            self._memo[k] = density_radius(self.position, k)
        return self._memo[k]

    def stats(self) -> dict:
        return {
            "emitted": self.emitted,
            "stored": self.n,
            "caustic": int(self.caustic.sum()),
            "indirect": int((~self.caustic).sum()),
            "stored_power": self.power.sum(axis=0).tolist(),
            "tree": self.tree.stats(),
        }


@dataclass(frozen=True)
class PhotonMaps:
    """Jensen's two maps: ``caustic`` (L S+ D, gathered with a small radius: caustics are
    sharp) and ``indirect`` (the global map: at least one diffuse bounce, gathered with
    a larger one: indirect light is smooth), each with its own BSP (Algorithm 1).

    The arrays of both (caustic photons first) are available as one map's would be.
    """

    caustic_map: PhotonMap
    indirect_map: PhotonMap
    emitted: int
    global_map: PhotonMap | None = None  # final gathering's: every diffuse hit of the global group (None: off)
    # the power (RGB) the global group's photons still carried when max_bounces ended their paths, an estimate of
    # the lights' power still in flight, and its luminance's share of the power that reached the scene (the global
    # group's at emission less that of its photons whose first ray hit nothing, :func:`reached`: an open scene's
    # sky, a directional light's disc past the scene, which as a share of all it emits hid the cut, h529); not the
    # caustic group's: aimed at the specular objects, its photons estimate a part of that light again (its
    # specular paths), which summed with the global group's counted it twice (h511: a mirror box 132%)
    cut_power: tuple[float, float, float] = (0.0, 0.0, 0.0)
    cut_share: float = 0.0

    @property
    def maps(self) -> tuple[PhotonMap, PhotonMap]:
        return self.caustic_map, self.indirect_map

    @property
    def gathered(self) -> tuple[PhotonMap, ...]:
        """The maps the pipeline keeps and gathers (:data:`PIPELINE_MAPS`; their trees are
        built by the Vertex PM: :meth:`tlm.arch.functional.TreeWork.of_maps`): caustic and
        indirect; with final gathering, caustic and global (the indirect map is then the
        software's only, for its statistics and the reference)."""
        return tuple(getattr(self, f"{name}_map") for name in PIPELINE_MAPS[self.global_map is not None])

    @property
    def n(self) -> int:
        return self.caustic_map.n + self.indirect_map.n

    def _cat(self, name: str) -> np.ndarray:
        return np.concatenate([getattr(m, name) for m in self.maps])

    @property
    def position(self) -> np.ndarray:
        return self._cat("position")

    @property
    def normal(self) -> np.ndarray:
        return self._cat("normal")

    @property
    def incoming(self) -> np.ndarray:
        return self._cat("incoming")

    @property
    def power(self) -> np.ndarray:
        return self._cat("power")

    @property
    def caustic(self) -> np.ndarray:
        return self._cat("caustic")

    def stats(self) -> dict:
        return {
            "emitted": self.emitted,
            "stored": self.n,
            "caustic": self.caustic_map.n,
            "indirect": self.indirect_map.n,
            "stored_power": self.power.sum(axis=0).tolist(),
            "cut_power": list(self.cut_power),
            "cut_share": self.cut_share,
            "tree": self.indirect_map.tree.stats(),
            "caustic_tree": self.caustic_map.tree.stats(),
            **({} if self.global_map is None else {"global": self.global_map.n,
                                                   "global_tree": self.global_map.tree.stats()}),
        }


@dataclass(frozen=True)
class PhotonTrace:
    """Traced photon maps and the work it took: ``work[name]`` per emitted photon."""

    photons: PhotonMaps
    work: dict[str, np.ndarray]

    def totals(self) -> dict[str, int]:
        return {k: int(v.sum()) for k, v in self.work.items()}


def map_levels(n: int, levels: int | None, leaf_photons: int | None) -> int | None:
    """A photon map's BSP split levels: ``levels``; or, when None, about ``leaf_photons``
    photons a leaf (``round(log2(n / leaf_photons))``, at least 0, at most 24); or, when
    both are None, None: the thesis's ``floor(ln n)`` (:func:`~tlm.kernels.bsp.build_point_tree`)."""
    if levels is not None or leaf_photons is None:
        return levels
    if n <= leaf_photons:
        return 0
    return int(min(24, max(0, round(np.log2(n / leaf_photons)))))


def _of_the_scene(scene: Scene, name: str, a: np.ndarray) -> None:
    """A per-triangle array a caller gave: one row per triangle of ``scene`` (the compiled
    bounce reads them by triangle id, without a bounds check), or a ValueError naming it."""
    if a.shape[0] != scene.n_triangles:
        raise ValueError(f"{name} has {a.shape[0]} rows; the scene has {scene.n_triangles} triangles")


def trace_photons(
    scene: Scene,
    accel: TriangleAccel,
    n: int,
    seed: int = 0,
    max_bounces: int = 8,
    russian_roulette: bool = True,
    levels: int | None = None,
    leaf_photons: int | None = None,
    caustic_fraction: float = 0.5,
    caustic_count: int | None = None,
    aim: str = "box",
    aim_triangles: int = 64,
    global_map: bool = False,
    batch: int = 4,
    page_words: int = PAGE_WORDS,
    pairs: int = PAIRS,
    cache=None,
    fresnel: bool = True,
    batch_rays: int | None = None,
    normals: np.ndarray | None = None,
    shading: np.ndarray | None = None,
    table: dict[str, np.ndarray] | None = None,
    prepare: bool = False,
    radii: Sequence[tuple[str, int]] = (),
) -> PhotonTrace:
    """Emit ``n`` photons, trace them through the scene and build the photon BSP.

    With mirrors or dielectrics in the scene, ``caustic_fraction`` of each light's
    photons (or, with ``caustic_count``, that many photons beside the ``n`` of the
    global group) form a caustic group aimed at the specular objects (``aim``: "box",
    one cone about them all; "parts", a mixture of cones about boxes of at most
    ``aim_triangles`` triangles of each part, :func:`aim_boxes`, :func:`emit`), which
    stores only caustic photons (L S+ D); the global group then stores only indirect
    ones (a diffuse bounce on the way), so nothing is counted twice. page_words, pairs : the
    data cache whose misses the photons' reads are charged; cache : in their place, a run
    config's ``cache`` section (a render's), every key of it (:meth:`~tlm.kernels.memory.Streams.of`).
    batch_rays : the most rays a chunk of photons traces and keeps the reads of (the
    render's ``render.batch_rays``): photons go in chunks of at most ``batch_rays //
    max_bounces`` (or of :data:`PHOTON_MIN_BATCH` where that is more, :func:`photon_spans`), each
    through all its bounces and charged before the next, so memory does not grow with the
    bounces (None: no bound; the maps and work are the same).
    normals, shading, table : the scene's unit face normals (:func:`face_normals`), corner
    shading normals and :meth:`~tlm.scenes.model.Scene.material_table` when the caller has
    them already (a render's frame), so they are not made again (None: made here).
    prepare, radii : what a render needs of the maps before its batches run at once, made
    with the maps' trees on the threads: each map the pipeline gathers in leaf order
    (:meth:`PhotonMap.prepared`; :data:`PIPELINE_MAPS`: not the indirect map with
    ``global_map``, which nothing gathers) and the density radii ``(map, k)``
    (:meth:`PhotonMap.density_radius`; map: "caustic", "indirect" or "global", the last
    only with ``global_map``). The same values as made later.
    """
    if n < 0:
        raise ValueError(f"photons (={n}) must be >= 0")
    if max_bounces < 0:
        raise ValueError(f"max_bounces (={max_bounces}) must be >= 0")
    if not 0.0 <= caustic_fraction < 1.0:
        raise ValueError(f"caustic_fraction (={caustic_fraction}) must be in [0, 1)")
    if caustic_count is not None and caustic_count < 0:
        raise ValueError(f"caustic_count (={caustic_count}) must be >= 0")
    if aim not in ("parts", "box"):
        raise ValueError(f"aim (={aim!r}) must be 'parts' or 'box'")
    if aim_triangles < 1:
        raise ValueError(f"aim_triangles (={aim_triangles}) must be >= 1")
    for name, _ in radii:
        if name not in ("caustic", "indirect", "global") or (name == "global" and not global_map):
            raise ValueError(f"radii: no {name!r} map to measure (the maps: 'caustic', 'indirect', "
                             f"and 'global' with global_map)")
    streams = Streams(page_words, pairs) if cache is None else Streams.of(cache)  # checked before any tracing
    key = photon_key(seed)
    table = scene.material_table() if table is None else table
    for k in ("kind", "albedo", "reflectance", "transmittance", "ior"):
        _of_the_scene(scene, f"table[{k!r}]", table[k])
    kind_of, albedo, refl_of = table["kind"], table["albedo"], table["reflectance"]
    trans, ior = table["transmittance"], table["ior"]
    flat = scene.triangles.reshape(-1, 3)
    spec = scene.triangles[kind_of != KIND["lambertian"]].reshape(-1, 3)
    aimed = spec.shape[0] > 0 and (caustic_fraction > 0 if caustic_count is None else caustic_count > 0)
    specular_box = bounds(spec) if aimed and aim == "box" else None
    boxes = aim_boxes(scene.triangles, kind_of, scene.part, aim_triangles) if aimed and aim == "parts" else None
    # the kernel's constants, built before the chunks run on threads (a cached property: by
    # one thread), on a worker while the photons are emitted
    prepared = threads.background(accel.prepare)
    o, d, power, caustic_group, source = emit(scene.lights, n, key, bounds(flat),
                                              specular_box, caustic_fraction, with_source=True,
                                              caustic_boxes=boxes, caustic_count=caustic_count)
    split = aimed  # caustics come from the caustic group only
    n = o.shape[0]
    normals = face_normals(scene.triangles) if normals is None else normals
    if shading is None:
        shading = scene.normals if scene.normals is not None else crease_normals(scene.triangles, scene.part)
    matched = (kind_of == KIND["dielectric"]) & (ior == 1.0)  # index-matched: light crosses unchanged
    eps = SPAWN_EPS * max(accel.scale, np.finfo(float).tiny)

    compiled = engine() == "numba" and n > 0
    for name, a in (("normals", normals), ("shading", shading)):
        _of_the_scene(scene, name, a)
    if compiled:
        from tlm.kernels import _jit_photons

        seed64 = np.uint64(key & 0xFFFFFFFFFFFFFFFF)
        caustic_group = np.ascontiguousarray(caustic_group, dtype=bool)
        shading = np.ascontiguousarray(shading, dtype=np.float64)
        normals = np.ascontiguousarray(normals, dtype=np.float64)
    work = {k: np.zeros(n, dtype=np.int64) for k in PHOTON_WORK}
    work["photons_emitted"][:] = 1
    emitted = (o, d, power, source)

    def trace(span: tuple[int, int]):
        """Photons ``lo .. hi - 1``, every bounce, as traced with all the others (their
        random numbers are hashed by photon and bounce): their work (owner: the photon
        from ``lo``), what each bounce stored, in photon order, the pairs charged and the
        power of the photons still travelling after ``max_bounces`` (their paths cut)."""
        lo, hi = span
        m = hi - lo
        work = {k: np.zeros(m, dtype=np.int64) for k in PHOTON_WORK if k != "photons_emitted"}
        o, d, power, last = (x[lo:hi] for x in emitted)  # last: the triangle each photon leaves
        pid = np.arange(m)  # photons still travelling (from lo)
        specular_only = np.ones(m, dtype=bool)  # every bounce so far was specular
        direct = np.ones(m, dtype=bool)  # straight from the light (index-matched crossings only)
        rec = Recorder(streams.page_words)
        stored: dict[str, list[np.ndarray]] = {k: [] for k in STORED}  # bounce by bounce
        # the global map (final gathering): every Lambertian hit of the global group, direct light included
        full: dict[str, list[np.ndarray]] = {k: [] for k in STORED}
        rel = None  # the spawn offsets of the rays (made by the compiled bounce)
        for bounce in range(max_bounces):
            if pid.shape[0] == 0:
                break
            if rel is None:
                rel = eps / np.linalg.norm(d, axis=1)
            hits = closest_hit(accel, o, d, tmin=rel, ignore=last, batch=batch, record=True)
            for name, acc in traversal_accesses(hits.touched, accel.leaf_first, accel.leaf_last,
                                                streams.page_words).items():
                rec.add(name, acc, pid)
            if compiled:  # the rest of the bounce in one call (the numpy code below, bit for bit)
                phi = 2.0 * np.pi * hash_uniform(key, lo + pid, bounce, 2)  # (numpy's cos and sin)
                c = hits.counts
                (pid, o, d, power, last, specular_only, direct, rel), got, got_full = _jit_photons.bounce(
                    seed64, lo, bounce, pid, o, d, power, specular_only, direct,
                    hits.triangle, hits.t, hits.u, hits.v,
                    (c.node_visits, c.leaves_crossed, c.leaf_visits, c.tri_tests), np.cos(phi), np.sin(phi),
                    caustic_group, kind_of, normals, shading, albedo, refl_of, trans, ior, matched,
                    KIND["lambertian"], KIND["mirror"], split, global_map, russian_roulette, fresnel, eps,
                    (work["node_visits"], work["leaves_crossed"], work["leaf_visits"], work["tri_tests"]),
                    work["rays"], work["lost"], work["bounces"], work["stored"], work["absorbed"])
                for into, values in ((stored, got), (full, got_full if global_map else ())):
                    for name, value in zip(STORED, values, strict=False):
                        into[name].append(value)
                continue
            for name in ("node_visits", "leaves_crossed", "leaf_visits", "tri_tests"):
                work[name][pid] += getattr(hits.counts, name)
            work["rays"][pid] += 1
            hit = hits.triangle >= 0
            work["lost"][pid[~hit]] += 1
            pid, o, d, power = pid[hit], o[hit], d[hit], power[hit]
            tri, specular_only, direct = hits.triangle[hit], specular_only[hit], direct[hit]
            group = caustic_group[lo + pid]
            x = o + hits.t[hit, None] * d
            work["bounces"][pid] += 1
            kind = kind_of[tri]
            n_geo = normals[tri]
            front = facing(n_geo, d)

            lam = kind == KIND["lambertian"]
            store = lam & ~direct  # the first hit is direct light: the ray-cast frame's
            if split:
                store &= specular_only == group
            for name, value in (("position", x), ("normal", front), ("incoming", d), ("power", power),
                                ("caustic", specular_only)):
                stored[name].append(value[store])
            if global_map:  # the maps the final-gather pipeline keeps: caustic and global
                every_hit = lam & ~group
                for name, value in (("position", x), ("normal", front), ("incoming", d), ("power", power),
                                    ("caustic", specular_only)):
                    full[name].append(value[every_hit])
                work["stored"][pid[store & specular_only]] += 1
                work["stored"][pid[every_hit]] += 1
            else:
                work["stored"][pid[store]] += 1

            u = [hash_uniform(key, lo + pid, bounce, dim) for dim in range(4)]
            new_d = np.empty_like(d)
            alive = np.ones(pid.shape[0], dtype=bool)
            if lam.any():
                a = albedo[tri[lam]]
                if russian_roulette:
                    p = a.max(axis=1)
                    survive = u[0][lam] < p
                    scale = np.where(survive[:, None], a / np.where(p > 0, p, 1.0)[:, None], 0.0)
                else:
                    survive = a.max(axis=1) > 0
                    scale = a
                power[lam] = power[lam] * scale
                new_d[lam] = cosine_directions(front[lam], u[1][lam], u[2][lam])
                if split:  # a caustic-group photon has nothing left to give after a diffuse hit
                    survive &= ~group[lam]
                alive[lam] = survive
                work["absorbed"][pid[lam][~survive]] += 1
            spec = ~lam
            if spec.any():
                ns = interpolate(shading, tri[spec], hits.u[hit][spec], hits.v[hit][spec], n_geo[spec])
                mir = kind[spec] == KIND["mirror"]
                refl, refr, f = scatter_specular(d[spec], ns, n_geo[spec], np.where(mir, 1.0, ior[tri[spec]]))
                # a mirror reflects (power x reflectance); a dielectric reflects with probability F
                # (Russian roulette on the Fresnel term: power unchanged) or refracts (x transmittance)
                if not fresnel:  # Snell only: glass reflects only totally
                    f = np.where(f < 1.0, 0.0, 1.0)
                go_refl = mir | (u[3][spec] < f)
                new_d[spec] = np.where(go_refl[:, None], refl, refr)
                ps = power[spec]
                ps[mir] *= refl_of[tri[spec][mir]]
                through = ~go_refl
                ps[through] *= trans[tri[spec][through]]
                power[spec] = ps
            crossing = matched[tri]
            specular_only = specular_only & ~lam
            direct = direct & crossing
            keep = alive & (power.max(axis=1) > 0)
            pid, o, d, power = pid[keep], x[keep], new_d[keep], power[keep]
            last, specular_only, direct = tri[keep], specular_only[keep], direct[keep]
            rel = None

        pairs = Deferred.like(streams) if concurrent else streams
        rec.charge(pairs, m, {name: work[_MISS_KEYS[name]] for name, _ in rec.added})
        # (the global group's alone: its paths, every one the lights send, estimate all the power in flight; the
        # caustic group's, aimed at the specular objects, estimate a part of it again: h511, a mirror box's 132%)
        return work, stored, full, pairs, power[~caustic_group[lo + pid]]

    threads.result(prepared)
    spans = photon_spans(n, max_bounces, batch_rays)
    # (on one thread the chunks run in order, each charged to the pairs as it comes)
    concurrent = len(spans) > 1 and threads.current() > 1
    stored: dict[str, list[list[np.ndarray]]] = {k: [] for k in STORED}  # bounce -> chunks' photons
    full: dict[str, list[list[np.ndarray]]] = {k: [] for k in STORED}
    cut: list[np.ndarray] = []  # each chunk's global-group photons still travelling after max_bounces: their power
    traced = (threads.forked(trace, spans, threads.current()) if concurrent and threads.can_fork()
              else threads.ordered(trace, spans))
    with contextlib.closing(traced):  # (ended here, whatever stops the loop: forked workers and their lock too)
        for (lo, hi), (part, got, got_full, pairs, left) in zip(spans, traced, strict=True):
            checkpoint()  # (a signal whose interrupt got lost stops the trace here, the chunks in flight too)
            if concurrent:
                streams.settle(pairs)  # the chunks' reads in photon order: photon-major, as one trace's
            for k, v in part.items():
                work[k][lo:hi] = v
            cut.append(left)
            for into, add in ((stored, got), (full, got_full)):
                for name, per_bounce in add.items():
                    for bounce, value in enumerate(per_bounce):
                        if bounce == len(into[name]):
                            into[name].append([])
                        into[name][bounce].append(value)
    stored = {name: [v for chunks in per_bounce for v in chunks] for name, per_bounce in stored.items()}
    full = {name: [v for chunks in per_bounce for v in chunks] for name, per_bounce in full.items()}

    def cat(store: dict[str, list[np.ndarray]], name: str) -> np.ndarray:
        parts = store[name]
        if parts:
            return np.concatenate(parts)
        return np.zeros(0, dtype=bool) if name == "caustic" else np.zeros((0, 3))

    def one_map(every: dict[str, np.ndarray], sel: np.ndarray | None) -> PhotonMap:
        """The map of the photons ``sel`` selects (None: all of them, the arrays themselves)."""
        position, normal, incoming, power, caustic = (
            every[k] if sel is None else every[k][sel] for k in ("position", "normal", "incoming", "power", "caustic"))
        return PhotonMap(position=position, normal=normal, incoming=incoming, power=power, caustic=caustic,
                         tree=build_point_tree(position, map_levels(position.shape[0], levels, leaf_photons)),
                         emitted=n)

    every = {name: cat(stored, name) for name in stored}
    sources = {"caustic": (every, every["caustic"]), "indirect": (every, ~every["caustic"])}
    if global_map:
        sources["global"] = ({name: cat(full, name) for name in full}, None)  # (every photon: no copy)
    size = {name: a["position"].shape[0] if sel is None else int(np.count_nonzero(sel))
            for name, (a, sel) in sources.items()}

    def build(name: str) -> PhotonMap:
        m = one_map(*sources[name])
        if prepare and name in PIPELINE_MAPS[bool(global_map)]:
            m.prepared()
        return m

    def radius(name: str, k: int) -> float | None:  # (the positions alone: not waiting for the tree)
        a, sel = sources[name]
        return density_radius(a["position"] if sel is None else a["position"][sel], k)

    # the maps' trees are built at once on the threads, each on its own (the same trees), the
    # largest first; beside them, the density radii asked for (from the positions alone)
    wanted = list(dict.fromkeys(radii))
    tasks = [(build, (name,)) for name in sorted(sources, key=lambda x: -size[x])]
    tasks += [(radius, nk) for nk in sorted(wanted, key=lambda nk: -size[nk[0]])]
    made = dict(zip([args for _, args in tasks], threads.ordered(lambda t: t[0](*t[1]), tasks), strict=True))
    for name, k in wanted:
        made[(name,)]._memo[k] = made[(name, k)]  # (what PhotonMap.density_radius keeps)
    lost = cut_power(cut)
    photons = PhotonMaps(made[("caustic",)], made[("indirect",)], emitted=n,
                         global_map=made[("global",)] if global_map else None, cut_power=lost,
                         cut_share=cut_share(lost, cut_power([power[~caustic_group & reached(work)]])))
    return PhotonTrace(photons, work)
