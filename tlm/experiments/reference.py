"""Converged reference images of the photon-mapped term, cached, and image error.

A reference is the exact k-nearest-photon estimate (Jensen's, cone filter) at the
Lambertian eye hits, averaged over independent photon maps (each round traces a new
map from a child of one ``SeedSequence``) until the mean's relative standard error —
the RMS over pixels of the per-pixel standard error of the mean, estimated from the
spread of the rounds, over the RMS of the mean — falls below ``tolerance``. (The
change a single round makes shrinks as 1/rounds while the error shrinks only as
1/sqrt(rounds), so the standard error is the honest stopping rule; the change per
round is recorded too.) What it converges to is the expectation of the k-NN estimate
with that many photons per round: the kernel's blur remains (a smaller
``k_nearest`` or more photons per round shrink it). ``meta.json`` records the rounds,
both measures per round and whether the tolerance was met.

References are cached under ``$TLM_CACHE`` (default ``~/.cache/tlm``) in
``references/<key>/``, keyed by everything the converged image depends on: the scene
(triangles, materials, lights, camera and resolution), the photon path settings
(``max_bounces``) and the reference settings. The run's seed, filter, radius and
photon count are not part of the key: every PMap run of a scene is measured against
the same reference. Nor is the stopping rule: ``tlm reference`` reuses a cached
reference that meets the requested tolerance and computes it again otherwise.
"""

from __future__ import annotations

import hashlib
import json
import sys
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from tlm.config import RunConfig
from tlm.kernels.estimate import knn_estimate
from tlm.render.passes import Frame, GBuffer, gather_points, pixel_mean, trace_photon_map
from tlm.scenes.model import Scene
from tlm.storage import atomic_folder, cache_root, digest_problem, file_digest, warn

REFERENCE_SEED = 0x5EED


@dataclass(frozen=True)
class ReferenceSettings:
    photons: int  # per round
    k_nearest: int = 100
    tolerance: float = 0.02
    min_rounds: int = 4
    max_rounds: int = 64

    @classmethod
    def from_config(cls, scene: Scene, cfg: RunConfig) -> ReferenceSettings:
        r = cfg.reference
        return cls(photons=scene.photons if r.photons is None else r.photons, k_nearest=r.k_nearest,
                   tolerance=r.tolerance, min_rounds=r.min_rounds, max_rounds=r.max_rounds)


def cache_dir() -> Path:
    return cache_root("references")


