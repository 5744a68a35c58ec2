"""The photon-map frame: the photon maps, their search radii, the estimate at every gather
point and final gathering (eqs. 3.2-3.5).

* :func:`trace_photon_map` traces the frame's photon maps (caustic and indirect) by its
  ``photons.*`` settings;
* :func:`search_radius`, :func:`caustic_radius` and :func:`global_radius` size the
  gathers (a fixed fraction of the scene or the density rule, :func:`radii`);
* :func:`pmap_pass` is the photon-mapped term at the gather points of
  :func:`tlm.render.passes.gather_points` (the Lambertian eye hits and the ends of the
  mirror and glass paths) with the configured filter, or with final gathering
  (:func:`final_gathering`: rays from each point to where the global map is gathered),
  whose rays' work :func:`tlm.render.passes.fgather_pass` reports as a pass of its own;
* :func:`gathered_maps` says which maps that pass gathers (the one rule: the pass and
  :mod:`tlm.experiments.error_cost`, which times their leaf order with the trace, ask it),
  and :func:`gathered_radii` the radius it gathers each of them with (:func:`map_radius`).

Work and page misses follow the rules of :mod:`tlm.render.passes`: the gathers' photon-leaf
reads in pixel order, the caustic map's on a pair of its own (:data:`CAUSTIC_STREAM`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from tlm.kernels.emission import cosine_directions
from tlm.kernels.engine import engine
from tlm.kernels.estimate import GATHER_STREAM
from tlm.kernels.memory import SHADING_WORDS, Accesses, Streams
from tlm.kernels.photons import PhotonMap, PhotonMaps, PhotonTrace, trace_photons
from tlm.kernels.recording import Recorder
from tlm.kernels.shade import (
    emitted,
    final_gather_bounce,
    hash_uniform,
)
from tlm.kernels.work import GATHER_KEYS  # the work schema, declared once
from tlm.progress import booked_apart
from tlm.registry import ESTIMATORS
from tlm.render.estimators import Gather
from tlm.render.frame import (
    Frame,
    GBuffer,
    charge,
    new_streams,
    new_work,
    pixel_mean,
    ray_budget,
    trace_secondary,
)
from tlm.render.passes import gather_points_full
from tlm.render.planner import photon_count, uses_radius

# the caustic map's leaf reads: a stream not in tlm.kernels.memory.PM_STREAMS, so a pair of its own
# (the two maps' gathers of consecutive packets then miss as the whole image's do)
CAUSTIC_STREAM = "caustic_photons"
# what pmap_pass's per_map tallies of each map's gathers (with their count, gathers): results.json's
# photons.gather.<map>, whose counts summed over the maps are work.pmap's (photons_weighted too: h243)
MAP_TALLY = ("photons_tested", "photons_accepted", "photons_weighted", "leaves_visited")


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
        cache=cfg.cache, fresnel=cfg.render.fresnel,
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
    return _radius_used(frame, photons, which)[0]


def _radius_used(frame: Frame, photons: PhotonMaps | PhotonMap | None, which: str) -> tuple[float, str]:
    """The ``which`` map's radius and the rule that gave it: :func:`radius_rule`'s, but
    ``fallback`` where the density rule's map is too small to measure (fewer than 2 photons, or
    all on one point: :data:`FALLBACK_FRACTION` of the diagonal)."""
    est = frame.cfg.estimate
    given, fraction, k = ((est.caustic_radius, est.caustic_radius_fraction, est.caustic_radius_photons)
                          if which == "caustic" else (est.radius, est.radius_fraction, est.radius_photons))
    rule = radius_rule(frame, which)
    if rule == "radius":
        return given, rule
    if rule == "density":
        m = _map_of(photons, which)
        if m is None:
            raise ValueError(f"the {which} map's radius follows the density rule: pass the photon map")
        r = m.density_radius(k)
        if r is not None:
            return r, rule
        return FALLBACK_FRACTION[which] * frame.accel.scale, "fallback"
    return fraction * frame.accel.scale, rule


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
    trace without the split stands for both: :func:`density_requests`). None under a filter that
    uses no radius (``knn``: :func:`tlm.render.planner.uses_radius`): no gather reads one, so none
    is made, nor timed in an error-vs-cost row's ``trace_seconds`` (h426)."""
    est = frame.cfg.estimate
    out: list[tuple[str, int]] = []
    if not uses_radius(est.filter):
        return out
    if est.final_gather > 0 and est.radius is None and est.radius_fraction is None:
        out.append(("global", est.final_gather_photons))
    for which, k in (("indirect", est.radius_photons), ("caustic", est.caustic_radius_photons)):
        if radius_rule(frame, which) == "density":
            out.append((which, k))
    return out


