"""The work that crosses from the render to the timing model, declared once.

Every kernel returns, with its results, the work the proposed hardware would do for it;
the timing model (:mod:`tlm.arch`) turns that work into cycles. This module is the one
place that says what that work is (after pbrt-v4's wavefront ``workitems.h``, where each
work item the kernels hand each other is declared once): one table of :class:`Item`
per kind of work, each item with what it counts and which units of the hardware charge
it, and the typed arrays that hold it, one frozen dataclass per kind (structures of
arrays: each field one count per pixel, photon or BSP level, an ``(items,)`` int64
array, or int32 where a render keeps counts that fit in it):

* :class:`RayPassWork`: per pixel, a ray pass (``rcast``, ``reflect``, ``refract``,
  and ``fgather``, the final-gather rays traced with the photon-map frame);
* :class:`GatherWork`: per pixel, the photon-map pass (``pmap``);
* :class:`PhotonWork`: per emitted photon, in emission order;
* :class:`BuildLevelWork`: per level of a BSP build (Algorithm 1; the fields of
  :class:`tlm.kernels.bsp.LevelWork`, checked at import);
* :data:`MODEL_ITEMS`: what the timing model counts itself per packet (``items``, the
  elements of a build, the sequential streams restarted), which a program table may
  price too.

Everything else derives from these tables: the render's key tuples
(:data:`WORK_KEYS`, :data:`GATHER_KEYS`, :data:`PHOTON_WORK`, which
:mod:`tlm.render.passes`, :mod:`tlm.render.pmap` and :mod:`tlm.kernels.photons` fill as dicts), the page-miss
keys and the address stream each charges (:data:`MISS_KEYS`, :func:`stream_keys`), the
work the timing model holds (:mod:`tlm.arch.functional` converts a render's dicts to
these classes strictly: a key missing or unknown is an error), and the check of a PM
program table (:func:`tlm.arch.costs.load_programs`: a job must price every item this
module says it charges, and may price only the items of the work it reads).

An item's ``charged`` names its units: ``"pm.job"`` for a job of a programmable PM
(priced by name in ``tlm/arch/programs.yaml``), ``"intersection"`` for the
fixed-function Intersection PM (ray loads, triangles, its page misses) and
``"crossbar"`` for records sent between pipelines. An item no unit charges says why
(``uncharged``).
"""

from __future__ import annotations

import inspect
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field, fields
from typing import ClassVar

import numpy as np

from tlm.kernels.bsp import LevelWork

FIXED_UNITS = ("intersection", "crossbar")  # the units an item may name besides the PM jobs


@dataclass(frozen=True)
class Item:
    """One work item: one count per pixel, photon or BSP level.

    ``charged``: the units that charge it (``"pm.job"``, ``"intersection"``,
    ``"crossbar"``); ``streams``: for a page-miss count, the kernels' address streams
    (:mod:`tlm.kernels.memory`) whose misses it counts; ``uncharged``: why no unit
    charges it (then ``charged`` is empty).
    """

    name: str
    doc: str
    charged: tuple[str, ...] = ()
    streams: tuple[str, ...] = ()
    uncharged: str = ""

    def __post_init__(self) -> None:
        if bool(self.charged) == bool(self.uncharged):
            raise ValueError(f"work item {self.name!r}: name the units that charge it, or say why none does")
        for unit in self.charged:
            pm, dot, job = unit.partition(".")
            if not (unit in FIXED_UNITS or (dot and pm and job)):
                raise ValueError(f"work item {self.name!r}: {unit!r} is no unit ('pm.job', {FIXED_UNITS})")

    @property
    def miss(self) -> bool:
        """A page-miss count (it depends on the accesses of the items before it)."""
        return bool(self.streams)


def _traversal(prefix: str, job: str, whose: str) -> tuple[Item, ...]:
    """The four counts of a traversal by Traversal PM job ``job`` (keys ``prefix + ...``)."""
    pm = f"traversal.{job}"
    return (
        Item(prefix + "node_visits", f"{whose}: inner nodes entered", (pm,)),
        Item(prefix + "leaves_crossed", f"{whose}: leaves on the rays' lists", (pm,)),
        Item(prefix + "leaf_visits", f"{whose}: leaves tested before stopping (each ends a loop: a flush)", (pm,)),
        Item(prefix + "tri_tests", f"{whose}: ray-triangle tests (FIFO pushes; a triangle each)", (pm, "intersection")),
    )


