"""The seam between the functional layer and the timing model: what a render hands over.

Functional results do not depend on timing (docs/design.md, "Why the seam makes sweeps
cheap"), so a render's work counts are kept apart from the SimPy layer: :class:`Functional`
holds exactly what the timing model reads and can be saved and loaded as one ``.npz``. The cache of these files,
keyed by what determines them, is :mod:`tlm.experiments.frames`.

The work is typed, one frozen dataclass per kind of work item (after pbrt-v4's
wavefront ``workitems.h``: the queues between its kernels hold typed work items, stored
as structures of arrays), each field one count per item as an ``(items,)`` int64 array:

* :class:`RayPassWork`: per pixel, a ray pass (``rcast``, ``reflect``, ``refract``);
* :class:`GatherWork`: per pixel, the photon-map pass (``pmap``);
* :class:`PhotonWork`: per emitted photon, in emission order;
* :class:`BuildLevelWork`: per level of a BSP build (Algorithm 1), in :class:`TreeWork`.

Every field's metadata ``doc`` says which unit charges it. The render produces plain
dicts (:data:`tlm.render.passes.WORK_KEYS` and ``GATHER_KEYS``,
:data:`tlm.kernels.photons.PHOTON_WORK`); they are converted here, strictly: a key the
dataclass lacks, or one it has and the dict lacks, is an error, so that a new work key
cannot be dropped on the way to the timing model (``tests/test_seam.py`` also checks
that the fields and the render's keys agree).

The PM program table (``programs.yaml``) prices work by *name*, so each work class also
reads as a read-only mapping from field name to array (``w["tri_tests"]``,
``w.items()``); the timing model reads its own fields as attributes.
"""

from __future__ import annotations

import json
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import ClassVar

import numpy as np

from tlm.kernels.bsp import BSPTree
from tlm.storage import write_atomic

FORMAT = "functional/3"  # the .npz layout (unchanged by the typed classes: old entries load)

# per-pixel ray passes: RayPassWork (fgather: the final-gather rays, traced with the photon-map frame)
RAY_PASSES = ("rcast", "reflect", "refract", "fgather")
GATHER_PASS = "pmap"  # the photon-map pass: GatherWork


def _count(doc: str):
    """A work field: one int64 count per item; ``doc`` says what it counts and who charges it."""
    return field(metadata={"doc": doc})


class WorkArrays(Mapping):
    """Base of the typed work classes: equal-length ``(items,)`` int64 arrays, one per field.

    Validated at construction (every field a 1-D int64 array, all of one length, no
    negative count); the arrays are stored as read-only views. Reads as a read-only
    mapping from field name to array (``KEYS`` in field order).
    """

    KEYS: ClassVar[tuple[str, ...]] = ()
    ITEM: ClassVar[str] = "item"  # what one entry of the arrays is (for messages)

    def __post_init__(self) -> None:
        n = None
        for k in self.KEYS:
            v = getattr(self, k)
            where = f"{type(self).__name__}.{k}"
            if not isinstance(v, np.ndarray):
                raise ValueError(f"{where}: expected a numpy array, got {type(v).__name__}")
            if v.dtype != np.int64 or v.ndim != 1:
                raise ValueError(f"{where}: expected a 1-D int64 array (one count per {self.ITEM}), "
                                 f"got {v.dtype} of shape {v.shape}")
            if n is None:
                n = v.shape[0]
            elif v.shape[0] != n:
                raise ValueError(f"{type(self).__name__}: {k} has {v.shape[0]} {self.ITEM}s, "
                                 f"{self.KEYS[0]} has {n}")
            if v.size and v.min() < 0:
                raise ValueError(f"{where}: negative count at {self.ITEM} {int(np.argmin(v))}")
            if v.flags.writeable:
                v = v.view()
                v.flags.writeable = False
                object.__setattr__(self, k, v)

    @classmethod
    def from_mapping(cls, work: Mapping[str, np.ndarray], what: str | None = None):
        """From a render's dict (key -> integer array of any shape, read row-major).

        The keys must be exactly :attr:`KEYS`; integer arrays are converted to int64.
        """
        what = what or cls.__name__
        if isinstance(work, cls):
            return work
        missing = [k for k in cls.KEYS if k not in work]
        extra = [k for k in work if k not in cls.KEYS]
        if missing or extra:
            raise ValueError(f"{what}: the work keys differ from {cls.__name__}'s fields"
                             + (f"; missing {missing}" if missing else "")
                             + (f"; unknown {extra}" if extra else ""))
        arrays = {}
        for k in cls.KEYS:
            v = np.asarray(work[k])
            if v.dtype != np.int64:
                if not (np.issubdtype(v.dtype, np.integer) or (v.dtype == np.bool_)):
                    raise ValueError(f"{what}.{k}: work counts must be integers, got {v.dtype}")
                v = v.astype(np.int64)
            arrays[k] = v.reshape(-1)
        return cls(**arrays)

    @classmethod
    def zeros(cls, n: int):
        """``n`` items without work."""
        return cls(**{k: np.zeros(n, dtype=np.int64) for k in cls.KEYS})

    @property
    def n(self) -> int:
        """Items (pixels, photons or levels): the arrays' length."""
        return int(getattr(self, self.KEYS[0]).shape[0]) if self.KEYS else 0

    def totals(self) -> dict[str, int]:
        return {k: int(getattr(self, k).sum()) for k in self.KEYS}

    def as_dict(self) -> dict[str, np.ndarray]:
        return {k: getattr(self, k) for k in self.KEYS}

    # -- read-only mapping: field name -> array ----------------------------------------------
    def __getitem__(self, key: str) -> np.ndarray:
        if key not in self.KEYS:
            raise KeyError(key)
        return getattr(self, key)

    def __iter__(self) -> Iterator[str]:
        return iter(self.KEYS)

    def __len__(self) -> int:
        return len(self.KEYS)

    def __contains__(self, key) -> bool:
        return key in self.KEYS

    def __eq__(self, other) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(np.array_equal(getattr(self, k), getattr(other, k)) for k in self.KEYS)

    __hash__ = None  # type: ignore[assignment]

    def __reduce__(self):
        return _rebuild, (type(self), self.as_dict())  # unpickled through the validation (read-only arrays)

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.n} {self.ITEM}s: " + \
            ", ".join(f"{k}={int(getattr(self, k).sum())}" for k in self.KEYS) + ")"