# the maps of gathered_maps whose radius a density_wanted entry sizes (a single map: the indirect one's)
_SIZES = {"global": ("global",), "indirect": ("indirect", "photons"), "caustic": ("caustic",)}


def density_requests(frame: Frame, photons: PhotonMaps | PhotonMap,
                     gathered_only: bool = False) -> list[tuple[PhotonMap, int]]:
    """:func:`density_wanted` of ``photons``' maps: the ``(map, k)`` whose density radius
    (:meth:`PhotonMap.density_radius`) the pmap frame's radii ask for, each map once per ``k``.
    ``gathered_only``: only those of the radii the photon-map pass gathers with
    (:func:`gathered_radii`): under final gathering not the indirect map's, which :func:`radii`
    records but nothing gathers, nor a map's that holds no photon."""
    once: list[tuple[PhotonMap, int]] = []
    names = gathered_maps(frame, photons) if gathered_only else None
    for which, k in density_wanted(frame):
        if names is not None and not any(name in names for name in _SIZES[which]):
            continue
        m = (photons.global_map if final_gathering(frame, photons) else None) if which == "global" else _map_of(
            photons, which)
        if m is not None and not any(m is m2 and k == k2 for m2, k2 in once):
            once.append((m, k))
    return once


def radii(frame: Frame, photons: PhotonMaps | PhotonMap) -> dict:
    """The search radii a pmap frame used and the rule that gave each (``results.json``): ``radius``,
    ``fraction`` or ``density`` (with ``<key>_photons``, its k), and ``fallback`` where the
    density rule's map is too small to measure (fewer than 2 photons, or all on one point: an
    empty caustic map), the radius then :data:`FALLBACK_FRACTION` of the diagonal
    (``<key>_fraction``). Under a filter that uses no radius (``knn``:
    :func:`tlm.render.planner.uses_radius`) each radius and rule is None, as an error-cost row's."""
    est = frame.cfg.estimate
    out = {}
    if not uses_radius(est.filter):  # (knn: the k nearest photons, within no radius: none recorded)
        if final_gathering(frame, photons):
            out.update(global_radius=None, global_radius_rule=None, final_gather=est.final_gather)
        return {**out, "radius": None, "radius_rule": None, "caustic_radius": None, "caustic_radius_rule": None}
    if final_gathering(frame, photons):
        out["global_radius"], out["global_radius_rule"] = _global_radius_used(frame, photons)
        if out["global_radius_rule"] == "density":
            out["global_radius_photons"] = est.final_gather_photons
        elif out["global_radius_rule"] == "fallback":
            out["global_radius_fraction"] = FALLBACK_FRACTION["indirect"]
        out["final_gather"] = est.final_gather
    for which, key, k in (("indirect", "radius", est.radius_photons),
                          ("caustic", "caustic_radius", est.caustic_radius_photons)):
        out[key], rule = _radius_used(frame, photons, which)
        out[f"{key}_rule"] = rule
        if rule == "density":
            out[f"{key}_photons"] = k
        elif rule == "fallback":
            out[f"{key}_fraction"] = FALLBACK_FRACTION[which]
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
    return _global_radius_used(frame, photons)[0]


