"""The functional cache: a frame's work counts on disk, keyed by what determines them.

A render's :class:`~tlm.arch.functional.Functional` (what the timing model reads) is
saved as one ``.npz`` keyed by everything that determines it: the config without its
``arch`` section, the scene's content and the code (:func:`tlm.fingerprint.code_fingerprint`,
the whole package). Re-simulating a frame under another architecture config then
reruns only the SimPy layer. Beside each ``.npz`` a JSON sidecar of the same key keeps
what a result row needs and the timing model does not (work totals, scene statistics,
the photon-map frame's image error), so a sweep point never has to render to report
them, with the size and sha256 of the ``.npz`` (``npz``): a damaged entry (a file cut
short, zeroed or overwritten) is reported once as a warning naming the file, removed and
rendered again.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tlm.arch.functional import Functional
from tlm.config import to_dict
from tlm.experiments import run
from tlm.fingerprint import code_fingerprint
from tlm.render.planner import inert_changes
from tlm.scenes.loader import load_scene
from tlm.storage import cache_root, digest_problem, file_digest, warn, write_file


def scene_fingerprint(scene) -> str:
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(scene.triangles, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(scene.material_index).tobytes())
    if scene.normals is not None:
        h.update(np.ascontiguousarray(scene.normals, dtype=np.float64).tobytes())
    h.update(repr((scene.materials, scene.lights, scene.camera, scene.photons)).encode())
    return h.hexdigest()[:16]


@dataclass(frozen=True)
class CachedRender:
    """A frame's :class:`Functional` with the render's summary, and where it came from.

    ``summary`` holds what a result row needs that the timing model does not: the
    scene's statistics, the plan, the primary rays, the work totals per pass, the photon
    map's statistics and the photon-map frame's error, as ``results.json`` of ``tlm run``
    writes them (keys :data:`SUMMARY_KEYS`), and the render's host seconds per stage.
    The error is the one measured when the frame was rendered: a reference computed
    later does not change a cached summary.
    """

    functional: Functional
    summary: dict
    cached: bool  # True when both came from the cache
    key: str  # the cache key (:func:`functional_key`)


SUMMARY_KEYS = ("scene", "plan", "primary", "work", "photons", "error", "warnings")
SUMMARY_FORMAT = "functional-summary/3"  # /2: with the npz's size and sha256; /3: warnings without the settings unused


def render_key(cfg, base: Path | None = None, source: str | None = None) -> str:
    """The cache key of ``cfg``'s frame (loads the scene: a bad scene is an InputError)."""
    scene = load_scene(cfg.scene, base, cfg.resolution, source)
    return functional_key(to_dict(cfg), scene_fingerprint(scene), code_fingerprint())


def is_cached(key: str) -> bool:
    """Whether the cache holds the functional result and the summary of ``key``."""
    d = cache_dir()
    return (d / f"{key}.npz").is_file() and (d / f"{key}.json").is_file()


def cached_render(cfg, base: Path | None = None, source: str | None = None, use_cache: bool = True
                  ) -> CachedRender:
    """The work and summary of ``cfg``'s frame: from the cache, or rendered and cached.

    An entry is the functional result (``<key>.npz``) and its summary (``<key>.json``,
    a sidecar); an entry missing either, unreadable or of an older format is rendered
    again. Both files are written atomically, so concurrent renders of one key (two
    processes of a sweep) leave one whole entry.
    """
    key = render_key(cfg, base, source)
    path = cache_dir() / f"{key}.npz"
    side = path.with_suffix(".json")
    if use_cache and path.exists() and side.exists():
        got = _load_entry(path, side, key)
        if got is not None:
            return got
    res = run.render(cfg, base, source)
    fn = res.functional()
    full = run.results_dict(res, exposure=0.0, config_path=source)
    # the render's own warnings: not this config's unused settings, which another config of the
    # key (a sweep point of other arch or estimate settings) does not share (tlm.experiments.sweep)
    inert = set(inert_changes(cfg))
    full["warnings"] = [w for w in full["warnings"] if w not in inert]
    summary = {"format": SUMMARY_FORMAT, **{k: full[k] for k in SUMMARY_KEYS},
               "host_seconds": {k: round(v, 6) for k, v in res.timer.seconds.items()}}
    if use_cache:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            fn.save(path)  # the npz first: the sidecar holds its size and checksum
            write_file(side, json.dumps({**summary, "npz": file_digest(path)}, indent=1) + "\n")
        except OSError:
            pass  # a read-only (or full) cache only costs speed
    return CachedRender(fn, summary, False, key)


def _load_entry(path: Path, side: Path, key: str) -> CachedRender | None:
    """The cached entry, or None: outdated (an older format, rendered again quietly) or
    damaged (a warning naming the file; both files removed, so it is said once)."""
    try:
        summary = json.loads(side.read_text())
        if not isinstance(summary, dict):
            raise ValueError("not a JSON object")
    except (OSError, ValueError) as e:  # (UnicodeDecodeError is a ValueError)
        _damaged(side, path, f"unreadable sidecar ({type(e).__name__})")
        return None
    if summary.get("format") != SUMMARY_FORMAT:
        return None  # an entry of an older tlm: rendered again and replaced
    problem = digest_problem(path, summary.pop("npz", None))
    if problem is not None:
        _damaged(path, side, problem)
        return None
    try:
        return CachedRender(Functional.load(path), summary, True, key)
    except Exception as e:  # BadZipFile, EOFError, zlib.error, ValueError, KeyError: a damaged file
        _damaged(path, side, f"{type(e).__name__}: {e}")
        return None


def _damaged(bad: Path, other: Path, why: str) -> None:  # (its callers return None)
    warn(f"damaged functional cache entry {bad} ({why}): removed, rendering it again")
    for f in (bad, other):
        f.unlink(missing_ok=True)


def cached_functional(cfg, base: Path | None = None, source: str | None = None, use_cache: bool = True
                      ) -> tuple[Functional, bool]:
    """The work of ``cfg``'s frame: from the cache when an identical render was cached.

    Returns the :class:`Functional` and whether it came from the cache. The key is the
    config without ``arch`` (and without what only changes pixels' brightness), the
    scene's content and the functional layer's source code.
    """
    got = cached_render(cfg, base, source, use_cache)
    return got.functional, got.cached


def cache_dir() -> Path:
    return cache_root("functional")


def functional_key(cfg_dict: dict, scene_fingerprint: str, code_version: str) -> str:
    """Hash of what the work counts depend on: the config without ``arch``, the scene."""
    keep = {k: v for k, v in cfg_dict.items() if k not in ("arch", "reference")}
    keep.setdefault("render", {})
    # (not what changes only brightness or speed: the exposure, the kernels' threads)
    keep["render"] = {k: v for k, v in keep["render"].items() if k not in ("exposure", "threads")}
    blob = json.dumps({"cfg": keep, "scene": scene_fingerprint, "code": code_version}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:24]
