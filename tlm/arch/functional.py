"""The seam between the functional layer and the timing model: what a render hands over.

Functional results do not depend on timing (DESIGN.md §6), so a render's work counts
are kept apart from the SimPy layer: :class:`Functional` holds exactly what the timing
model reads (per-pixel work of every pass, per-photon work, the BSP builds' per-level
work, :class:`TreeWork`) and can be saved and loaded as one ``.npz``. The cache of
these files, keyed by what determines them, is :mod:`tlm.experiments.frames`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from tlm.kernels.bsp import BSPTree
from tlm.storage import write_atomic

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
        with write_atomic(path, mode="wb") as fh:
            np.savez_compressed(fh, **arrays)

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