def _global_radius_used(frame: Frame, photons: PhotonMaps) -> tuple[float, str]:
    """:func:`global_radius` and the rule that gave it (:func:`_radius_used`'s words)."""
    est = frame.cfg.estimate
    if est.radius is not None or est.radius_fraction is not None:
        return _radius_used(frame, photons, "indirect")
    r = photons.global_map.density_radius(est.final_gather_photons) if photons.global_map is not None else None
    return (FALLBACK_FRACTION["indirect"] * frame.accel.scale, "fallback") if r is None else (r, "density")


def final_gathering(frame: Frame, photons: PhotonMaps | PhotonMap | None) -> bool:
    """Whether the photon-map frame gathers the indirect light by final gathering
    (``estimate.final_gather`` > 0 and the trace kept a global map)."""
    return (frame.cfg.estimate.final_gather > 0 and isinstance(photons, PhotonMaps)
            and photons.global_map is not None)


def gathered_maps(frame: Frame, photons: PhotonMaps | PhotonMap | None) -> dict[str, PhotonMap]:
    """The photon maps :func:`pmap_pass` gathers for ``frame`` from ``photons``, by the names
    of its ``per_map`` tallies: a single :class:`PhotonMap` alone (``"photons"``); else the
    caustic map (``"caustic"``) and the indirect one (``"indirect"``), or, with final
    gathering (:func:`final_gathering`), the global one in its place (``"global"``, gathered
    where the final-gather rays land); none that holds no photon (and none for ``None``).
    Every gather reads a map in its leaf order (:meth:`PhotonMap.prepared`): these are the
    maps whose leaf order a frame needs (:mod:`tlm.experiments.error_cost` times it with
    the trace). The one rule: :func:`pmap_pass` gathers exactly these."""
    if photons is None:
        return {}
    if not isinstance(photons, PhotonMaps):
        found = {"photons": photons}
    elif final_gathering(frame, photons):
        found = {"caustic": photons.caustic_map, "global": photons.global_map}
    else:
        found = {"caustic": photons.caustic_map, "indirect": photons.indirect_map}
    return {name: m for name, m in found.items() if m is not None and m.n > 0}


def map_radius(frame: Frame, photons: PhotonMaps | PhotonMap | None, name: str) -> float:
    """The radius :func:`pmap_pass` gathers the map ``name`` of :func:`gathered_maps` with: the
    caustic map's :func:`caustic_radius`, the global map's :func:`global_radius` (final gathering),
    the indirect map's (or a single map's, ``"photons"``) :func:`search_radius`."""
    return map_radius_used(frame, photons, name)[0]


def map_radius_used(frame: Frame, photons: PhotonMaps | PhotonMap | None, name: str) -> tuple[float, str]:
    """:func:`map_radius` and the rule that gave it, in the words of :func:`radii`: ``radius``,
    ``fraction``, ``density`` or ``fallback`` (the one source of a gathered map's radius and rule:
    :func:`tlm.experiments.error_cost.radius_rule_used` reads its rule here). A density radius is
    the map's own, kept: asked again, nothing is computed."""
    if name == "caustic":
        return _radius_used(frame, photons, "caustic")
    if name == "global":
        return _global_radius_used(frame, photons)
    return _radius_used(frame, photons, "indirect")


def gathered_radii(frame: Frame, photons: PhotonMaps | PhotonMap | None) -> dict[str, float]:
    """The search radius of each map :func:`pmap_pass` gathers, by the names of :func:`gathered_maps`
    (:func:`map_radius`): with final gathering the caustic and global maps', not the indirect map's
    (built, and recorded by :func:`radii`, but not gathered), which is not computed here."""
    return {name: map_radius(frame, photons, name) for name in gathered_maps(frame, photons)}


