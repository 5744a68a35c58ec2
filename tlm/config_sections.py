"""The functional model's sections of the experiment schema (:mod:`tlm.config`): the geometry BSP,
the passes, photon tracing, the radiance estimate, the PMs' cache and the converged reference.

Each is a frozen dataclass whose fields carry their default, range and help text (``_f``);
:mod:`tlm.config` re-exports them beside the timing section (``ArchConfig``) and ``RunConfig``,
and loads and checks them.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from tlm.registry import ESTIMATORS

FILTERS = ESTIMATORS  # the names estimate.filter may take (tlm.render.estimators and plug-ins)


def _f(default: Any, help: str, **check: Any) -> Any:  # noqa: A002 - "help" reads best
    return field(default=default, metadata={"help": help, **check})


@dataclass(frozen=True)
class BSPConfig:
    levels: int | None = _f(
        None, "BSP split levels (2**levels leaves); null = floor(ln n), the thesis's depth",
        min=0, max=24,
    )
    memory_factor: float = _f(
        20.0, "element slots reserved per triangle for the expansion pass (thesis: 20x)", min=1.0
    )


@dataclass(frozen=True)
class RenderConfig:
    reflect_depth: int = _f(4, "specular bounces followed by the Reflect pass", min=0, max=64)
    refract_depth: int = _f(6, "specular bounces followed by the Refract pass", min=0, max=64)
    light_samples: int = _f(
        4, "shadow rays per quad light per shaded point (a square number: n x n strata)",
        min=1, max=1024,
    )
    spp: int = _f(
        4, "eye rays per pixel, jittered in the pixel (stratified when a square number); 1 = the pixel's "
        "centre, the thesis's ray casting", min=1, max=4096,
    )
    fresnel: bool = _f(True, "glass reflects and refracts by the exact Fresnel terms (both branches traced); "
                       "false: Snell refraction alone, reflection only when total")
    min_weight: float = _f(
        1e-3, "a Fresnel branch (glass reflection or refraction) whose path weight falls below it is not traced",
        min=0.0, max=1.0,
    )
    exposure: float | None = _f(
        None, "radiance scale before the sRGB curve; null = auto (99.5th percentile -> 1)",
        min_exclusive=0.0,
    )
    batch: int = _f(4, "leaves per ray tested together by the traversal kernel (speed only)", min=1, max=64)
    batch_rays: int = _f(1 << 17, "eye rays (pixels x spp) a run traces and shades together, pixel by pixel, "
                         "every pass of a batch before the next; also the most shadow rays, and mirror and glass "
                         "rays (all bounces of a pixel run), traced together within a pass, so the specular "
                         "depth does not raise the peak; and the photons a chunk traces through all their bounces "
                         "(batch_rays / photons.max_bounces photons, or 4,096 where that is more) (memory only: "
                         "images and work do not depend on it; peak memory grows with it)", min=1)
    threads: int | None = _f(None, "threads the kernels run on (traversal, gathers, photon tracing); null = the "
                             "CPUs available to the process (its affinity, within a container's CPU quota; in a "
                             "sweep of several --jobs: their share of them, at most 8 unless TLM_FORK_WORKERS=1); "
                             "past 8 the batches run on forked worker processes, which take every CPU (threads share "
                             "Python's interpreter lock and render slower past 8; TLM_FORK_WORKERS=0: threads, "
                             "null at most 8); "
                             "speed only: images, work and cycles are bit-identical for every count; at most 1024 "
                             "(more than the CPUs: allowed, and slower)", min=1, max=1024)


@dataclass(frozen=True)
class PhotonConfig:
    count: int | None = _f(None, "photons emitted; null = the scene's default", min=0)
    max_bounces: int = _f(8, "surface hits after which a photon path stops", min=0, max=64)
    russian_roulette: bool = _f(True, "absorb photons at Lambertian hits with probability 1 - max(albedo)")
    caustic_fraction: float = _f(
        0.5, "share of each light's photons in the caustic group, aimed at the specular objects (caustic map)",
        min=0.0, max=0.95,
    )
    caustic_count: int | None = _f(
        None, "photons of the caustic group, a budget of its own beside count (which is then the global "
        "group's alone); null = caustic_fraction x count", min=0,
    )
    aim: str = _f(
        "parts", "where the caustic group is aimed: parts = a cone per specular part (cut into boxes of about "
        "aim_triangles triangles), chosen in proportion to the solid angle it subtends (Jensen's projection "
        "maps); box = one cone about the box of every mirror and dielectric (the thesis study's)",
        choices=("parts", "box"),
    )
    aim_triangles: int = _f(
        64, "aim: parts: specular triangles per aiming box (a part larger than this is split along its longest "
        "axis)", min=1,
    )
    levels: int | None = _f(
        None, "photon BSP split levels of both maps; null = from leaf_photons, or when that is null too "
              "floor(ln n) of each map's stored photons (the thesis's depth)", min=0, max=24
    )
    leaf_photons: int | None = _f(
        8, "when levels is null: split each map until its leaves hold about this many photons "
            "(levels = round(log2(n / leaf_photons))), so a gather tests photons in proportion to the "
            "radius's, not to the map's size; null = floor(ln n) (the thesis's)", min=1,
    )


@dataclass(frozen=True)
class EstimateConfig:
    filter: str = _f("mvoxel", "disk (eq. 3.2) | mvoxel (eq. 3.3) | kvoxel (eq. 3.5) | knn (exact reference) "
                     "| a registered estimator (tlm.registry)", choices=FILTERS)
    radius: float | None = _f(
        None, "the indirect map's search radius in scene units; null = radius_fraction x the scene's diagonal, "
        "or when that is null too the density rule (radius_photons); at most 1e150 (the estimate divides by "
        "pi r^2, which overflows past 7.6e153)", min_exclusive=0.0, max=1e150,
    )
    radius_fraction: float | None = _f(
        None, "the indirect map's radius as a fraction of the scene's diagonal when radius is null (the rule "
        "before the density rule: 0.04; the thesis study 0.02); null = the density rule",
        min_exclusive=0.0, max=1.0,
    )
    radius_photons: int = _f(
        100, "density rule of the indirect map (radius and radius_fraction null): the radius that holds about "
        "this many stored photons, the median distance from a fixed sample of 256 of the map's photons to their "
        "radius_photons-th nearest neighbour (the same map gives the same radius); gathered only without final "
        "gathering (final_gather 0): with it, the global map is gathered at final_gather_photons instead",
        min=1, max=100000,
    )
    caustic_radius: float | None = _f(
        None, "the caustic map's search radius in scene units; null = caustic_radius_fraction x the diagonal, "
        "or when that is null too the density rule (caustic_radius_photons); at most 1e150", min_exclusive=0.0,
        max=1e150,
    )
    caustic_radius_fraction: float | None = _f(
        None, "the caustic map's radius as a fraction of the scene's diagonal when caustic_radius is null (the "
        "rule before the density rule: 0.01); null = the density rule", min_exclusive=0.0, max=1.0,
    )
    caustic_radius_photons: int = _f(
        8, "density rule of the caustic map: the radius that holds about this many of its stored photons (as "
        "radius_photons; few, because most caustic photons spread thin and a caustic is sharp)", min=1, max=100000,
    )
    final_gather: int = _f(
        16, "final gathering (Jensen): cosine-weighted rays per gather point (stratified), each hit gathering the "
        "global map, in place of the indirect map's estimate at the point; 0 = off (the thesis's pipeline)",
        min=0, max=4096,
    )
    final_gather_photons: int = _f(
        16, "final gathering: the density rule of the global map its rays gather (a radius holding about this "
        "many photons: few, because each point averages the lookups of all its rays)", min=1, max=100000,
    )
    k: int = _f(8, "voxels sampled by the stochastic k-voxel filter", min=1, max=1024)
    k_nearest: int = _f(50, "photons of the exact k-nearest reference estimate", min=1, max=100000)
    cone_k: float = _f(1.1, "cone filter constant: weight 1 - d / (cone_k r)", min=1.0)


@dataclass(frozen=True)
class CacheConfig:
    pairs: int = _f(4, "cache block pairs per programmable PM (thesis: 8 blocks = 4 pairs); a PM phase's k-th "
                    "stream takes pair k mod pairs (1: node heap and leaf indices share one)", min=1, max=4)
    block_words: int = _f(1024, "128-bit words per cache block, the page a miss fetches (thesis: 1024), its "
                          "transfer free (a miss costs arch.page_miss_cycles at any size: a sweep of it measures "
                          "locality alone); the next block is prefetched past its middle (at least 3 words: in a "
                          "block of 2 no word is past it)", min=3, max=1 << 20)


@dataclass(frozen=True)
class ReferenceConfig:
    photons: int | None = _f(None, "photons per round of the reference; null = the scene's default", min=1)
    k_nearest: int = _f(100, "photons of each round's k-nearest estimate", min=1, max=100000)
    tolerance: float = _f(0.02, "stop when the mean's relative standard error is below it", min_exclusive=0.0)
    min_rounds: int = _f(4, "rounds before the tolerance may stop", min=2, max=10000)
    max_rounds: int = _f(128, "rounds at most (the reference then says it did not converge)", min=2, max=10000)
    spp: int = _f(4, "eye rays per pixel of a cycle of that many rounds (one a round, a new photon map each; "
                  "at most max_rounds / 2), stratified over the pixel (each cell of a g x g grid once when a "
                  "square number): cycles average to the pixel's box-filter integral, which every render.spp "
                  "converges to, so one reference serves every spp; the standard error is over cycles", min=1, max=4096)
    auto: bool = _f(True, "'tlm run' of a pmap config computes and caches the reference when none is cached, "
                    "to print and record the photon frame's error (false, or 'tlm run --no-reference': the "
                    "error is left out unless a reference is cached)")