def _rebuild(cls, arrays: dict[str, np.ndarray]):
    return cls(**arrays)


def _typed(cls):
    """Freeze ``cls`` as a dataclass (array equality and repr from :class:`WorkArrays`) and set ``KEYS``."""
    cls = dataclass(frozen=True, eq=False, repr=False)(cls)
    cls.KEYS = tuple(f.name for f in fields(cls))
    return cls


@_typed
class RayPassWork(WorkArrays):
    """Per pixel (row-major, a pixel's samples summed): a ray pass, ``rcast``, ``reflect`` or ``refract``.

    Its pixels with rays run the pass's ``rays`` phase (Traversal PM job ``rays``, then
    the Intersection PM, then Fragment PM job ``shade``); those with shadow rays its
    ``shadow`` phase (Traversal PM job ``shadow``, the Intersection PM, Fragment PM job
    ``light``). Per-item weights of the programmable PMs: ``programs.yaml``.
    """

    ITEM: ClassVar[str] = "pixel"

    primary_rays: np.ndarray = _count(
        "eye rays traced: Traversal PM (rays: generated there); Intersection PM (a ray load each)")
    secondary_rays: np.ndarray = _count(
        "reflected / refracted rays traced: Traversal PM (rays); Intersection PM (ray loads); "
        "the crossbar (a ray record each, from the Fragment PM's module to the Traversal PM's)")
    shadow_rays: np.ndarray = _count(
        "shadow rays traced (any-hit): Fragment PM (shade: set-up; light); Traversal PM (shadow); "
        "Intersection PM (ray loads); the crossbar (a ray record each)")
    shadow_hits: np.ndarray = _count("shadow rays that found an occluder: Fragment PM (light: flushes)")
    node_visits: np.ndarray = _count("eye and secondary rays' inner nodes entered: Traversal PM (rays)")
    leaves_crossed: np.ndarray = _count("... leaves on the rays' lists: Traversal PM (rays)")
    leaf_visits: np.ndarray = _count("... leaves tested before stopping: Traversal PM (rays: and flushes)")
    tri_tests: np.ndarray = _count(
        "... ray-triangle tests: Traversal PM (rays: FIFO pushes); Intersection PM (a triangle each)")
    shadow_node_visits: np.ndarray = _count("shadow rays' inner nodes entered: Traversal PM (shadow)")
    shadow_leaves_crossed: np.ndarray = _count("... leaves on their lists: Traversal PM (shadow)")
    shadow_leaf_visits: np.ndarray = _count("... leaves tested: Traversal PM (shadow: and flushes)")
    shadow_tri_tests: np.ndarray = _count(
        "... ray-triangle tests: Traversal PM (shadow: FIFO pushes); Intersection PM (a triangle each)")
    fragments: np.ndarray = _count("Lambertian points shaded: Fragment PM (shade: and flushes)")
    specular_bounces: np.ndarray = _count(
        "mirror reflections, refractions, total internal reflections: Fragment PM (shade)")
    trav_misses: np.ndarray = _count("page misses of the eye and secondary rays' node and leaf-index reads: "
                                     "Traversal PM (rays)")
    isect_misses: np.ndarray = _count("... of their triangle vertex reads: Intersection PM")
    shadow_trav_misses: np.ndarray = _count("the same for the shadow rays: Traversal PM (shadow)")
    shadow_isect_misses: np.ndarray = _count("... Intersection PM (shadow rays)")
    frag_misses: np.ndarray = _count("page misses of the shading records read per fragment: Fragment PM (shade)")


