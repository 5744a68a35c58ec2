"""What the timing model needs from a render, and a cache of it on disk.

Functional results do not depend on timing (DESIGN.md §6), so a render's work counts
are kept apart from the SimPy layer: :class:`Functional` holds exactly what the timing
model reads (per-pixel work of every pass, per-photon work, the BSP builds' per-level
work), can be saved and loaded as one ``.npz``, and is keyed by everything that
determines it (the config without its ``arch`` section, the scene's content, the code
version). Re-simulating a frame under another architecture config then reruns only
the SimPy layer. Beside each ``.npz`` a JSON sidecar of the same key keeps what a
result row needs and the timing model does not (work totals, scene statistics, the
photon-map frame's image error), so a sweep point never has to render to report them.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tlm.kernels.bsp import BSPTree

LEVEL_FIELDS = ("nodes", "elements_in", "storage_reads", "elements_out", "expansion_copies")
FORMAT = "functional/3"


@dataclass(frozen=True)
class TreeWork:
    """One BSP build (Algorithm 1): per-level work and sizes."""

    levels: dict[str, np.ndarray]  # LEVEL_FIELDS -> (levels,) int64
    n_elements: int
    slots: int  # element slots of the final list (triangles: with the expansion copies)
    nodes: int

    @classmethod
    def of(cls, tree: BSPTree) -> TreeWork:
        lv = {f: np.array([getattr(w, f) for w in tree.work], dtype=np.int64) for f in LEVEL_FIELDS}
        return cls(lv, int(tree.n_elements), int(tree.items.shape[0]), int(tree.n_nodes))

    @classmethod
    def of_maps(cls, photons) -> TreeWork:
        """Both photon maps' builds (:class:`~tlm.kernels.photons.PhotonMaps`) as one job of
        the Vertex PM: level j's work is the two trees' level-j work added (the shallower
        tree's missing levels count as zero), sizes added."""
        parts = [cls.of(m.tree) for m in photons.maps]
        depth = max(p.n_levels for p in parts)
        levels = {f: sum(np.pad(p.levels[f], (0, depth - p.n_levels)) for p in parts) for f in LEVEL_FIELDS}
        return cls({f: np.asarray(v, dtype=np.int64) for f, v in levels.items()},
                   sum(p.n_elements for p in parts), sum(p.slots for p in parts), sum(p.nodes for p in parts))

    @property
    def n_levels(self) -> int:
        return int(self.levels["nodes"].shape[0])


@dataclass(frozen=True)
class Functional:
    """The work of one image, as the timing model charges it."""

    passes: tuple[str, ...]  # rendered passes, plan order
    work: dict[str, dict[str, np.ndarray]]  # pass -> key -> (pixels,) int64, row-major
    geometry: TreeWork
    photon_work: dict[str, np.ndarray] | None  # key -> (photons,) int64, emission order
    photon_tree: TreeWork | None
    pixels: int
    width: int  # image columns: pixel i is at row i // width, column i % width

    @property
    def height(self) -> int:
        return self.pixels // self.width

    @classmethod
    def of(cls, res) -> Functional:
        """From a :class:`~tlm.experiments.run.RenderResult`."""
        work = {p: {k: np.asarray(v, dtype=np.int64).reshape(-1) for k, v in res.work[p].items()}
                for p in res.plan.run_names}
        traced = res.photons
        return cls(
            passes=tuple(res.plan.run_names), work=work, geometry=TreeWork.of(res.accel.tree),
            photon_work=None if traced is None else {k: np.asarray(v, np.int64) for k, v in traced.work.items()},
            photon_tree=None if traced is None else TreeWork.of_maps(traced.photons),
            pixels=int(res.gbuffer.pixels.shape[0]), width=int(res.scene.camera.width),
        )

    # -- persistence -------------------------------------------------------------------
    def save(self, path: Path) -> None:
        arrays: dict[str, np.ndarray] = {}
        meta = {"format": FORMAT, "passes": list(self.passes), "pixels": self.pixels, "width": self.width,
                "trees": {}}
        for p, counts in self.work.items():
            for k, v in counts.items():
                arrays[f"work/{p}/{k}"] = v
        for name, tw in (("geometry", self.geometry), ("photon_tree", self.photon_tree)):
            if tw is None:
                continue
            meta["trees"][name] = {"n_elements": tw.n_elements, "slots": tw.slots, "nodes": tw.nodes}
            for f, v in tw.levels.items():
                arrays[f"tree/{name}/{f}"] = v
        for k, v in (self.photon_work or {}).items():
            arrays[f"photons/{k}"] = v
        arrays["meta"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
        tmp = path.with_name(path.name + f".tmp{os.getpid()}")
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        os.replace(tmp, path)

    @classmethod
    def load(cls, path: Path) -> Functional:
        with np.load(path) as z:
            meta = json.loads(bytes(z["meta"]).decode())
            if meta.get("format") != FORMAT:
                raise ValueError(f"{path}: format {meta.get('format')!r}, expected {FORMAT!r}")
            work: dict[str, dict[str, np.ndarray]] = {p: {} for p in meta["passes"]}
            photons: dict[str, np.ndarray] = {}
            levels: dict[str, dict[str, np.ndarray]] = {}
            for name in z.files:
                parts = name.split("/")
                if parts[0] == "work":
                    work[parts[1]][parts[2]] = z[name]
                elif parts[0] == "photons":
                    photons[parts[1]] = z[name]
                elif parts[0] == "tree":
                    levels.setdefault(parts[1], {})[parts[2]] = z[name]
        trees = {name: TreeWork(levels[name], **sizes) for name, sizes in meta["trees"].items()}
        return cls(tuple(meta["passes"]), work, trees["geometry"], photons or None,
                   trees.get("photon_tree"), int(meta["pixels"]), int(meta["width"]))


def code_fingerprint() -> str:
    """Hash of the functional layer's source: a changed kernel invalidates the cache."""
    global _CODE
    if _CODE is None:
        root = Path(__file__).resolve().parents[1]
        h = hashlib.sha256()
        files = [root / "arch" / "cache.py", root / "config.py"]
        for sub in ("kernels", "render", "scenes"):
            files.extend(sorted((root / sub).glob("*.py")))
        for f in files:
            h.update(f.name.encode())
            h.update(f.read_bytes())
        _CODE = h.hexdigest()[:16]
    return _CODE


_CODE: str | None = None


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
SUMMARY_FORMAT = "functional-summary/1"


def render_key(cfg, base: Path | None = None, source: str | None = None) -> str:
    """The cache key of ``cfg``'s frame (loads the scene: a bad scene is an InputError)."""
    from tlm.config import to_dict
    from tlm.scenes.loader import load_scene

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
    from tlm.experiments.run import render, results_dict

    key = render_key(cfg, base, source)
    path = cache_dir() / f"{key}.npz"
    side = path.with_suffix(".json")
    if use_cache and path.exists() and side.exists():
        try:
            summary = json.loads(side.read_text())
            if summary.get("format") != SUMMARY_FORMAT:
                raise ValueError(f"{side}: format {summary.get('format')!r}, expected {SUMMARY_FORMAT!r}")
            return CachedRender(Functional.load(path), summary, True, key)
        except (ValueError, KeyError, OSError):
            pass  # an unreadable or outdated entry is recomputed
    res = render(cfg, base, source)
    fn = Functional.of(res)
    full = results_dict(res, exposure=0.0, config_path=source)
    summary = {"format": SUMMARY_FORMAT, **{k: full[k] for k in SUMMARY_KEYS},
               "host_seconds": {k: round(v, 6) for k, v in res.timer.seconds.items()}}
    if use_cache:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            _write_atomic(side, (json.dumps(summary, indent=1) + "\n").encode())
            fn.save(path)
        except OSError:
            pass  # a read-only cache only costs speed
    return CachedRender(fn, summary, False, key)


def cached_functional(cfg, base: Path | None = None, source: str | None = None, use_cache: bool = True
                      ) -> tuple[Functional, bool]:
    """The work of ``cfg``'s frame: from the cache when an identical render was cached.

    Returns the :class:`Functional` and whether it came from the cache. The key is the
    config without ``arch`` (and without what only changes pixels' brightness), the
    scene's content and the functional layer's source code.
    """
    got = cached_render(cfg, base, source, use_cache)
    return got.functional, got.cached


def _write_atomic(path: Path, data: bytes) -> None:
    tmp = path.with_name(path.name + f".tmp{os.getpid()}")
    tmp.write_bytes(data)
    os.replace(tmp, path)


def cache_dir() -> Path:
    base = os.environ.get("TLM_CACHE") or (Path.home() / ".cache" / "tlm")
    return Path(base) / "functional"


def functional_key(cfg_dict: dict, scene_fingerprint: str, code_version: str) -> str:
    """Hash of what the work counts depend on: the config without ``arch``, the scene."""
    keep = {k: v for k, v in cfg_dict.items() if k not in ("arch", "reference")}
    keep.setdefault("render", {})
    keep["render"] = {k: v for k, v in keep["render"].items() if k != "exposure"}
    blob = json.dumps({"cfg": keep, "scene": scene_fingerprint, "code": code_version}, sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:24]