def _gather_radius(frame: Frame, photons: PhotonMaps | PhotonMap, name: str) -> float:
    """The radius :func:`pmap_pass` hands the estimator for the map ``name``: :func:`map_radius`, or
    ``math.inf`` under a filter that uses no radius (``knn``, the k nearest photons at any distance:
    :func:`tlm.render.planner.uses_radius`), so no density radius is made that no gather reads (h426)."""
    return map_radius(frame, photons, name) if uses_radius(frame.cfg.estimate.filter) else math.inf


# the host-seconds stages of the pmap and fgather passes (tlm.render.batches times pass <name> as
# the stage pass_<name>): final gathering runs in the pmap pass, and its seconds are the fgather
# pass's (tlm.progress.booked_apart)
PMAP_STAGE, FGATHER_STAGE = "pass_pmap", "pass_fgather"

# final-gather rays traced together: their hits and reads are per chunk, so memory is bounded
# by it, not by the batch's gather points x estimate.final_gather
FG_CHUNK_RAYS = 1 << 16


@functools.lru_cache(maxsize=64)
def _fg_key(seed: int) -> int:
    """The final-gather rays' hash key of the run's ``seed`` (made once a seed: every chunk asks)."""
    return int(np.random.SeedSequence([seed, 0xF16A7]).generate_state(1, dtype=np.uint64)[0] >> 1)


def final_gather_directions(normals: np.ndarray, point_keys: np.ndarray, rays: int, seed: int):
    """``rays`` cosine-weighted unit directions about each unit normal (m, 3), stratified
    (``rays`` a square: a sqrt x sqrt grid over the two sample dimensions; otherwise strata
    of the polar dimension), seeded by each point's key and the ray's index, never by its
    neighbours. Returns the point of each ray (m * rays,), its index (m * rays,) and its
    direction (m * rays, 3), point-major."""
    m = normals.shape[0]
    ray = np.arange(m * rays, dtype=np.int64)  # (repeat and tile's values, by ufuncs: without the interpreter lock)
    j, r = ray // rays, ray % rays
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
        hits = trace_secondary(frame, origin, d, ignore, o, ray_work, rec)
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
    charge(rec, ray_streams, ray_work)
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
        tally = per_map.setdefault("global", dict.fromkeys((*MAP_TALLY, "gathers"), 0))
        for k in MAP_TALLY:
            tally[k] += int(getattr(e, k).sum())
        tally["gathers"] += int(lj.shape[0])
    return flux * (np.pi / rays)


def _add_per_pixel(work: dict, k: str, owner: np.ndarray, e, streams: Streams) -> None:
    """Add the gathers' count ``k`` of ``e`` to their pixels ``owner`` (the misses through
    ``streams.fold``, which a :class:`~tlm.kernels.recording.Deferred` corrects later)."""
    if k == "gather_misses":
        streams.fold(e.gather_misses, owner, work[k])
    elif engine() == "numba":  # (the same integer sums, compiled: without the interpreter lock)
        from tlm.kernels._jit_pmap import add_per_owner

        add_per_owner(work[k], np.ascontiguousarray(owner, dtype=np.int64), getattr(e, k))
    else:
        work[k] += np.bincount(owner, weights=getattr(e, k), minlength=work[k].shape[0]).astype(np.int64)


