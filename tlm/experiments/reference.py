"""Converged reference images of the photon-mapped term, cached, and image error.

A reference is the exact k-nearest-photon estimate (Jensen's, cone filter) at the
Lambertian points the eye sees (the eye hits and the ends of the mirror and glass walks),
averaged over independent rounds until the mean's relative standard error — the RMS over
pixels of the per-pixel standard error of the mean, over the RMS of the mean — falls
below ``tolerance``. Each round traces a new photon map and casts one new eye ray per
pixel; rounds come in cycles of ``reference.spp`` rounds whose rays are stratified over
the pixel (each cell of a ``g x g`` grid once, in an order shifted per pixel; every ray
uniform in its pixel), all seeded from one ``SeedSequence``. The cycles are independent,
so the standard error is estimated from their spread and checked after each cycle. The
mean converges to the box-filter integral over each pixel, which every run converges to
whatever its ``render.spp`` (a run of ``spp: 1`` samples the pixel's centre, so at edges
its error includes that aliasing). (The change a cycle makes shrinks as 1/cycles while
the error shrinks only as 1/sqrt(cycles), so the standard error is the honest stopping
rule; the change is recorded too.) What it converges to is the expectation of the k-NN
estimate with that many photons per round: the kernel's blur remains (a smaller
``k_nearest`` or more photons per round shrink it). ``meta.json`` records the rounds,
both measures per cycle and whether the tolerance was met. The k nearest photons are
found on a numba grid (:mod:`tlm.experiments._reference_jit`), or with a ``cKDTree``
when ``TLM_KERNELS=numpy``: the same estimate.

The reference traces with settings of its own (:func:`reference_config`): of the run's
config only what changes the converged image is read, the rest is fixed (Russian
roulette, the caustic group's share and aiming, no final gathering, the cone filter's
constant :data:`CONE_K`), so it is cached in tlm's cache folder (``$TLM_CACHE``, else
``$XDG_CACHE_HOME/tlm``, else ``~/.cache/tlm``: :func:`tlm.caches.cache_home`) in
``references/<key>/``, keyed (:func:`reference_key`) by the scene (triangles, shading
normals or parts, materials, lights, camera and resolution), the photons' path length
(``photons.max_bounces``), where the eye paths gather (``render.reflect_depth`` with
mirrors, ``refract_depth`` and ``fresnel`` with glass, ``min_weight`` with either) and
the reference's own ``photons`` and ``k_nearest``. The run's seed, ``render.spp``,
photon count, filter, radii, final gathering, caustic budget and aiming are not: every
PMap run of a scene is measured against the same reference. Nor is the way the rounds
sample the pixel (``reference.spp``: any converges to the pixel's integral), nor the
stopping rule: ``tlm reference`` reuses a cached reference that meets the requested
tolerance and computes it again otherwise, but for one with more rounds than
``reference.max_rounds`` (:func:`fewer_rounds`: fewer rounds of the same key are no better) or
one that computing again would only repeat (:func:`repeats`: the same stopping rule, :data:`RULE`,
or one that stops at the same round, e.g. a stricter tolerance and the same ``max_rounds``);
``tlm run`` uses whatever is cached, and computes it when nothing is (:func:`ensure_reference`;
``reference.auto``). A reference computed now replaces the cached one only where it is better
(:func:`better`, :func:`store_reference`: it meets the tolerance asked for now
(:func:`meets_tolerance`: its error and rounds, not the flag of the run that computed it) and
the cached one does not, or neither does and its relative standard error is lower), or with
``--force``.

A cache that cannot be written (a read-only ``~/.cache``) loses no reference: ``tlm run``
uses the one it computed for that run only, and ``tlm reference`` keeps it in the
temporary folder (``<tmp>/tlm-cache-<uid>/references/<key>``), says where, and exits as
it would have with a writable cache. That folder is made for this user alone, and one made
by someone else first (a link, another user's folder, one others may write) is not written
into (:func:`private_folder`). Which reference the cache keeps, and its files:
:mod:`tlm.experiments.reference_cache`. One interrupted (Ctrl-C, a crash) resumes from its last
finished cycle, to the same bits: :mod:`tlm.experiments.reference_resume`.
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np

from tlm.config import EstimateConfig, PhotonConfig, RunConfig
from tlm.errors import EnvironmentFailure, InputError, shell_word
from tlm.experiments.reference_cache import (
    RULE,
    ReferenceSettings,
    cache_dir,
    computing_line,
    cycle_length,
    describe,
    kept_back,
    kept_root,
    load_reference,
    meets_tolerance,
    npy_digest,
    rounds_advice,  # (h473: re-exported; in reference_cache, which run_warnings may import)
    save_reference,
    store_reference,
    verdict,
)
from tlm.experiments.reference_resume import Partial, Rounds, marked
from tlm.kernels.camera import primary_rays
from tlm.kernels.engine import engine
from tlm.kernels.estimate import density_radius
from tlm.kernels.shade import emitted, hash_uniform, surface_emission
from tlm.kernels.traverse import closest_hit
from tlm.progress import checkpoint, progress_bar
from tlm.render.frame import Frame, GBuffer, pixel_batches
from tlm.render.passes import gather_points
from tlm.render.planner import check_photon_memory
from tlm.render.pmap import trace_photon_map
from tlm.scenes.model import Scene
from tlm.storage import warn

REFERENCE_SEED = 0x5EED
KEY_VERSION = 2  # 1: keyed by render.spp, the eye samples the run's
CONE_K = 1.1  # the reference's cone filter constant (Jensen's), whatever the run's estimate.cone_k
QUERY_BLOCK = 16384  # gather points per k-nearest query (memory: QUERY_BLOCK x k_nearest neighbours)
# a reference a run computes (ensure_reference) with no bar drawn (stderr no terminal, or --no-progress):
# a line of its rounds at most this often (tlm reference says every cycle's)
ROUND_LINE_SECONDS = 15.0


def _has(scene: Scene, kind: str) -> bool:
    return any(scene.materials[i].kind == kind for i in np.unique(scene.material_index))


def reference_config(cfg: RunConfig, settings: ReferenceSettings) -> RunConfig:
    """The config a reference traces with: the run's scene, resolution, geometry BSP and
    what :func:`reference_key` keys; the reference's seed, photons per round and one eye ray a round;
    the defaults of everything else that could change a photon map or its estimate
    (Russian roulette, the caustic group and its aiming, no final gathering), so that the
    run's settings that do not change the converged image cannot change the reference."""
    r = cfg.render
    photons = replace(PhotonConfig(), count=settings.photons, max_bounces=cfg.photons.max_bounces,
                      levels=0)  # (the reference searches a cKDTree: no photon BSP to build)
    estimate = replace(EstimateConfig(), filter="knn", k_nearest=settings.k_nearest, cone_k=CONE_K)
    if hasattr(estimate, "final_gather"):
        estimate = replace(estimate, final_gather=0)
    render = replace(r, spp=1, exposure=None)  # one eye ray per pixel a round (eye_rays)
    return replace(cfg, mode="pmap", seed=REFERENCE_SEED, render=render, photons=photons, estimate=estimate)


