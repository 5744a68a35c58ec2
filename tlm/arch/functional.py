"""The seam between the functional layer and the timing model: what a render hands over.

Functional results do not depend on timing (docs/design.md, "Why the seam makes sweeps
cheap"), so a render's work counts are kept apart from the SimPy layer: :class:`Functional`
holds exactly what the timing model reads and can be saved and loaded as one ``.npz``. The cache of these files,
keyed by what determines them, is :mod:`tlm.experiments.frames`.

The work items and their typed arrays are declared once, below the render, in
:mod:`tlm.kernels.work` (:class:`RayPassWork`, :class:`GatherWork`, :class:`PhotonWork`,
:class:`BuildLevelWork`; re-exported here). The render produces plain dicts of those
keys; :meth:`Functional.of` takes them as the render returns them (each pass's work, the
geometry BSP, the photon trace) and converts them strictly: a key the schema lacks, or
one it has and the dict lacks, is an error, so that a new work key cannot be dropped on
the way to the timing model.
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO

import numpy as np

from tlm.kernels.bsp import BSPTree
from tlm.kernels.work import (
    GATHER_PASS,
    LEVEL_FIELDS,
    RAY_PASSES,
    BuildLevelWork,
    GatherWork,
    PhotonWork,
    RayPassWork,
    WorkArrays,
    pass_work_class,
)
from tlm.storage import write_atomic

if TYPE_CHECKING:
    from tlm.kernels.photons import PhotonTrace

FORMAT = "functional/3"  # the .npz layout (unchanged by the typed classes: old entries load)
PassWork = RayPassWork | GatherWork

__all__ = ["FORMAT", "GATHER_PASS", "LEVEL_FIELDS", "RAY_PASSES", "BuildLevelWork", "Functional", "GatherWork",
           "PassWork", "PhotonWork", "RayPassWork", "TreeWork", "WorkArrays", "pass_work_class", "save_npz"]

NPZ_LEVEL = 1  # zlib's level for save_npz: savez_compressed's 6 takes 1.6-6x the time for 3-20% fewer bytes


def save_npz(file: Path | BinaryIO, arrays: Mapping[str, np.ndarray], level: int = NPZ_LEVEL) -> None:
    """``np.savez_compressed(file, **arrays)`` at zlib level ``level``: the same zip of the same
    ``<name>.npy`` members (zip64, deflated), which ``np.load`` reads back as the same arrays
    (dtype, shape and values), without pickles (an object array is a ValueError). ``file``: a
    path (written as it is named, no ``.npz`` added) or a binary file open for writing."""
    with zipfile.ZipFile(file, mode="w", compression=zipfile.ZIP_DEFLATED, compresslevel=level,
                         allowZip64=True) as zf:
        for name, value in arrays.items():
            with zf.open(f"{name}.npy", "w", force_zip64=True) as member:
                np.lib.format.write_array(member, np.asanyarray(value), allow_pickle=False)


def _whole(v, what: str, minimum: int = 0) -> int:
    if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or v < minimum:
        raise ValueError(f"{what} (={v!r}) must be a whole number >= {minimum}")
    return int(v)


@dataclass(frozen=True, eq=False)
class TreeWork:
    """One BSP build (Algorithm 1): per-level work and sizes.

    ``levels`` may be given as a mapping (field -> array), converted by
    :meth:`BuildLevelWork.from_mapping`.
    """

    levels: BuildLevelWork
    n_elements: int  # elements of the list (Vertex PM job: read once)
    slots: int  # element slots of the final list (triangles: with the expansion copies)
    nodes: int  # nodes of the tree (the tree's words fanned out to the pipelines)

    def __post_init__(self) -> None:
        if not isinstance(self.levels, BuildLevelWork):
            if not isinstance(self.levels, Mapping):
                raise ValueError(f"TreeWork.levels: expected BuildLevelWork, got {type(self.levels).__name__}")
            object.__setattr__(self, "levels", BuildLevelWork.from_mapping(self.levels, "TreeWork.levels"))
        for name in ("n_elements", "slots", "nodes"):
            object.__setattr__(self, name, _whole(getattr(self, name), f"TreeWork.{name}"))

    @classmethod
    def of(cls, tree: BSPTree) -> TreeWork:
        lv = {f: np.array([getattr(w, f) for w in tree.work], dtype=np.int64) for f in LEVEL_FIELDS}
        return cls(BuildLevelWork(**lv), int(tree.n_elements), int(tree.items.shape[0]), int(tree.n_nodes))

    @classmethod
    def of_maps(cls, photons) -> TreeWork:
        """The photon maps' builds (:class:`~tlm.kernels.photons.PhotonMaps` ``gathered``: caustic
        and indirect, or caustic and global with final gathering) as one job of
        the Vertex PM: level j's work is the two trees' level-j work added (the shallower
        tree's missing levels count as zero), sizes added."""
        parts = [cls.of(m.tree) for m in getattr(photons, "gathered", photons.maps)]
        depth = max(p.n_levels for p in parts)
        levels = {f: sum(np.pad(p.levels[f], (0, depth - p.n_levels)) for p in parts) for f in LEVEL_FIELDS}
        return cls(BuildLevelWork(**{f: np.asarray(v, dtype=np.int64) for f, v in levels.items()}),
                   sum(p.n_elements for p in parts), sum(p.slots for p in parts), sum(p.nodes for p in parts))

    @property
    def n_levels(self) -> int:
        return self.levels.n

    def __eq__(self, other) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return (self.levels == other.levels and self.n_elements == other.n_elements
                and self.slots == other.slots and self.nodes == other.nodes)

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, eq=False)
class Functional:
    """The work of one image, as the timing model charges it.

    ``work`` maps every rendered pass (plan order, as ``passes``) to its typed work:
    :class:`RayPassWork` for the ray passes, :class:`GatherWork` for ``pmap``. Plain
    mappings (pass -> key -> array, key -> array) are accepted for ``work`` and
    ``photon_work`` and converted strictly (:meth:`WorkArrays.from_mapping`), so a
    render's dicts, or ``dataclasses.replace(fn, work=...)`` with edited arrays, give a
    validated, typed :class:`Functional`.
    """

    passes: tuple[str, ...]  # rendered passes, plan order
    work: dict[str, PassWork]  # pass -> its per-pixel work, (pixels,) row-major
    geometry: TreeWork  # the geometry BSP's build
    photon_work: PhotonWork | None  # (photons,) emission order; None without photons
    photon_tree: TreeWork | None  # both photon maps' builds; None without photons
    pixels: int
    width: int  # image columns: pixel i is at row i // width, column i % width

    def __post_init__(self) -> None:
        set_ = lambda k, v: object.__setattr__(self, k, v)  # noqa: E731
        set_("passes", tuple(self.passes))
        for p in self.passes:
            if not isinstance(p, str):
                raise ValueError(f"Functional.passes: {p!r} is not a pass name")
        if len(set(self.passes)) != len(self.passes):
            raise ValueError(f"Functional.passes: {self.passes} repeats a pass")
        pixels = _whole(self.pixels, "Functional.pixels")
        width = _whole(self.width, "Functional.width", 1)
        if pixels % width:
            raise ValueError(f"Functional: {pixels} pixels are no whole number of rows of {width}")
        set_("pixels", pixels)
        set_("width", width)
        if not isinstance(self.work, Mapping) or set(self.work) != set(self.passes):
            got = sorted(self.work) if isinstance(self.work, Mapping) else type(self.work).__name__
            raise ValueError(f"Functional.work: expected the work of the passes {list(self.passes)}, got {got}")
        work = {}
        for p in self.passes:
            cls, w = pass_work_class(p), self.work[p]
            if not isinstance(w, cls):
                if isinstance(w, WorkArrays) or not isinstance(w, Mapping):
                    raise ValueError(f"Functional.work[{p!r}]: expected {cls.__name__}, got {type(w).__name__}")
                w = cls.from_mapping(w, f"Functional.work[{p!r}]")
            if w.n != pixels:
                raise ValueError(f"Functional.work[{p!r}]: {w.n} pixels, the image has {pixels}")
            work[p] = w
        set_("work", work)
        if not isinstance(self.geometry, TreeWork):
            raise ValueError(f"Functional.geometry: expected TreeWork, got {type(self.geometry).__name__}")
        pw = self.photon_work
        if pw is not None and not isinstance(pw, PhotonWork):
            if isinstance(pw, WorkArrays) or not isinstance(pw, Mapping):
                raise ValueError(f"Functional.photon_work: expected PhotonWork, got {type(pw).__name__}")
            set_("photon_work", PhotonWork.from_mapping(pw, "Functional.photon_work"))
        if self.photon_tree is not None and not isinstance(self.photon_tree, TreeWork):
            raise ValueError(f"Functional.photon_tree: expected TreeWork, got {type(self.photon_tree).__name__}")
        if (self.photon_work is None) != (self.photon_tree is None):
            raise ValueError("Functional: photon_work and photon_tree come together (both None without photons)")

    @property
    def height(self) -> int:
        return self.pixels // self.width

    def ray_work(self, name: str) -> RayPassWork:
        """The work of the ray pass ``name`` (one of :data:`RAY_PASSES` that was rendered)."""
        w = self.work[name]
        if not isinstance(w, RayPassWork):
            raise ValueError(f"{name!r} is not a ray pass")
        return w

    @property
    def gather_work(self) -> GatherWork | None:
        """The photon-map pass's work (None when the plan has no pmap pass)."""
        w = self.work.get(GATHER_PASS)
        assert w is None or isinstance(w, GatherWork)
        return w

    @classmethod
    def of(cls, work: Mapping[str, Mapping[str, np.ndarray]], geometry: BSPTree, photons: PhotonTrace | None,
           width: int) -> Functional:
        """From what the render produces: ``work``, each rendered pass's work dict in plan
        order (key -> (H, W) or (pixels,) counts, as the pass functions return them), the
        geometry BSP, the photon trace (None without a pmap pass) and the image's width.
        The dicts are converted strictly to the typed work (:meth:`WorkArrays.from_mapping`)."""
        passes = tuple(work)
        first = next((v for w in work.values() for v in w.values()), None)
        return cls(
            passes=passes, work=dict(work), geometry=TreeWork.of(geometry),
            photon_work=None if photons is None else PhotonWork.from_mapping(photons.work, "photon work"),
            photon_tree=None if photons is None else TreeWork.of_maps(photons.photons),
            pixels=0 if first is None else int(np.size(first)), width=width,
        )

    def __eq__(self, other) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return (self.passes == other.passes and self.pixels == other.pixels and self.width == other.width
                and all(self.work[p] == other.work[p] for p in self.passes)
                and self.geometry == other.geometry and self.photon_work == other.photon_work
                and self.photon_tree == other.photon_tree)

    __hash__ = None  # type: ignore[assignment]

    # -- persistence -------------------------------------------------------------------
    def save(self, path: Path) -> None:
        """One ``.npz``: ``work/<pass>/<field>``, ``photons/<field>``, ``tree/<name>/<field>``, ``meta``."""
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
            save_npz(fh, arrays)

    @classmethod
    def load(cls, path: Path) -> Functional:
        """What :meth:`save` wrote. A file of another format, or whose work does not fit the
        typed classes, is a ValueError (the functional cache then renders again)."""
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
        try:
            trees = {name: TreeWork(levels.get(name, {}), **sizes) for name, sizes in meta["trees"].items()}
            return cls(tuple(meta["passes"]), work, trees["geometry"], photons or None,
                       trees.get("photon_tree"), int(meta["pixels"]), int(meta["width"]))
        except (TypeError, ValueError) as e:
            raise ValueError(f"{path}: {e}") from e