def _trace_misses(prefix: str, job: str, whose: str) -> tuple[Item, ...]:
    """The page misses of a traversal: its node and leaf-index reads, its triangle vertex reads."""
    return (
        Item(prefix + "trav_misses", f"{whose}: page misses of the node heap and leaf-index reads",
             (f"traversal.{job}",), streams=(prefix + "nodes", prefix + "indices")),
        Item(prefix + "isect_misses", f"{whose}: page misses of the triangle vertex reads",
             ("intersection",), streams=(prefix + "vertices",)),
    )


def _item_fields(items: tuple[Item, ...]):
    """Decorator: ``cls`` as a frozen dataclass with one ``np.ndarray`` field per item, in order."""

    def make(cls):
        names = [i.name for i in items]
        if len(set(names)) != len(names):
            raise ValueError(f"{cls.__name__}: an item is declared twice in {names}")
        cls.__annotations__ = {**inspect.get_annotations(cls), **dict.fromkeys(names, np.ndarray)}
        for i in items:
            setattr(cls, i.name, field(metadata={"doc": i.doc, "item": i}))
        cls = dataclass(frozen=True, eq=False, repr=False)(cls)
        cls.ITEMS = items
        cls.KEYS = tuple(f.name for f in fields(cls))
        return cls

    return make