# the config keys :func:`reference_key` reads, or a section of them (a sweep's command that computes the
# reference of its points names these of its factors and --set: tlm.experiments.sweep_reference.unmeasured_line)
KEY_READS = ("scene", "resolution", "photons.max_bounces", "render.reflect_depth", "render.refract_depth",
             "render.fresnel", "render.min_weight", "reference")


def reference_key(scene: Scene, cfg: RunConfig, settings: ReferenceSettings) -> str:
    """A hash of everything the converged photon-map image depends on (the module's docstring;
    of the config, the keys :data:`KEY_READS`)."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(scene.triangles).tobytes())
    h.update(np.ascontiguousarray(scene.material_index).tobytes())
    if scene.normals is not None:
        h.update(np.ascontiguousarray(scene.normals, dtype=np.float64).tobytes())
    else:  # the renderer's crease normals, which follow the parts
        h.update(np.ascontiguousarray(scene.part, dtype=np.int64).tobytes())
    render = cfg.render
    mirrors, glass = _has(scene, "mirror"), _has(scene, "dielectric")
    doc = {
        "version": KEY_VERSION,
        "materials": [m.record() for m in scene.materials],
        "lights": [lt.record() for lt in scene.lights],
        "camera": asdict(scene.camera),
        "max_bounces": cfg.photons.max_bounces,
        # where the photon term is gathered: the eye hits and the ends of the specular walks
        # (what a walk depends on, in a scene that has its surfaces)
        "gather": {"reflect_depth": render.reflect_depth if mirrors else None,
                   "refract_depth": render.refract_depth if glass else None,
                   "fresnel": render.fresnel if glass else None,
                   "min_weight": render.min_weight if mirrors or glass else None},
        # what the converged image depends on; the stopping rule (tolerance, rounds) only
        # says how close to it the cached mean is, which meta.json records
        # (not its spp: any number of eye rays per cycle converges to the pixel's box integral)
        "reference": {"photons": settings.photons, "k_nearest": settings.k_nearest, "cone_k": CONE_K,
                      "pixel": "box"},
    }
    h.update(json.dumps(doc, sort_keys=True).encode())
    return h.hexdigest()[:20]


def eye_rays(frame: Frame, pixels: np.ndarray, strata: int, turn: int, seed: int,
             shift_seed: int) -> tuple[np.ndarray, np.ndarray]:
    """One eye ray per pixel, for round ``turn`` of a cycle of ``strata`` rounds.

    The ray lies in stratum ``(turn + shift) mod strata`` of the pixel's
    :func:`~tlm.kernels.camera.primary_rays` with ``strata`` samples (a ``g x g`` grid when
    ``strata`` is a square, else uniform in the pixel), jittered in it by ``seed``; the
    shift is a uniform draw per pixel from ``shift_seed``, one per cycle. So every ray is
    uniform in its pixel, and a cycle visits each of a pixel's strata once. One stratum:
    uniform in the pixel (a uniformly chosen quarter of the 2 x 2 grid), not its centre.
    """
    camera = frame.scene.camera
    pixels = np.asarray(pixels, dtype=np.int64)
    grid = max(strata, 4) if strata == 1 else strata
    o, d = primary_rays(camera, pixels, grid, seed)
    if strata == 1:
        pick = np.minimum((hash_uniform(seed, pixels, 0x51) * grid).astype(np.int64), grid - 1)
    else:
        shift = np.minimum((hash_uniform(shift_seed, pixels, 0x52) * strata).astype(np.int64), strata - 1)
        pick = (turn + shift) % strata
    rows = np.arange(pixels.shape[0], dtype=np.int64) * grid + pick
    return o[rows], d[rows]


def _cast(frame: Frame, o: np.ndarray, d: np.ndarray, pixels: np.ndarray) -> GBuffer:
    """:func:`tlm.render.frame.cast` of given eye rays, one per pixel (no reads recorded)."""
    hits = closest_hit(frame.accel, o, d, tmin=0.0, batch=frame.cfg.render.batch, shared_origin=True)
    le, seen = emitted(frame.scene.lights, o, d, hits.t, frame.eps)
    return GBuffer(pixels, 1, o, d, hits, le, seen, surface_emission(frame.emission, frame.normals, hits.triangle, d))


def knn_density(kdtree, power: np.ndarray, incoming: np.ndarray, points: np.ndarray, normals: np.ndarray,
                k_nearest: int, cone_k: float = CONE_K, workers: int = -1) -> np.ndarray:
    """Jensen's k-nearest estimate with a cone filter, (q, 3) flux densities: the
    density of :func:`tlm.kernels.estimate.knn_estimate` without its work counts, taking the
    neighbours' distances as the ``cKDTree`` returns them (sorted) and querying in blocks
    on ``workers`` threads."""
    q, n = points.shape[0], kdtree.n
    out = np.zeros((q, 3))
    kk = min(int(k_nearest), n)
    if q == 0 or kk == 0:
        return out
    area = (1.0 - 2.0 / (3.0 * cone_k)) * math.pi
    for q0 in range(0, q, QUERY_BLOCK):
        q1 = min(q0 + QUERY_BLOCK, q)
        d, idx = kdtree.query(points[q0:q1], k=kk, workers=workers)
        d, idx = d.reshape(q1 - q0, kk), idx.reshape(q1 - q0, kk)
        rk = d[:, -1]
        front = np.einsum("qkc,qc->qk", incoming[idx], normals[q0:q1]) < 0.0
        with np.errstate(divide="ignore", invalid="ignore"):
            w = np.where(front & (rk > 0.0)[:, None], 1.0 - d / (cone_k * rk[:, None]), 0.0)
        sums = np.matmul(w[:, None, :], power[idx])[:, 0]
        norm = area * rk**2
        out[q0:q1] = np.divide(sums, norm[:, None], out=np.zeros_like(sums), where=norm[:, None] > 0.0)
    return out


class _Estimator:
    """A round's photons, ready for k-nearest queries: a numba grid (``TLM_KERNELS``'s
    engine is numba) or a ``cKDTree`` (numpy), the same estimate either way."""

    def __init__(self, position: np.ndarray, power: np.ndarray, incoming: np.ndarray, k: int):
        self.power, self.incoming, self.k = power, incoming, k
        if engine() == "numba":
            from tlm.experiments._reference_jit import PhotonGrid

            r = density_radius(position, k) if position.shape[0] >= 2 else None
            cell = 0.6 * r if r else float(np.ptp(position, axis=0).max()) / 64.0
            self.grid, self.tree = PhotonGrid(position, power, incoming, cell), None
        else:
            from scipy.spatial import cKDTree

            self.grid, self.tree = None, cKDTree(position)

    def __call__(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        if self.grid is not None:
            return self.grid.density(points, normals, self.k, CONE_K)
        return knn_density(self.tree, self.power, self.incoming, points, normals, self.k)


def reference_round(frame: Frame, settings: ReferenceSettings, photon_seed: int, eye_seed: int,
                    strata: int = 1, turn: int = 0, shift_seed: int = 0) -> np.ndarray:
    """One round: a photon map of ``photon_seed``, one eye ray per pixel (:func:`eye_rays`);
    the (pixels, 3) k-NN photon frame. ``frame``'s config is the reference's
    (:func:`reference_config`)."""
    cam = frame.scene.camera
    n_pixels = cam.width * cam.height
    out = np.zeros((n_pixels, 3))
    ph = trace_photon_map(frame, settings.photons, photon_seed).photons
    if ph.n == 0:
        return out
    estimate = _Estimator(ph.position, ph.power, ph.incoming, settings.k_nearest)
    for at in pixel_batches(n_pixels, 1, frame.cfg.render.batch_rays):
        pixels = np.arange(at.start, at.stop, dtype=np.int64)
        o, d = eye_rays(frame, pixels, strata, turn, eye_seed, shift_seed)
        g = _cast(frame, o, d, pixels)
        idx, tri, pts, n, weight = gather_points(frame, g)
        samples = np.zeros((pixels.shape[0], 3))
        if idx.shape[0]:
            np.add.at(samples, idx, weight * frame.albedo[tri] / np.pi * estimate(pts, n))
        out[at] = samples
    return out


def compute_reference(frame: Frame, g: GBuffer | None, settings: ReferenceSettings, progress=None,
                      bar: bool = False, key: str | None = None, say=None) -> tuple[np.ndarray, dict]:
    """Average k-NN photon-map frames over independent rounds until converged.

    Rounds come in cycles of :func:`cycle_length` (``spp``) rounds, each round a new photon
    map and one eye ray per pixel, a cycle's rays stratified over the pixel
    (:func:`eye_rays`); cycles are independent, so the standard error is measured over the
    cycles' means and the stopping rule is checked after each cycle.

    frame : the run's frame (its scene, BSP and config; the reference traces with
        :func:`reference_config` of it). g : unused (the reference casts its own eye rays
        every round; kept for callers that pass the run's G-buffer).
    progress : called ``(round, change, standard error)`` after each round, the round's number
        counted from 1; the change and the standard error are measured after each cycle from the
        second, and are NaN after the other rounds (a cycle's first rounds, the first cycle).
    bar : a progress bar of the rounds on stderr (only when it is a terminal); its total is the
        most rounds (``reference.max_rounds``), and its status says that it stops before, once the
        relative standard error is below the tolerance (``rse 0.0412, stop < 0.03``).
    key : the reference's key (:func:`reference_key`), for a caller that stores it
        (:func:`~tlm.experiments.reference_cache.store_reference`, which then removes its saved rounds):
        its rounds are saved at the end of a cycle (:meth:`~tlm.experiments.reference_resume.Partial.save`:
        each, or one a minute where large), and the rounds saved by an interrupted compute of the key
        resumed from, to the same result (:mod:`tlm.experiments.reference_resume`; ``say``: called with
        the line that says so, or why not; ``meta`` then says ``resumed_from_round``, and its
        ``host_seconds`` add the earlier ones). None: nothing saved nor resumed.
    Returns the (pixels, 3) radiance and the metadata (rounds, changes, converged).
    """
    del g
    check_photon_memory(settings.photons, "reference.photons")  # (before the first round)
    rframe = replace(frame, cfg=reference_config(frame.cfg, settings))
    strata = cycle_length(settings)
    max_cycles = max(2, settings.max_rounds // strata)
    min_cycles = max(2, -(-settings.min_rounds // strata))
    cam = frame.scene.camera
    saved = None if key is None else Partial(key, strata, cam.width * cam.height, say)
    done = (saved.resume(min_cycles, max_cycles, settings.tolerance) if saved is not None else None) or Rounds()
    k0 = done.k  # (cycles resumed: the rounds saved stop no earlier under these settings, reference_resume)
    mean = np.zeros((cam.width * cam.height, 3)) if done.mean is None else done.mean
    m2 = np.zeros_like(mean) if done.m2 is None else done.m2  # Welford's running sum of squared deviations
    changes, errors = list(done.changes), list(done.errors)
    t0 = time.perf_counter()
    converged = k0 >= min_cycles and errors[-1] < settings.tolerance  # (resumed at the very cycle it stops at)
    rounds = progress_bar(bar, total=max_cycles * strata, desc="reference", unit="round", leave=False,
                          initial=k0 * strata,
                          postfix=f"stops at rse < {settings.tolerance}")  # (rse: the relative standard error)
    if k0 > 1:
        rounds.set_postfix_str(f"rse {errors[-1]:.4f}, stop < {settings.tolerance}")
    children = np.random.SeedSequence(REFERENCE_SEED).spawn(max_cycles)
    with marked(saved):  # (an interrupt of the rounds carries them: tlm run's line says how many are kept)
        for k, child in enumerate([] if converged else children[k0:], start=k0 + 1):
            shift_seed = int(child.generate_state(1)[0])
            frame_k = np.zeros_like(mean)
            for turn, each in enumerate(child.spawn(strata)):
                checkpoint()  # (a lost interrupt stops the reference here, not at its last round)
                photon_seed, eye_seed = (int(x) for x in each.generate_state(2))
                frame_k += reference_round(rframe, settings, photon_seed, eye_seed, strata, turn, shift_seed)
                rounds.update()
                if progress is not None and turn < strata - 1:  # (a cycle's last round: after its measures)
                    progress((k - 1) * strata + turn + 1, math.nan, math.nan)
            frame_k /= strata
            delta = frame_k - mean
            new = mean + delta / k
            m2 += delta * (frame_k - new)
            norm = float(np.sqrt(np.mean(new**2)))
            if k > 1 and norm > 0:
                changes.append(float(np.sqrt(np.mean((new - mean) ** 2)) / norm))
                errors.append(float(np.sqrt(np.mean(m2 / (k - 1) / k)) / norm))
            elif k > 1:
                changes.append(0.0)
                errors.append(0.0)
            mean = new
            if k > 1:
                rounds.set_postfix_str(f"rse {errors[-1]:.4f}, stop < {settings.tolerance}")  # (fits 80 columns)
            if progress is not None:
                progress(k * strata, changes[-1] if k > 1 else math.nan, errors[-1] if k > 1 else math.nan)
            if k >= min_cycles and errors[-1] < settings.tolerance:
                converged = True
                break
            if saved is not None and k < max_cycles:  # (the state after this cycle: an interrupt resumes from it)
                saved.save(Rounds(k, mean, m2, changes, errors, done.seconds + time.perf_counter() - t0))
    rounds.close()
    cycles = len(errors) + 1
    meta = {
        **asdict(settings),
        "cone_k": CONE_K,
        "rounds": cycles * strata,
        "rounds_per_cycle": strata,
        "cycles": cycles,
        "relative_standard_error": errors[-1] if errors else None,
        "final_change": changes[-1] if changes else None,
        "standard_error_per_cycle": errors,
        "change_per_cycle": changes,
        "converged": converged,
        "host_seconds": round(done.seconds + time.perf_counter() - t0, 3),
        "seed": REFERENCE_SEED,
        **({"resumed_from_round": k0 * strata} if k0 else {}),
    }
    return mean, meta


def image_error(image: np.ndarray, reference: np.ndarray) -> dict[str, float | None]:
    """RMSE and relative MSE, ``rel_mse``: the sum of squared error over the sum of squared reference
    (None for a black reference), the ``rel_mse`` of every run, study and report of tlm. A bright pixel
    weighs more than a dark one: it is not the per-pixel relative MSE of many rendering papers (the mean
    of ``(t - r)^2 / (r^2 + eps)``, :func:`tlm.oracle.mitsuba.rel_mse_per_pixel`)."""
    diff = np.asarray(image, dtype=np.float64) - np.asarray(reference, dtype=np.float64)
    ref2 = float(np.sum(np.asarray(reference, dtype=np.float64) ** 2))
    sq = float(np.sum(diff**2))
    return {"rmse": float(np.sqrt(np.mean(diff**2))), "rel_mse": sq / ref2 if ref2 > 0 else None}


def reference_named(key, photons=None, k_nearest=None, rounds=None, resolution=None, standard_error=None) -> str:
    """One line naming the photon-map reference an error is measured against (h507), as the reports show it:
    ``reference 94cd... (4,000 photons a round, k_nearest 100, 88 rounds, relative standard error 0.0198, 32x32
    pixels)``: ``photons`` a round (resolved: a number), ``rounds`` averaged, ``resolution`` [width, height]. What
    is None or not a number (a run or study written before it was recorded) is left out."""
    def number(v) -> float | None:
        return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) and np.isfinite(v) else None

    def whole(v) -> int | None:
        return None if number(v) is None else int(v)

    size = resolution if isinstance(resolution, (list, tuple)) and len(resolution) == 2 else (None, None)
    width, height = (whole(v) for v in size)
    rse = number(standard_error)
    parts = [f"{whole(photons):,} photons a round" if whole(photons) is not None else "",
             f"k_nearest {whole(k_nearest)}" if whole(k_nearest) is not None else "",
             f"{whole(rounds)} rounds" if whole(rounds) is not None else "",
             f"relative standard error {rse:.3g}" if rse is not None else "",
             f"{width}x{height} pixels" if width is not None and height is not None else ""]
    said = ", ".join(w for w in parts if w)
    return f"reference {key}" + (f" ({said})" if said else "")


@dataclass
class Found:
    """A reference looked up (and perhaps computed) for a frame: ``image`` (pixels, 3) and
    ``meta`` are None when none is cached and none was computed; ``seconds``: what
    computing it took now (None: it was cached)."""

    key: str
    settings: ReferenceSettings
    image: np.ndarray | None = None
    meta: dict | None = None
    seconds: float | None = None


def ensure_reference(frame: Frame, compute: bool = False, bar: bool = False, say=None) -> Found:
    """The cached reference of ``frame``'s scene and config; with ``compute``, computed and
    cached when there is none (``say``: called with a line before and after, e.g. to
    stderr, and, where no bar is drawn, with lines of the rounds as they go: :func:`round_lines`;
    ``bar``: the rounds' progress bar on stderr, when it is a terminal). The ``meta`` of
    one computed now is the cached one's, its ``npy`` (size and sha256 of ``reference.npy``)
    included, and its ``image`` the one stored (float32, as a later run reads it back), so that the
    same sha256 means the same error; where the cache could not take it, the image and ``npy`` are
    those of the ``reference.npy`` it would have been (float32,
    :func:`~tlm.experiments.reference_cache.npy_digest`)."""
    settings = ReferenceSettings.from_config(frame.scene, frame.cfg)
    key = reference_key(frame.scene, frame.cfg, settings)
    found = load_reference(key)
    if found is not None:
        return Found(key, settings, found[0].reshape(-1, 3), found[1])
    if not compute:
        return Found(key, settings)
    if say is not None:
        skip = "('--no-reference' or reference.auto: false skips it)"
        say(computing_line(key, settings, f"every run of this scene {skip}",
                           f"used by this run only, and computed again by the next {skip}"))
    t0 = time.perf_counter()
    drawn = bar and _terminal(sys.stderr)  # (the bar says how the rounds go: no lines besides it)
    lines = round_lines(say, settings) if say is not None and not drawn else None
    image, meta = compute_reference(frame, None, settings, progress=lines, bar=bar, key=key, say=say)
    cam = frame.scene.camera
    kept = ""
    try:
        stored = store_reference(key, image.reshape(cam.height, cam.width, 3), meta, settings)
    except (EnvironmentFailure, OSError, InputError) as e:  # (a read-only or full cache: this run still gets
        # its error; InputError: something in the way of the entry's folder, storage.check_destination)
        where = f"not cached ({' '.join(str(e).split())}): used by this run only"
        # (the image as its reference.npy would hold it, float32, and that file's sha256: the one computed again
        # with these settings, so that its error is the one a run reading that file measures)
        image = image.astype(np.float32)
        meta = {**meta, "npy": npy_digest(image.reshape(cam.height, cam.width, 3))}
    else:
        where = f"cached in {stored.folder}"
        # (the image as stored, float32, and its meta as its meta.json holds it, npy's sha256 too: the error is
        # the one every later run reading that reference.npy measures; not the float64 mean computed)
        image, meta = stored.image.reshape(-1, 3), stored.meta
        if not stored.replaced:  # (another process cached a better one meanwhile: this run uses it)
            kept = stored.line
    seconds = time.perf_counter() - t0
    if say is not None:
        if kept:
            say(f"{kept}; this run uses the cached one")
        else:
            state = ("converged" if meets_tolerance(meta, settings) else
                     "NOT converged (reference.max_rounds reached)")
            say(f"reference {key}: {state} after {meta['rounds']} rounds (relative standard error "
                f"{meta['relative_standard_error']:.4f}) in {seconds:.1f} s; {where}")
    return Found(key, settings, image, meta, seconds)


def _terminal(fp) -> bool:
    try:
        return bool(fp.isatty())
    except (AttributeError, OSError, ValueError):
        return False


def round_lines(say, settings: ReferenceSettings, every: float | None = None):
    """A :func:`compute_reference` ``progress`` that says how its rounds go with ``say``, a line at
    most every ``every`` seconds (:data:`ROUND_LINE_SECONDS`): a run's reference, which may take
    minutes, where no bar is drawn. ``  round  24  change 0.0153  relative standard error 0.0412 (stops
    below 0.03)`` after a measured cycle (as ``tlm reference`` says each), ``  round   3 of at most 128``
    before the first measure."""
    every = ROUND_LINE_SECONDS if every is None else every
    strata = cycle_length(settings)
    most = max(2, settings.max_rounds // strata) * strata  # (compute_reference's: whole cycles)
    last = [time.perf_counter()]

    def progress(k: int, change: float, error: float) -> None:
        now = time.perf_counter()
        if now - last[0] < every:
            return
        last[0] = now
        if math.isnan(error):
            say(f"  round {k:3d} of at most {most}")
        else:
            say(f"  round {k:3d}  change {change:.4f}  relative standard error {error:.4f} "
                f"(stops below {settings.tolerance})")

    return progress


# the difference image's colours at -scale, 0 and +scale: ours below the reference, equal, above. Cividis's two
# ends and a neutral grey between them: their grey (0.299 R + 0.587 G + 0.114 B, as a greyscale print takes it)
# is 0.11, 0.49 and 0.86 and changes linearly between them, so a greyscale print keeps the sign
DIFFERENCE_COLOURS = ("#00224e", "#7d7d7d", "#fee838")
# the colours of the difference images written before 2026-11-29 (blue, white, red: alike in grey), which
# the report still reads back (tlm.report.images.error_figure)
DIFFERENCE_COLOURS_BEFORE = ("#2166ac", "#f7f7f7", "#b2182b")
LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709


def difference_image(image: np.ndarray, reference: np.ndarray, scale: float | None = None) -> tuple[np.ndarray, float]:
    """(H, W, 3) uint8: the luminance of ``image`` minus ``reference`` (both (H, W, 3)
    linear radiance) in :data:`DIFFERENCE_COLOURS`, dark blue below, light yellow above, full colour
    at ``-scale`` and ``+scale`` (clipped beyond). ``scale``: default the 99th percentile
    of the absolute difference (1 where that is 0). Returns the image and the scale."""
    diff = (np.asarray(image, dtype=np.float64) - np.asarray(reference, dtype=np.float64)) @ LUMINANCE
    if scale is None:
        scale = float(np.percentile(np.abs(diff), 99)) if diff.size else 0.0
        scale = scale if scale > 0.0 else 1.0
    t = np.clip(diff / scale, -1.0, 1.0)[..., None]
    low, mid, high = (np.array([int(c[i:i + 2], 16) for i in (1, 3, 5)], dtype=np.float64)
                      for c in DIFFERENCE_COLOURS)
    rgb = np.where(t < 0, mid + (low - mid) * -t, mid + (high - mid) * t)
    return np.clip(np.rint(rgb), 0, 255).astype(np.uint8), scale



@dataclass
class Made:
    """What :func:`make_reference` did: the reference ``key``, the ``settings`` asked for, the
    ``meta`` of the reference the cache holds now (rounds, standard error, converged) and the
    ``folder`` that holds it, and its ``image``; ``computed``: whether one was computed now (True), or the cached
    one was returned with nothing computed (False: one that meets the tolerance, or one that
    misses it and is kept, as computing again would not better it). ``kept``: the line that
    says which one the cache holds and why, where that is not one computed now that meets the
    tolerance: a cached one kept without computing (``computed`` False, :attr:`meets` False), or
    a better one kept over the one computed now (``computed`` True); empty otherwise."""

    key: str
    settings: ReferenceSettings
    meta: dict
    computed: bool
    folder: Path | None  # (None: computed, but kept nowhere, with ``unkept``)
    kept: str = ""
    image: np.ndarray | None = None  # (H, W, 3) float32: the reference of ``meta``, as its reference.npy holds it
    warnings: tuple[str, ...] = ()  # (tlm.api.reference: the lines tlm reference prints on stderr, returned)

    def __repr__(self) -> str:
        """One line (a notebook shows it for ``tlm.reference(...)``), not the image's values: the key, the image's
        width x height, the rounds and relative standard error against the tolerance, whether computed now, the
        folder, and how many warnings; each field as it is: ``.image``, ``.meta``, ``.settings``, ``.kept``."""
        image = "x".join(map(str, self.image.shape[1::-1])) if self.image is not None else "none"
        rse = self.meta.get("relative_standard_error")
        error = f"{rse:.3g}" if isinstance(rse, (int, float)) else "unknown"
        tolerance = getattr(self.settings, "tolerance", None)
        folder = str(self.folder) if self.folder is not None else "none (kept nowhere)"
        return (f"Made(key={self.key!r}, image {image}, {self.meta.get('rounds', '?')} rounds, relative standard "
                f"error {error} (tolerance {tolerance}: {'met' if self.meets else 'not met'}), "
                f"{'computed now' if self.computed else 'from the cache'}, folder {folder}"
                + (", kept: see .kept" if self.kept else "")
                + (f", {len(self.warnings)} warning{'s' if len(self.warnings) != 1 else ''}" if self.warnings else "")
                + ")")

    @property
    def meets(self) -> bool:
        """Whether the reference the cache holds now meets the tolerance asked for
        (:func:`meets_tolerance` of ``meta`` and ``settings``; not its own ``converged`` flag)."""
        return meets_tolerance(self.meta, self.settings)

    @property
    def advice(self) -> str:
        """The rounds that would reach the tolerance, estimated from ``meta`` (:func:`rounds_advice`: `` to about 648
        (...)``; empty where it meets it or nothing is known): what ``tlm reference``'s line says to raise."""
        return rounds_advice(self.meta.get("relative_standard_error"), self.meta.get("rounds"), self.settings)


def make_reference(cfg: RunConfig, base: Path | None = None, source: str | None = None, force: bool = False,
                   say=None, progress=None, bar: bool = False, overrides: tuple[str, ...] = (),
                   via: str = "--set", unkept: bool = False, warned=None) -> Made:
    """The converged reference of ``cfg``'s photon-map frame (``tlm reference``): the cached
    one when it meets ``reference.tolerance`` and ``reference.min_rounds`` as asked for now
    (:func:`meets_tolerance`, whatever tolerance it was computed for; and not ``force``), else
    computed now and cached where it is better than the cached one (:func:`store_reference`).
    A cached one that misses the tolerance with more rounds than ``reference.max_rounds``
    (:func:`fewer_rounds`), or one that computing again would repeat (:func:`repeats`: the same
    stopping rule, :data:`RULE`, or one that stops it at the same round), is kept without computing
    (but with ``force``).

    ``say``: called with a line when a cached reference misses the tolerance, before
    computing, and when the cache keeps its own; ``progress``: called ``(round, change,
    relative standard error)`` after each round (:func:`compute_reference`); ``bar``: the
    rounds' progress bar on stderr. ``overrides``: the ``dotted.key=value`` strings ``cfg`` was made
    with (``tlm reference --set``; ``via``: how they were given, as :func:`tlm.api.load_config` names
    them): one that sets nothing (``--set render={}``: :func:`~tlm.experiments.run_warnings.empty_sets`)
    is said on stderr (``tlm: warning: ...``) first, once, or given to ``warned`` (:func:`tlm.api.reference`).
    ``unkept``: one computed now that neither the cache nor :func:`~tlm.experiments.reference_cache.kept_root`
    can take is returned all the same (``folder`` None, said by a warning; a sweep holds it in its output folder
    for its points), not the cache's error.
    """
    from tlm.experiments.loading import load_frame
    from tlm.experiments.run_warnings import empty_sets
    from tlm.scenes.loader import load_scene

    for line in empty_sets(overrides, via):
        (warned or warn)(line)
    say = say or (lambda line: None)
    scene = load_scene(cfg.scene, base, cfg.resolution, source)
    settings = ReferenceSettings.from_config(scene, cfg)
    key = reference_key(scene, cfg, settings)
    cached = None if force else load_reference(key)
    if cached is not None:
        kind = verdict(cached[1], settings)
        if kind == "meets":
            return Made(key, settings, cached[1], False, cache_dir() / key, image=cached[0])
        if kind == "fewer":
            say(line := kept_back(key, cached[1], settings))
            return Made(key, settings, cached[1], False, cache_dir() / key, line, cached[0])
        if kind == "repeats":
            say(line := (f"reference {key} is cached with {describe(cached[1], settings)}, "
                         f"{repeats_why(cached[1], settings)}, so it is kept (raise reference.max_rounds above "
                         f"{cached[1].get('rounds')}"
                         f"{rounds_advice(cached[1].get('relative_standard_error'), cached[1].get('rounds'), settings)}"
                         ", or use --force to compute it again)"))
            return Made(key, settings, cached[1], False, cache_dir() / key, line, cached[0])
        say(f"reference {key} is cached but does not meet tolerance {settings.tolerance}: computing it again")
    frame = load_frame(cfg, scene=scene, check_photons=None if settings.photons else "reference")  # (none: refused)
    say(f"reference {key}: {settings.photons} photons per round, k = {settings.k_nearest}, "
        f"tolerance {settings.tolerance}, cycles of {cycle_length(settings)} rounds")
    image, meta = compute_reference(frame, None, settings, progress=progress, bar=bar, key=key, say=say)
    image = image.reshape(scene.camera.height, scene.camera.width, 3)
    try:
        stored = store_reference(key, image, meta, settings, force=force)
    except (EnvironmentFailure, OSError, InputError) as e:  # (the rounds' result is not thrown away)
        folder = _kept_elsewhere(key, image, meta, e, unkept)  # (its meta as there, with its npy, as a cached one's)
        return Made(key, settings, {**meta, "npy": npy_digest(image)}, True, folder, image=image.astype(np.float32))
    line = "" if stored.replaced else stored.line if stored.same else f"{stored.line} (--force replaces it)"
    if line:
        say(line)
    return Made(key, settings, stored.meta, True, stored.folder, line, stored.image)


def repeats_why(meta: dict, settings: ReferenceSettings) -> str:
    """Why computing the cached reference of ``meta`` again with ``settings`` would only repeat it
    (:func:`~tlm.experiments.reference_cache.repeats`): the words of ``tlm reference``'s line that keeps it."""
    same = all(meta.get(k) == getattr(settings, k) for k in RULE)
    how = (f"computed with these reference settings ({', '.join(RULE)})" if same else
           f"where these reference settings stop it too (cycles of {meta.get('rounds_per_cycle')} "
           f"rounds, at most {meta.get('cycles')} of them, none before the last below the tolerance)")
    return f"{how}: computing it again would repeat the same rounds"


def _kept_elsewhere(key: str, image: np.ndarray, meta: dict, error: BaseException, unkept: bool = False
                    ) -> Path | None:
    """The reference ``key``, which the cache could not take (``error``), written into
    :func:`kept_root` instead, and one warning line that says so; ``error`` itself where
    that cannot be written either (``unkept``: None, the warning saying it is kept nowhere)."""
    root = kept_root()
    try:
        folder = save_reference(key, image, meta, root / "references")
    except (EnvironmentFailure, OSError, InputError) as e:
        warn(f"reference {key}: not kept in {root} either ({' '.join(str(e).split())})"
             + (f"; not cached ({' '.join(str(error).split())}): only this sweep's points are measured against it"
                if unkept else ""))
        if unkept:
            return None
        raise error from None
    warn(f"reference {key}: not cached ({' '.join(str(error).split())}): kept in {folder} instead, "
         f"which later runs read with TLM_CACHE={shell_word(str(root))}")
    return folder