@_typed
class GatherWork(WorkArrays):
    """Per pixel (row-major, samples summed): the photon-map pass, ``pmap``.

    Its pixels with gathers run Fragment PM job ``gather`` (Fig. 8: the search list, the
    photons of its leaves, the filter), on both photon maps.
    """

    ITEM: ClassVar[str] = "pixel"

    gathers: np.ndarray = _count("radiance estimates made (Lambertian eye hits): Fragment PM (gather)")
    node_visits: np.ndarray = _count("photon BSP inner nodes on the search lists: Fragment PM (gather)")
    leaves_visited: np.ndarray = _count("photon BSP leaves searched: Fragment PM (gather: and flushes)")
    photons_tested: np.ndarray = _count("photons compared against the search radius: Fragment PM (gather)")
    photons_accepted: np.ndarray = _count("photons inside it that were filtered: Fragment PM (gather: and flushes)")
    gather_misses: np.ndarray = _count("page misses reading the searched leaves' photons: Fragment PM (gather)")


@_typed
class PhotonWork(WorkArrays):
    """Per emitted photon (emission order), all its bounces: the photon tracing of the pmap frame.

    The Vertex PM emits them (job ``photon_emit``); chunks of them are traced on every
    pipeline (Traversal PM job ``photons``, the Intersection PM) and their hits scattered
    and stored (Fragment PM job ``photons``).
    """

    ITEM: ClassVar[str] = "photon"

    photons_emitted: np.ndarray = _count("1 per photon: Vertex PM (photon_emit)")
    rays: np.ndarray = _count("rays traced, one per bounce: Traversal PM (photons); Intersection PM (ray loads)")
    node_visits: np.ndarray = _count("inner nodes entered: Traversal PM (photons)")
    leaves_crossed: np.ndarray = _count("leaves on the rays' lists: Traversal PM (photons)")
    leaf_visits: np.ndarray = _count("leaves tested: Traversal PM (photons: and flushes)")
    tri_tests: np.ndarray = _count(
        "ray-triangle tests: Traversal PM (photons: FIFO pushes); Intersection PM (a triangle each)")
    bounces: np.ndarray = _count("surface hits scattered: Fragment PM (photons); a photon with none skips it")
    stored: np.ndarray = _count(
        "photons stored: Fragment PM (photons: and flushes); the crossbar (a photon record each, back to "
        "pipeline 0 for the photon BSP)")
    absorbed: np.ndarray = _count("paths ended by Russian roulette: not charged by the default table")
    lost: np.ndarray = _count("rays that left the scene: not charged by the default table")
    trav_misses: np.ndarray = _count("page misses of the node and leaf-index reads: Traversal PM (photons)")
    isect_misses: np.ndarray = _count("page misses of the triangle vertex reads: Intersection PM (photons)")


@_typed
class BuildLevelWork(WorkArrays):
    """Per level of one BSP build (Algorithm 1; :class:`tlm.kernels.bsp.LevelWork`): the
    Vertex PM's job ``geometry_bsp`` or ``photon_bsp``, one packet per level."""

    ITEM: ClassVar[str] = "level"

    nodes: np.ndarray = _count("nodes of the level: Vertex PM (and flushes)")
    elements_in: np.ndarray = _count("elements of the level, read once by the centre-of-mass pass: Vertex PM")
    storage_reads: np.ndarray = _count("elements read by the left and right storage passes: Vertex PM")
    elements_out: np.ndarray = _count("elements written to P': Vertex PM")
    expansion_copies: np.ndarray = _count("triangles copied to both sides: Vertex PM")


LEVEL_FIELDS = BuildLevelWork.KEYS
PassWork = RayPassWork | GatherWork


def pass_work_class(name: str) -> type[RayPassWork] | type[GatherWork]:
    """The work class of the rendered pass ``name``."""
    if name == GATHER_PASS:
        return GatherWork
    if name in RAY_PASSES:
        return RayPassWork
    raise ValueError(f"unknown pass {name!r} (expected one of {(*RAY_PASSES, GATHER_PASS)})")


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
    def of(cls, res) -> Functional:
        """From a :class:`~tlm.experiments.run.RenderResult` (its work dicts converted strictly)."""
        traced = res.photons
        return cls(
            passes=tuple(res.plan.run_names), work={p: res.work[p] for p in res.plan.run_names},
            geometry=TreeWork.of(res.accel.tree),
            photon_work=None if traced is None else PhotonWork.from_mapping(traced.work, "photon work"),
            photon_tree=None if traced is None else TreeWork.of_maps(traced.photons),
            pixels=int(res.gbuffer.pixels.shape[0]), width=int(res.scene.camera.width),
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
            np.savez_compressed(fh, **arrays)

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