def reference_key(scene: Scene, cfg: RunConfig, settings: ReferenceSettings) -> str:
    """A hash of everything the converged photon-map image depends on."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(scene.triangles).tobytes())
    h.update(np.ascontiguousarray(scene.material_index).tobytes())
    if scene.normals is not None:
        h.update(np.ascontiguousarray(scene.normals, dtype=np.float64).tobytes())
    doc = {
        "materials": [m.record() for m in scene.materials],
        "lights": [lt.record() for lt in scene.lights],
        "camera": asdict(scene.camera),
        "max_bounces": cfg.photons.max_bounces,
        # where the photon term is gathered: the eye samples and the specular walks' ends
        "gather": {"spp": cfg.render.spp, "reflect_depth": cfg.render.reflect_depth,
                   "refract_depth": cfg.render.refract_depth, "min_weight": cfg.render.min_weight},
        # what the converged image depends on; the stopping rule (tolerance, rounds) only
        # says how close to it the cached mean is, which meta.json records
        "reference": {"photons": settings.photons, "k_nearest": settings.k_nearest},
    }
    h.update(json.dumps(doc, sort_keys=True).encode())
    return h.hexdigest()[:20]


def compute_reference(frame: Frame, g: GBuffer, settings: ReferenceSettings, progress=None,
                      bar: bool = False) -> tuple[np.ndarray, dict]:
    """Average k-NN photon-map frames over independent maps until converged.

    progress : called ``(round, change, standard error)`` after every round but the first.
    bar : a progress bar of the rounds on stderr (only when it is a terminal).
    Returns the (pixels, 3) radiance and the metadata (rounds, changes, converged).
    """
    from scipy.spatial import cKDTree
    from tqdm import tqdm

    cfg = frame.cfg
    idx, tri, pts, n, weight = gather_points(frame, g)
    mean = np.zeros((g.pixels.shape[0], 3))
    m2 = np.zeros_like(mean)  # Welford's running sum of squared deviations
    changes: list[float] = []
    errors: list[float] = []
    seeds = np.random.SeedSequence(REFERENCE_SEED).spawn(settings.max_rounds)
    t0 = time.perf_counter()
    converged = False
    rounds = tqdm(total=settings.max_rounds, desc="reference", unit="round", disable=None if bar else True,
                  file=sys.stderr, dynamic_ncols=True, leave=False)
    for k, child in enumerate(seeds, start=1):
        seed = int(child.generate_state(1)[0])
        ph = trace_photon_map(frame, settings.photons, seed).photons
        samples = np.zeros((g.origin.shape[0], 3))
        if ph.n and idx.shape[0]:
            e = knn_estimate(ph.position, ph.power, ph.incoming, pts, n, k_nearest=settings.k_nearest,
                             cone_k=cfg.estimate.cone_k, kdtree=cKDTree(ph.position))
            np.add.at(samples, idx, weight * frame.albedo[tri] / np.pi * e.density)
        frame_k = pixel_mean(frame, samples)
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
        rounds.update()
        if k > 1:
            rounds.set_postfix_str(f"relative standard error {errors[-1]:.4f} (stop below {settings.tolerance})")
        if progress is not None and k > 1:
            progress(k, changes[-1], errors[-1])
        if k >= settings.min_rounds and errors[-1] < settings.tolerance:
            converged = True
            break
    rounds.close()
    meta = {
        **asdict(settings),
        "rounds": len(errors) + 1,
        "relative_standard_error": errors[-1] if errors else None,
        "final_change": changes[-1] if changes else None,
        "standard_error_per_round": errors,
        "change_per_round": changes,
        "converged": converged,
        "host_seconds": round(time.perf_counter() - t0, 3),
        "seed": REFERENCE_SEED,
    }
    return mean, meta


def save_reference(key: str, image: np.ndarray, meta: dict) -> Path:
    """Write ``reference.npy`` and ``meta.json`` atomically into the cache."""
    final = cache_dir() / key
    with atomic_folder(final, "meta.json") as tmp:
        np.save(tmp / "reference.npy", image.astype(np.float32))
        body = {"key": key, **meta, "npy": file_digest(tmp / "reference.npy")}
        (tmp / "meta.json").write_text(json.dumps(body, indent=2) + "\n")
    return final


def load_reference(key: str) -> tuple[np.ndarray, dict] | None:
    """The cached reference ``key`` and its metadata, or None when there is none.

    A damaged one (``meta.json`` unreadable or of another key, ``reference.npy`` not the
    file ``meta.json`` describes, or not an array) is reported once as a warning naming
    the file and removed: it is computed again as if it had never been cached.
    """
    import shutil

    folder = cache_dir() / key
    npy, side = folder / "reference.npy", folder / "meta.json"
    if not npy.is_file() and not side.is_file():
        return None
    bad, why = side, None
    try:
        meta = json.loads(side.read_text())
        if not isinstance(meta, dict) or meta.get("key") != key:
            raise ValueError("not the metadata of this reference")
    except (OSError, ValueError) as e:
        why = f"unreadable ({type(e).__name__}: {' '.join(str(e).split())[:80]})"
    if why is None:
        bad = npy
        why = digest_problem(npy, meta["npy"]) if "npy" in meta else None  # (older entries have none)
    if why is None:
        try:
            image = np.load(npy, allow_pickle=False)
            if image.dtype.kind != "f" or image.ndim != 3 or image.shape[-1] != 3:
                raise ValueError(f"an array of {image.dtype} {image.shape}, not (H, W, 3) floats")
            return image, meta
        except (OSError, ValueError, EOFError) as e:
            why = f"{type(e).__name__}: {' '.join(str(e).split())[:80]}"
    warn(f"damaged reference cache entry {bad} ({why}): removed; 'tlm reference' computes it again")
    shutil.rmtree(folder, ignore_errors=True)
    return None


def image_error(image: np.ndarray, reference: np.ndarray) -> dict[str, float | None]:
    """RMSE and relative MSE (sum of squared error over sum of squared reference; None
    for a black reference)."""
    diff = np.asarray(image, dtype=np.float64) - np.asarray(reference, dtype=np.float64)
    ref2 = float(np.sum(np.asarray(reference, dtype=np.float64) ** 2))
    sq = float(np.sum(diff**2))
    return {"rmse": float(np.sqrt(np.mean(diff**2))), "rel_mse": sq / ref2 if ref2 > 0 else None}