def pmap_pass(frame: Frame, g: GBuffer, photons: PhotonMaps | PhotonMap, kdtree=None,
              streams: Streams | None = None, per_map: dict | None = None,
              fg_streams: Streams | None = None) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The photon-map frame: ``albedo / pi * density`` at every gather point (:func:`~tlm.render.passes.gather_points`).

    ``density`` is the reflected flux density by the configured filter: the caustic map's
    within :func:`caustic_radius` plus the indirect map's within :func:`search_radius`
    (a single :class:`PhotonMap` is gathered alone with the latter); the maps gathered are
    those of :func:`gathered_maps`, an empty one never. ``kdtree``: optional
    prebuilt ``cKDTree`` of a single map's positions for the exact k-nearest estimate.
    ``gather_misses``: the photon-leaf stream's misses, gathers in pixel order (the
    caustic map's leaves on a pair of their own, :data:`CAUSTIC_STREAM`; the indirect map's
    on the Fragment PM's ``photons`` pair), ``streams`` as in :func:`~tlm.render.passes.rcast_pass`.
    ``per_map``: a dict to which each map's totals are added (``"caustic"``, ``"indirect"``
    or, for a single map, ``"photons"`` -> :data:`MAP_TALLY` and ``gathers``), the split of
    the work's sums between the two maps.

    With final gathering (:func:`final_gathering`), the indirect map is not gathered: at
    every gather point ``estimate.final_gather`` stratified cosine-weighted rays (through
    mirrors and glass, one Fresnel branch each, up to ``render.refract_depth``) reach
    Lambertian points where the global map (:attr:`PhotonMaps.global_map`, direct light
    included) is gathered (within :func:`global_radius`, on the indirect map's pair); the
    point's indirect density is pi / N x the sum of their radiance (Jensen). Those
    gathers are this pass's work (``per_map["global"]``); the rays' work (a ray pass's
    keys, charged to ``fg_streams``) is left in ``g.memo["fgather_work"]`` for
    :func:`~tlm.render.passes.fgather_pass`. The final gathering's host seconds (its rays
    and their gathers) are that pass's too: run inside the stage ``pass_pmap`` of a
    :class:`~tlm.progress.Timer` (as :mod:`tlm.render.batches` runs the pass), they go to
    its stage ``pass_fgather`` instead.
    """
    p = g.pixels.shape[0]
    work = {k: np.zeros(p, dtype=np.int64) for k in GATHER_KEYS}
    radiance = np.zeros((g.origin.shape[0], 3))
    fg = final_gathering(frame, photons)
    if fg:
        g.memo["fgather_work"] = new_work(p)
    sidx, tri, pts, n, weight, bounce, medium = gather_points_full(frame, g)
    gathered = gathered_maps(frame, photons)  # (the global map's gathers are the final-gather rays', below)
    maps = [(name, m, _gather_radius(frame, photons, name), kdtree if name == "photons" else None,
             CAUSTIC_STREAM if name == "caustic" else GATHER_STREAM)
            for name, m in gathered.items() if name != "global"]
    if sidx.shape[0] == 0 or not (maps or fg):
        return pixel_mean(frame, radiance), work
    streams = new_streams(frame) if streams is None else streams
    owner = g.owner[sidx]
    keys = g.sample_keys[sidx]
    density = np.zeros((sidx.shape[0], 3))
    if "global" in gathered:
        with booked_apart(FGATHER_STAGE, within=PMAP_STAGE):  # (the rays and their gathers: the fgather pass's)
            fg_streams = new_streams(frame) if fg_streams is None else fg_streams
            radius = _gather_radius(frame, photons, "global")
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
                                                   pkeys[sl], medium[sl], owner[sl], p, g.memo["fgather_work"],
                                                   work, fg_streams, streams, per_map)
                lo = hi
    for name, ph, radius, tree, stream in maps:
        e = _estimate(frame, ph, radius, pts, n, keys, streams, tree, stream)
        density += e.density
        if per_map is not None:
            tally = per_map.setdefault(name, dict.fromkeys(MAP_TALLY, 0))
            for k in MAP_TALLY:
                tally[k] += int(getattr(e, k).sum())
            tally["gathers"] = tally.get("gathers", 0) + int(sidx.shape[0])
        for k in GATHER_KEYS[1:]:
            _add_per_pixel(work, k, owner, e, streams)
    np.add.at(radiance, sidx, weight * frame.albedo[tri] / np.pi * density)
    if maps:  # (the points' own searches; final gathering's lookups are counted where they land)
        work["gathers"] += np.bincount(owner, minlength=p)
    return pixel_mean(frame, radiance), work