class WorkArrays(Mapping):
    """Base of the typed work classes: equal-length ``(items,)`` int64 (or int32) arrays, one per item.

    Validated at construction (every field a 1-D int64 or int32 array, all of one length, no
    negative count); the arrays are stored as read-only views. Reads as a read-only
    mapping from item name to array (``KEYS`` in declaration order), as the program
    table prices work by name (``w["tri_tests"]``, ``w.items()``); the timing model
    reads its own fields as attributes.
    """

    ITEMS: ClassVar[tuple[Item, ...]] = ()
    KEYS: ClassVar[tuple[str, ...]] = ()
    ITEM: ClassVar[str] = "item"  # what one entry of the arrays is (for messages)

    def __post_init__(self) -> None:
        n = None
        for k in self.KEYS:
            v = getattr(self, k)
            where = f"{type(self).__name__}.{k}"
            if not isinstance(v, np.ndarray):
                raise ValueError(f"{where}: expected a numpy array, got {type(v).__name__}")
            if v.dtype not in (np.int64, np.int32) or v.ndim != 1:
                raise ValueError(f"{where}: expected a 1-D int64 or int32 array (one count per {self.ITEM}), "
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

        The keys must be exactly :attr:`KEYS`; int32 and int64 arrays are kept as they
        are (a render keeps per-pixel counts in int32 where they fit), other integer and
        boolean arrays are converted to int64. Whoever sums them widens to int64.
        """
        what = what or cls.__name__
        if isinstance(work, cls):
            return work
        missing = [k for k in cls.KEYS if k not in work]
        extra = [k for k in work if k not in cls.KEYS]
        if missing or extra:
            raise ValueError(f"{what}: the work keys differ from {cls.__name__}'s items (tlm.kernels.work)"
                             + (f"; missing {missing}" if missing else "")
                             + (f"; unknown {extra}" if extra else ""))
        arrays = {}
        for k in cls.KEYS:
            v = np.asarray(work[k])
            if v.dtype not in (np.int64, np.int32):
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

    # -- read-only mapping: item name -> array ------------------------------------------------
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


@_item_fields((
    Item("primary_rays", "eye rays traced (generated by the Traversal PM; each eye ray's result is a record of "
         "the Fragment PM's shade job)", ("traversal.rays", "intersection", "fragment.shade")),
    Item("secondary_rays", "reflected / refracted rays traced (a ray record each from the Fragment PM's module "
         "to the Traversal PM's)", ("traversal.rays", "intersection", "crossbar")),
    Item("shadow_rays", "shadow rays traced, any-hit (set up by the shade job, summed by the light job; a ray "
         "record each)", ("fragment.shade", "fragment.light", "traversal.shadow", "intersection", "crossbar")),
    Item("shadow_hits", "shadow rays that found an occluder (the light job's occluded branch)", ("fragment.light",)),
    *_traversal("", "rays", "eye and secondary rays"),
    *_traversal("shadow_", "shadow", "shadow rays (traced in a phase of their own, as the thesis's passes)"),
    Item("fragments", "Lambertian points shaded (the material branch)", ("fragment.shade",)),
    Item("specular_bounces", "mirror reflections, refractions, total internal reflections", ("fragment.shade",)),
    *_trace_misses("", "rays", "eye and secondary rays"),
    *_trace_misses("shadow_", "shadow", "shadow rays, on pairs of their own"),
    Item("frag_misses", "page misses of the shading records read per fragment", ("fragment.shade",),
         streams=("shading",)),
))
class RayPassWork(WorkArrays):
    """Per pixel (row-major, a pixel's samples summed): a ray pass, ``rcast``, ``reflect``,
    ``refract`` or ``fgather``.

    Its pixels with rays run the pass's ``rays`` phase (Traversal PM job ``rays``, then
    the Intersection PM, then Fragment PM job ``shade``); those with shadow rays its
    ``shadow`` phase (Traversal PM job ``shadow``, the Intersection PM, Fragment PM job
    ``light``). Per-item weights of the programmable PMs: ``programs.yaml``.
    """

    ITEM: ClassVar[str] = "pixel"


@_item_fields((
    Item("gathers", "radiance estimates made (Lambertian eye hits)", ("fragment.gather",)),
    Item("node_visits", "photon BSP inner nodes on the search lists (Fig. 8)", ("fragment.gather",)),
    Item("leaves_visited", "photon BSP leaves searched (each ends a loop: a flush)", ("fragment.gather",)),
    Item("photons_tested", "photons compared against the search radius", ("fragment.gather",)),
    Item("photons_accepted", "photons inside it, from the front, that were filtered (the power loaded and summed)",
         ("fragment.gather",)),
    Item("photons_weighted", "accepted photons whose filter computes a weight (the cone of eq. 3.3: mvoxel, kvoxel, "
         "knn; 0 for disk, eq. 3.2's weight 1)", ("fragment.gather",)),
    Item("gather_misses", "page misses reading the searched leaves' photons (0 for knn)", ("fragment.gather",),
         streams=("photons", "caustic_photons")),
))
class GatherWork(WorkArrays):
    """Per pixel (row-major, samples summed): the photon-map pass, ``pmap``.

    Its pixels with gathers run Fragment PM job ``gather`` (Fig. 8: the search list, the
    photons of its leaves, the filter), on both photon maps.
    """

    ITEM: ClassVar[str] = "pixel"


@_item_fields((
    Item("photons_emitted", "1 per photon (a point on the light, a direction, the power)", ("vertex.photon_emit",)),
    Item("rays", "rays traced, one per bounce", ("traversal.photons", "intersection")),
    *_traversal("", "photons", "photon rays"),
    Item("bounces", "surface hits scattered (a photon with none skips the Fragment PM)", ("fragment.photons",)),
    Item("stored", "photons stored (a photon record each, back to pipeline 0 for the photon BSP)",
         ("fragment.photons", "crossbar")),
    Item("absorbed", "paths ended by Russian roulette", uncharged="the roulette is part of every bounce's "
         "program (bounces); an absorbed path costs nothing more"),
    Item("lost", "rays that left the scene", uncharged="such a ray's traversal is in rays and the traversal "
         "counts; it has no hit to scatter"),
    *_trace_misses("", "photons", "photon rays"),
))
class PhotonWork(WorkArrays):
    """Per emitted photon (emission order), all its bounces: the photon tracing of the pmap frame.

    The Vertex PM emits them (job ``photon_emit``); chunks of them are traced on every
    pipeline (Traversal PM job ``photons``, the Intersection PM) and their hits scattered
    and stored (Fragment PM job ``photons``).
    """

    ITEM: ClassVar[str] = "photon"


_BUILDS = ("vertex.geometry_bsp", "vertex.photon_bsp")


@_item_fields((
    Item("nodes", "nodes of the level (the partition loop's exit: a flush each)", _BUILDS),
    Item("elements_in", "elements of the level, read once by the centre-of-mass pass", _BUILDS),
    Item("storage_reads", "elements read by the left and right storage passes", _BUILDS),
    Item("elements_out", "elements written to P'", _BUILDS),
    Item("expansion_copies", "triangles copied to both sides", _BUILDS),
))
class BuildLevelWork(WorkArrays):
    """Per level of one BSP build (Algorithm 1; :class:`tlm.kernels.bsp.LevelWork`): the
    Vertex PM's job ``geometry_bsp`` or ``photon_bsp``, one packet per level."""

    ITEM: ClassVar[str] = "level"


MODEL_ITEMS = (  # counted by the timing model per packet, not by the render
    Item("items", "pixels (or photons, or levels) in a packet: per-record loads and stores",
         ("fragment.shade", "fragment.light", "fragment.gather")),
    Item("elements", "elements of a BSP build's list, read once at its first level", _BUILDS),
    Item("stream_restarts", "sequential streams restarted (a page miss each): the Vertex PM's only misses",
         (*_BUILDS, "vertex.photon_emit")),
)

KINDS: tuple[type[WorkArrays], ...] = (RayPassWork, GatherWork, PhotonWork, BuildLevelWork)

# the rendered passes and their work (fgather: the final-gather rays, a ray pass traced with pmap)
PASS_WORK: dict[str, type[WorkArrays]] = {"rcast": RayPassWork, "reflect": RayPassWork, "refract": RayPassWork,
                                          "fgather": RayPassWork, "pmap": GatherWork}
RAY_PASSES = tuple(p for p, cls in PASS_WORK.items() if cls is RayPassWork)
GATHER_PASS = "pmap"

WORK_KEYS = RayPassWork.KEYS  # a ray pass's work dict (tlm.render.passes)
GATHER_KEYS = GatherWork.KEYS  # the photon-map pass's (``gathers`` first: the rest are per gather)
PHOTON_WORK = PhotonWork.KEYS  # the photon tracer's, per photon (tlm.kernels.photons)
LEVEL_FIELDS = BuildLevelWork.KEYS
# the keys that depend on the accesses before the pixel (the pairs' carried state): equal
# for a pixel only when the pixels before it ran too, in order, with one Streams
MISS_KEYS = tuple(i.name for cls in (RayPassWork, GatherWork) for i in cls.ITEMS if i.miss)


def stream_keys(cls: type[WorkArrays]) -> dict[str, str]:
    """Each address stream of ``cls``'s kernels and the work key its misses go to (streams
    sharing a pair, :data:`tlm.kernels.memory.PM_STREAMS`, always go to one key)."""
    return {s: i.name for i in cls.ITEMS for s in i.streams}


STREAM_KEYS = stream_keys(RayPassWork)  # the ray passes' streams (tlm.render.frame.charge charges them)


def pass_work_class(name: str) -> type[WorkArrays]:
    """The work class of the rendered pass ``name``."""
    if name not in PASS_WORK:
        raise ValueError(f"unknown pass {name!r} (expected one of {tuple(PASS_WORK)})")
    return PASS_WORK[name]


def job_items(unit: str) -> tuple[Item, ...]:
    """The items ``unit`` (``"pm.job"``, ``"intersection"``, ``"crossbar"``) charges, kinds in order."""
    return tuple(i for items in (*(c.ITEMS for c in KINDS), MODEL_ITEMS) for i in items if unit in i.charged)


def job_keys(unit: str) -> tuple[str, ...]:
    """What a program of ``unit`` may price: the keys of every kind one of whose items it
    charges (the work it reads), and the timing model's own (:data:`MODEL_ITEMS`)."""
    kinds = [c for c in KINDS if any(unit in i.charged for i in c.ITEMS)]
    return tuple(dict.fromkeys((*(k for c in kinds for k in c.KEYS), *(i.name for i in MODEL_ITEMS))))


def units() -> tuple[str, ...]:
    """Every unit some item names, in order of first mention."""
    return tuple(dict.fromkeys(u for items in (*(c.ITEMS for c in KINDS), MODEL_ITEMS) for i in items
                               for u in i.charged))


def _check_levels() -> None:
    """:class:`BuildLevelWork` holds exactly the per-level counts of the BSP builder."""
    per_level = tuple(f.name for f in fields(LevelWork) if f.name != "level")
    if per_level != LEVEL_FIELDS:
        raise ImportError(f"tlm.kernels.work: BuildLevelWork's items {LEVEL_FIELDS} are not "
                          f"tlm.kernels.bsp.LevelWork's counts {per_level}")


_check_levels()
