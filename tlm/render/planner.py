"""The pass planner: which frames a run renders, and why the others are left out.

The thesis renders multi-pass, RenderMan-like: a ray-cast frame with shadows, then
reflection, refraction and photon-map frames, summed into the final image (Fig. 9).
The modes are cumulative: ``rcast`` < ``reflect`` < ``refract`` < ``pmap``. A pass the
mode asks for is still left out when the scene cannot use it: no mirror material, no
Reflect pass; no dielectric, no Refract pass; a depth of 0, nothing to follow; no
light, no Lambertian surface to receive photons, or no photons, no photon pass. A
scene without lights renders primary visibility only (black), and the planner says so.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from dataclasses import dataclass

from tlm.config import MODES, RunConfig
from tlm.errors import InputError
from tlm.registry import ESTIMATORS, may_run_on
from tlm.scenes.model import Scene

PASSES = ("rcast", "reflect", "refract", "pmap")  # the frames, one per mode
WORK_PASSES = ("fgather",)  # passes with work and no frame of their own (final gathering's rays)


@dataclass(frozen=True)
class PassPlan:
    name: str
    run: bool
    reason: str
    by: str | None = None  # the setting that left the pass out (``photons.count``), where one did


@dataclass(frozen=True)
class Plan:
    passes: tuple[PassPlan, ...]
    notes: tuple[str, ...]

    def runs(self, name: str) -> bool:
        return any(p.name == name and p.run for p in self.passes)

    @property
    def run_names(self) -> list[str]:
        return [p.name for p in self.passes if p.run]

    def to_dict(self) -> dict:
        return {
            "run": self.run_names,
            "left_out": {p.name: p.reason for p in self.passes if not p.run},
            "reasons": {p.name: p.reason for p in self.passes},
            "notes": list(self.notes),
        }


def plan(scene: Scene, cfg: RunConfig) -> Plan:
    """Decide the passes of ``cfg.mode`` for ``scene``."""
    wanted = set(PASSES[: MODES.index(cfg.mode) + 1])
    kinds = scene.kinds_present()
    notes = []
    if not scene.lights:
        notes.append("the scene has no lights: no shadow rays are cast and every frame is black")
    elif all(max(lt.power) == 0.0 for lt in scene.lights):
        notes.append("every light has zero power: frames are black (shadow rays are still cast)")
    # (a zero-power light beside lit ones: the run's warning says it, tlm.render.checks.zero_power_warnings)
    if "lambertian" not in kinds:
        notes.append("the scene has no Lambertian surface: nothing receives direct light")

    def decide(name: str, needs: str | None, depth: int | None) -> PassPlan:
        if name not in wanted:
            return PassPlan(name, False, f"mode {cfg.mode!r} does not include the {name} pass")
        if needs is not None and needs not in kinds:
            return PassPlan(name, False, f"the scene has no {needs} material")
        if depth == 0:
            return PassPlan(name, False, f"render.{name}_depth is 0")
        return PassPlan(name, True, f"mode {cfg.mode!r} asks for it and the scene has what it needs")

    passes = (
        PassPlan("rcast", True, "every mode casts primary rays with shadow rays"),
        decide("reflect", "mirror", cfg.render.reflect_depth),
        decide("refract", "dielectric", cfg.render.refract_depth),
        _decide_pmap(scene, cfg, "pmap" in wanted, kinds),
    )
    if "pmap" in wanted:  # (final gathering belongs to the photon map: named only in its mode)
        passes = (*passes, _decide_fgather(cfg, passes[-1]))
    return Plan(passes, tuple(notes))


def _decide_fgather(cfg: RunConfig, pmap: PassPlan) -> PassPlan:
    """The final-gather rays (``estimate.final_gather`` per gather point): work of the
    Traversal, Intersection and Fragment PMs, traced by the pmap pass (no frame of its own:
    the light they gather is the pmap frame's)."""
    if not pmap.run:
        return PassPlan("fgather", False, "no pmap pass: final gathering gathers photons")
    if cfg.estimate.final_gather == 0:
        return PassPlan("fgather", False, "estimate.final_gather is 0: the indirect map is gathered at the "
                        "eye hits (the thesis's pipeline)")
    return PassPlan("fgather", True, f"estimate.final_gather is {cfg.estimate.final_gather}: rays from every "
                    "gather point gather the global map where they land")


def photon_count(scene: Scene, cfg: RunConfig) -> int:
    return scene.photons if cfg.photons.count is None else cfg.photons.count


def check_photon_memory(n: int, key: str, source: str | None = None, whose: str = "") -> None:
    """An InputError (naming ``key`` of ``source``) when ``n`` photons cannot be traced in
    this machine's memory at :data:`~tlm.kernels.photons.PHOTON_BYTES` each: said before
    any is emitted, not as an out-of-memory error deep in the tracer."""
    from tlm.kernels.photons import PHOTON_BYTES
    from tlm.scenes.shapes import machine_memory

    need, total = n * PHOTON_BYTES, machine_memory()
    if need > total:
        raise InputError(f"{n:,} photons{whose} need at least {need / 2**30:,.0f} GiB to trace, more than this "
                         f"machine's {total / 2**30:.0f} GiB", source=source, key=key)


def _decide_pmap(scene: Scene, cfg: RunConfig, wanted: bool, kinds: set[str]) -> PassPlan:
    if not wanted:
        return PassPlan("pmap", False, f"mode {cfg.mode!r} does not include the pmap (photon-map) pass")
    if not scene.lights or all(max(lt.power) == 0.0 for lt in scene.lights):
        return PassPlan("pmap", False, "no light with power: nothing emits photons")
    if "lambertian" not in kinds:
        return PassPlan("pmap", False, "no Lambertian surface: nothing stores or shows photons")
    if photon_count(scene, cfg) == 0:
        return PassPlan("pmap", False, "photons.count is 0", by="photons.count")
    if cfg.photons.max_bounces < 2:
        return PassPlan("pmap", False, f"photons.max_bounces is {cfg.photons.max_bounces}: a photon's first hit "
                        "is direct light (the ray-cast frame's), so the map would store nothing",
                        by="photons.max_bounces")
    return PassPlan("pmap", True, "mode 'pmap' asks for it and the scene has lights and diffuse receivers")


# why estimate.radius_photons changes nothing under final gathering (estimate.final_gather > 0): it
# sizes the indirect map, which is then not gathered (tlm.render.pmap.gathered_maps); the global map
# the final-gather rays gather is sized by final_gather_photons (tlm.render.pmap.global_radius)
FINAL_GATHER_RADIUS_PHOTONS = ("estimate.final_gather is on (its rays gather the global map, sized by "
                               "estimate.final_gather_photons; the indirect map this sizes is not gathered)")


# the keys that size a photon map's fixed search radius (tlm.render.pmap.radii): none read by an estimator
# that declares it uses no radius (tlm.render.estimators.Estimator.uses_radius: ``knn``)
RADIUS_SETTINGS = ("estimate.radius", "estimate.radius_fraction", "estimate.radius_photons",
                   "estimate.caustic_radius", "estimate.caustic_radius_fraction", "estimate.caustic_radius_photons")


def uses_radius(filter_name: str) -> bool:
    """Whether the estimator ``estimate.filter`` names gathers within a fixed search radius, as
    it declares (:attr:`tlm.render.estimators.Estimator.uses_radius`; an unknown name: True,
    its error is the config check's)."""
    return getattr(ESTIMATORS[filter_name], "uses_radius", True) if filter_name in ESTIMATORS else True


def radius_settings(cfg: RunConfig) -> tuple[str, ...]:
    """The keys that size a radius of ``cfg``'s photon-map frame: :data:`RADIUS_SETTINGS`, and
    ``estimate.final_gather_photons`` under final gathering (the global map's density rule)."""
    return (*RADIUS_SETTINGS, *(("estimate.final_gather_photons",) if cfg.estimate.final_gather > 0 else ()))


def recorded_inert_settings(cfg: RunConfig) -> set[str]:
    """The keys :func:`inert_settings` names for ``cfg`` (judged from its mode) whose value a
    frame still records: ``estimate.radius_photons`` under final gathering with the density
    rule, which changes neither the image nor the work but sizes the indirect map's radius
    that ``results.json`` records beside it (``photons.radius``, ``photons.radius_photons``;
    :func:`tlm.render.pmap.radii`); none under a filter that uses no radius (``knn``: no radius
    recorded). The functional key keeps them
    (:func:`tlm.experiments.frames.functional_key`), so a frame's record is its own config's."""
    est = cfg.estimate
    if cfg.mode == "pmap" and not uses_radius(est.filter):  # (knn: results.json records no radius)
        return set()
    if cfg.mode == "pmap" and est.final_gather > 0 and est.radius is None and est.radius_fraction is None:
        return {"estimate.radius_photons"}
    return set()


def inert_settings(cfg: RunConfig, pmap_reason: str | None = None) -> dict[str, str]:
    """The config's keys whose value changes nothing in a run of ``cfg``, each with why:
    what a user who set (or swept) one should be told, since the run takes it silently.

    ``pmap_reason``: why the photon-map pass does not run (the plan's reason), or None when
    it runs; by default judged from ``cfg.mode`` alone (a pass the mode does not ask for
    never runs). Only the built-in filters are judged; a registered one uses what it reads.
    The specular walk's render keys a mode never reads are :func:`walk_inert_settings`'.
    """
    out: dict[str, str] = {}
    if pmap_reason is None and cfg.mode != "pmap":
        pmap_reason = f"mode {cfg.mode!r} does not include the pmap (photon-map) pass"
    if pmap_reason is not None:
        why = f"the photon-map pass does not run ({pmap_reason})"
        for section in ("photons", "estimate", "reference"):
            for name in dataclasses.asdict(getattr(cfg, section)):
                out[f"{section}.{name}"] = why
    else:
        est = cfg.estimate
        if est.filter in ("disk", "mvoxel", "knn") and est.filter != "kvoxel":
            out["estimate.k"] = f"estimate.filter is {est.filter!r}: only 'kvoxel' samples k voxels"
        if est.filter in ("disk", "mvoxel", "kvoxel"):
            out["estimate.k_nearest"] = f"estimate.filter is {est.filter!r}: only 'knn' takes the k nearest photons"
        if est.filter == "disk":
            out["estimate.cone_k"] = "estimate.filter is 'disk', which weighs every photon alike (no cone)"
        if est.final_gather == 0:
            out["estimate.final_gather_photons"] = "estimate.final_gather is 0 (no final gathering)"
        elif est.radius is None and est.radius_fraction is None:  # (else the rule of radius, radius_fraction below)
            out["estimate.radius_photons"] = FINAL_GATHER_RADIUS_PHOTONS
        else:  # (the global map's radius is the indirect map's given one: tlm.render.pmap.global_radius)
            given = "estimate.radius" if est.radius is not None else "estimate.radius_fraction"
            out["estimate.final_gather_photons"] = (f"{given} is set, and sizes the global map that final gathering "
                                                    "gathers too (final_gather_photons sizes it only by density)")
        for prefix in ("", "caustic_"):
            if getattr(est, f"{prefix}radius") is not None:
                for name in (f"{prefix}radius_fraction", f"{prefix}radius_photons"):
                    out[f"estimate.{name}"] = f"estimate.{prefix}radius is set, and comes first"
            elif getattr(est, f"{prefix}radius_fraction") is not None:
                out[f"estimate.{prefix}radius_photons"] = f"estimate.{prefix}radius_fraction is set, and comes first"
        if not uses_radius(est.filter):  # (knn: the k nearest photons, at any distance)
            for key in radius_settings(cfg):
                out[key] = (f"estimate.filter is {est.filter!r}, which gathers the estimate.k_nearest nearest "
                            "photons within no fixed radius")
        ph = cfg.photons
        if ph.caustic_count is not None:
            out["photons.caustic_fraction"] = ("photons.caustic_count is set: the caustic photons are a budget of "
                                               "their own, not a fraction of each light's")
        if ph.levels is not None:
            out["photons.leaf_photons"] = "photons.levels is set, and comes first (the maps' BSP split levels)"
        if ph.aim == "box":
            out["photons.aim_triangles"] = ("photons.aim is 'box' (one box around every specular triangle): only "
                                            "'parts' aims at boxes of aim_triangles triangles")
    out.update(walk_inert_settings(cfg.mode))
    if cfg.arch.scheduler == "static":
        out["arch.tiles_per_pipeline"] = "arch.scheduler is 'static' (one tile a pipeline): only 'dynamic' queues tiles"
    return out


# The render keys that only a specular walk reads (:func:`tlm.render.walk.specular_walk`: the depth
# it follows, its Fresnel split and the weight it prunes a branch below), each with the first mode
# whose passes walk it: the reflect pass walks the paths that first meet a mirror (and split at the
# glass they meet), the refract pass those that first meet glass; the photon-map pass gathers at the
# ends of both walks and traces its photons by ``render.fresnel``. The ray-cast pass reads none.
WALK_SETTINGS = {"render.reflect_depth": "reflect", "render.fresnel": "reflect", "render.min_weight": "reflect",
                 "render.refract_depth": "refract"}


def walk_inert_settings(mode: str) -> dict[str, str]:
    """:data:`WALK_SETTINGS`' keys that no pass of ``mode`` reads, each with why
    (``render.reflect_depth`` in mode ``rcast``, ``render.refract_depth`` in mode ``reflect``)."""
    level = MODES.index(mode)
    out = {}
    for key, first in WALK_SETTINGS.items():
        if level < MODES.index(first):
            out[key] = (f"mode {mode!r} traces no mirror or glass paths (the reflect, refract and pmap passes do)"
                        if mode == "rcast" else
                        f"mode {mode!r} does not include the {first} pass (the {first} and pmap passes read it)")
    return out


def inert_timing_settings(cfg: RunConfig) -> dict[str, str]:
    """The timing model's and the cache's keys that cannot change a run of ``cfg`` at the
    value it gives them, each with why: the copies to other pipelines with one pipeline,
    the context switch with one image in flight (no older image to switch to), and more
    cache pairs than a PM phase has cached streams (each stream has a pair of its own at
    any of those values, as at the default).

    Kept apart from :func:`inert_settings`, whose answer a sweep reuses for every point of
    the same mode, photon sections and scheduler (``tlm.experiments.sweep``): these depend
    on other keys. What only the simulated run can tell (the FIFO's depth, empty tiles, a
    swap or context switch that never happened) is :func:`tlm.experiments.run_warnings.stream_warnings`'.
    """
    out: dict[str, str] = {}
    arch = cfg.arch
    if arch.pipelines == 1:
        out["arch.fanout"] = "arch.pipelines is 1 (no other pipeline to copy to)"
    if not may_run_on(arch.scheduler, arch.images_in_flight, arch.frames):  # (model.settling)
        out["arch.settle_frames"] = ("the stream runs arch.frames alone: only a stream of two images in flight runs "
                                     "on until it settles (the static tiles' from 3 x images_in_flight - 1 frames)")
    if arch.images_in_flight == 1:
        out["arch.context_switch_cycles"] = ("arch.images_in_flight is 1 (a PM never has an older image's job "
                                             "to switch to)")
    streams = pair_streams()
    default_pairs = RunConfig().cache.pairs
    if min(cfg.cache.pairs, default_pairs) >= streams:
        out["cache.pairs"] = (f"a PM phase reads at most {streams} cached streams, so {streams} or more pairs give "
                              f"each a pair of its own, as the default {default_pairs} does")
    return out


def pair_streams() -> int:
    """The most cached streams one PM phase reads (:data:`tlm.kernels.memory.PM_STREAMS`: 2, the node
    heap and the leaf indices, ...): a phase's stream ``k`` takes pair ``k mod cache.pairs``, so at this
    many pairs or more each stream has a pair of its own, the same one at every such value."""
    from tlm.kernels.memory import PM_STREAMS

    return max(len(names) for names in PM_STREAMS.values())


def same_frame_settings(cfg: RunConfig) -> dict[str, object]:
    """The settings of ``cfg`` at whose value the render gives the same frame as at other values,
    each with the value that stands for all of them: ``cache.pairs`` at :func:`pair_streams` or more
    (each cached stream on a pair of its own, the same pair at each of them: the same page misses,
    work and image) stands for the default's 4 (for :func:`pair_streams` where the default were fewer).
    The functional key holds that value (:func:`tlm.experiments.frames.functional_key`), so a sweep
    of ``cache.pairs`` 2, 3 and 4 renders one frame; 1 (both streams of a phase on one pair) its own."""
    streams = pair_streams()
    if cfg.cache.pairs >= streams:
        return {"cache.pairs": max(RunConfig().cache.pairs, streams)}
    return {}


def inert_changes(cfg: RunConfig, skip: Iterable[str] = ()) -> list[str]:
    """:func:`inert_settings` and :func:`inert_timing_settings` of the keys ``cfg`` sets
    away from their defaults, the photon sections and the specular walk's render keys
    (:data:`WALK_SETTINGS`) judged as if every pass ran (a config may hold them for another
    ``--mode``, and the plan says why a pass is left out): one warning line each
    (``estimate.k = 16 has no effect in this run: ...``). ``skip``: keys warned of for
    another reason, left out here (the overrides a run never reads:
    :func:`tlm.experiments.run_warnings.unread_overrides`)."""
    defaults = dataclasses.asdict(RunConfig())
    lines = []
    settings = inert_settings(dataclasses.replace(cfg, mode="pmap"))  # (judged as if every pass ran)
    settings.update(inert_timing_settings(cfg))
    skip = set(skip)
    for key, why in settings.items():
        if key in skip:
            continue
        section, name = key.split(".", 1)
        value = getattr(getattr(cfg, section), name)
        if value != defaults[section][name]:
            lines.append(f"{key} = {value!r} has no effect in this run: {why}")
    return lines
