"""The frame program: what each PM of each pipeline runs for one frame, in packets.

The reconstruction of the thesis's Figs. 13 and 14 (``docs/architecture.md``). A frame
is a sequence of :class:`Stage` s. A *shared* stage runs on pipeline 0 alone: the one
Vertex PM builds the geometry BSP and emits photons, and later builds the photon BSP
(§V.D: "the initial geometry/photon list are partitioned via a single Vertex PM"). A
*tiled* stage runs on every pipeline: its work is cut into :class:`Tile` s (image tiles
for the ray and gather passes, chunks of the photon list for photon tracing); each
tile is a chain of *phases* run in order on one pipeline. A phase is one job (Vertex or
Fragment PM) or two coupled jobs (Traversal and Intersection PMs joined by the FIFO).

Copies between memory modules (the crossbar's work):

* ``Stage.fan_out``: before a tiled stage, what the shared stage produced on pipeline
  0 is copied into every pipeline's modules (the tree, the vertices, the photon tree);
  with one pipeline only the copies between the image's two modules remain.
* ``Stage.fan_in``: before a shared stage, each pipeline's results of the previous
  tiled stage (``Tile.returns``, the stored photons) go back to pipeline 0.
* ``PhaseSpec.copy_words``: within a tile, between the image's two modules of one
  pipeline (new rays from the Fragment PM's module to the Traversal PM's).
* With more than one pipeline, each finished tile's pixels go to the top-level unit
  that composes the image (``Tile.pixels``).

The static scheduler cuts the image into exactly ``pipelines`` tiles (quadrants for 4,
the most nearly square grid for any N) and gives tile i to pipeline i; the dynamic
one cuts ``tiles_per_pipeline`` x ``pipelines`` tiles into a shared queue from which a
pipeline that finished its tile takes the next. Every work item is in exactly one tile,
so the work (and the image) does not depend on the tiling.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from functools import cached_property
from itertools import pairwise

import numpy as np

from tlm.arch.costs import Programs
from tlm.arch.functional import RAY_PASSES, Functional, PhotonWork, RayPassWork, TreeWork, WorkArrays
from tlm.config import ArchConfig
from tlm.registry import SCHEDULERS

PMS = ("vertex", "traversal", "intersection", "fragment")
PM_TABLE_NAMES = {"vertex": "TVert", "traversal": "TTrav", "intersection": "Tisct", "fragment": "TFrag"}
WORDS_PER_RAY = 2  # a ray record: origin and direction, two 128-bit words
WORDS_PER_PHOTON = 2  # position and power (with the incoming direction packed)
WORDS_PER_HIT = 2  # a hit record: t, triangle, barycentrics, pixel
WORDS_PER_PIXEL = 1  # a composed pixel: RGB in one 128-bit word


@dataclass(frozen=True)
class JobSpec:
    """One PM's part of a phase, in packets (all arrays (packets,) int64)."""

    pm: str
    kind: str  # program entry (vertex: geometry_bsp, ...; intersection: the phase's ray kind)
    role: int  # 0: the image's first module (tree, rays), 1: its second (vertices, hits)
    norm: np.ndarray
    misses: np.ndarray
    flushes: np.ndarray
    items: np.ndarray  # work items retired per packet (pixels, photons, rays, levels)
    entries: np.ndarray | None = None  # FIFO entries pushed (traversal) or popped (intersection)

    @property
    def n(self) -> int:
        return int(self.items.shape[0])

    @cached_property
    def packets(self) -> list[tuple[int, int, int, int, int | None]]:
        """Per packet (norm, misses, flushes, items, entries) as Python ints (entries None without them).

        The timing model's hot loop reads these, not the arrays: a list of ints is much
        cheaper to index than numpy scalars. (Computed once: the arrays are not changed.)
        """
        n = self.n
        cols = [_python_ints(a, n) for a in (self.norm, self.misses, self.flushes, self.items)]
        entries = [None] * n if self.entries is None else _python_ints(self.entries, n)
        return list(zip(*cols, entries, strict=True))


def _python_ints(a, n: int) -> list[int]:
    """The first ``n`` values of ``a`` as Python ints (an integer array's ``tolist`` gives them)."""
    values = np.asarray(a)[:n]
    return values.tolist() if np.issubdtype(values.dtype, np.integer) else list(map(int, values.tolist()))


@dataclass(frozen=True)
class PhaseSpec:
    name: str
    jobs: tuple[JobSpec, ...]
    copy_words: int  # words the crossbar copies between the image's modules before the phase
    copy_to: int | None = None  # the role the copy goes to (None: the role of the phase's first job)


@dataclass(frozen=True)
class Tile:
    """A chain of phases that one pipeline runs in order."""

    name: str
    phases: tuple[PhaseSpec, ...]
    pixels: int = 0  # pixels it composes into the image (with more than one pipeline)
    returns: int = 0  # words copied back to pipeline 0 before the next shared stage


@dataclass(frozen=True)
class FanOut:
    """Words produced on pipeline 0's module ``src_role``, needed on every pipeline's ``dst_role``."""

    what: str
    words: int
    src_role: int
    dst_role: int


@dataclass(frozen=True)
class Stage:
    name: str
    shared: bool  # pipeline 0 alone (one tile), else tiles over all pipelines
    tiles: tuple[Tile, ...]
    fan_out: tuple[FanOut, ...] = ()
    fan_in_role: int = 0  # where the previous stage's ``Tile.returns`` go on pipeline 0


@dataclass(frozen=True)
class FrameProgram:
    """One frame's stages, and the pipelines and the scheduler its tiles were cut for.

    The model reads the pipelines and the scheduler here, never in the arch config: a
    static program has one tile per pipeline, and its tiles only make sense on them.
    """

    stages: tuple[Stage, ...]
    left_out: dict[str, str]  # what was not built, and why
    pipelines: int = 1  # pipelines that run the tiled stages (the model builds their PMs and modules)
    scheduler: str = "static"  # the registered scheduler that hands the tiles to them (tlm.registry.SCHEDULERS)
    tiling: dict = field(default_factory=dict)  # rows, cols and tile bounds of the image tiles

    @classmethod
    def linear(cls, phases, left_out: dict[str, str] | None = None) -> FrameProgram:
        """One pipeline running ``phases`` in order (hand-built programs in tests)."""
        return cls((Stage("frame", True, (Tile("frame", tuple(phases)),)),), dict(left_out or {}))

    @property
    def phases(self) -> tuple[PhaseSpec, ...]:
        """Every phase of every tile, in program order."""
        return tuple(ph for st in self.stages for t in st.tiles for ph in t.phases)


# -- packets ---------------------------------------------------------------------------------

@dataclass(frozen=True)
class Packets:
    """Work cut into packets: consecutive runs of ``packet_size`` items in row-major order
    (pixels; photons in emission order), the last one possibly short.

    sizes : (packets,) int64, items per packet.
    counts : work key -> (packets,) int64, the packet's summed work.
    """

    name: str
    packet_size: int
    sizes: np.ndarray
    counts: dict[str, np.ndarray]

    @property
    def n(self) -> int:
        return int(self.sizes.shape[0])


def split(name: str, work: Mapping[str, np.ndarray], packet_size: int) -> Packets:
    """Cut per-item work (arrays of any shape, read row-major) into packets.

    The seam's promise (docs/design.md, "Two layers, one seam"): every kernel gives the
    same per-ray and per-pixel results and counts whatever packet it runs on, so a
    packet's counts are the sums of its items' counts in the whole-image run, and the
    timing model cuts the work into packets of any size after the kernels ran once.
    ``work``: a render's dict, or one of the seam's typed work classes
    (:class:`~tlm.arch.functional.RayPassWork`, ..., which read as mappings).
    """
    _check_packet_size(packet_size)
    flat = {k: np.asarray(v).reshape(-1) for k, v in work.items()}
    n = next(iter(flat.values())).shape[0] if flat else 0
    if any(v.shape[0] != n for v in flat.values()):
        raise ValueError(f"work arrays of {name!r} differ in length")
    starts, sizes = _starts_and_sizes(n, packet_size)
    counts = {}
    for k, v in flat.items():
        # integer sums in item order: exact, and the same as summing each packet alone (packets of one: the
        # items themselves, without reduceat's cost per packet)
        if packet_size == 1:
            counts[k] = v.astype(np.int64)
        else:
            counts[k] = np.add.reduceat(v.astype(np.int64, copy=False), starts) if n else np.zeros(0, np.int64)
    return Packets(name, int(packet_size), sizes, counts)


def _check_packet_size(packet_size) -> None:
    if isinstance(packet_size, bool) or not isinstance(packet_size, (int, np.integer)) or packet_size < 1:
        raise ValueError(f"packet_size (={packet_size!r}) must be a whole number >= 1")


def _starts_and_sizes(n: int, packet_size: int) -> tuple[np.ndarray, np.ndarray]:
    """The first item of each packet of ``n`` items and its items (the last packet possibly short), int64."""
    starts = np.arange(0, n, packet_size, dtype=np.int64)
    return starts, np.diff(np.append(starts, n)).astype(np.int64)


# -- tiling ----------------------------------------------------------------------------------

def grid_shape(n: int, width: int, height: int) -> tuple[int, int]:
    """Rows and columns of ``n`` tiles, the factorisation whose tiles are most nearly square."""
    best, best_cost = (1, n), math.inf
    for rows in range(1, n + 1):
        if n % rows:
            continue
        cols = n // rows
        cost = abs(math.log((max(height, 1) / rows) / (max(width, 1) / cols)))
        if cost < best_cost - 1e-12:
            best, best_cost = (rows, cols), cost
    return best


def _edges(total: int, parts: int) -> np.ndarray:
    return (np.arange(parts + 1, dtype=np.int64) * total) // parts


def image_tiles(width: int, height: int, n: int) -> tuple[list[np.ndarray], dict]:
    """``n`` rectangular tiles covering the image: each tile's pixel indices, row-major."""
    rows, cols = grid_shape(n, width, height)
    ry, cx = _edges(height, rows), _edges(width, cols)
    tiles, bounds = [], []
    for r in range(rows):
        for c in range(cols):
            ys = np.arange(ry[r], ry[r + 1], dtype=np.int64)
            xs = np.arange(cx[c], cx[c + 1], dtype=np.int64)
            tiles.append((ys[:, None] * width + xs[None, :]).reshape(-1))
            bounds.append([int(cx[c]), int(ry[r]), int(cx[c + 1]), int(ry[r + 1])])
    return tiles, {"rows": rows, "cols": cols, "tiles": bounds}


# -- phase builders --------------------------------------------------------------------------

def _level_packets(tw: TreeWork) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """A BSP build cut into one packet per level."""
    n = tw.n_levels
    counts = {k: v.astype(np.int64) for k, v in tw.levels.as_dict().items()}
    elements = np.zeros(n, dtype=np.int64)
    restarts = np.full(n, 3, dtype=np.int64)  # per level: read P twice, write P'
    if n:
        elements[0] = tw.n_elements
        restarts[0] += 1  # the element list itself
    else:  # a tree of 0 levels still reads its elements once
        elements = np.array([tw.n_elements], dtype=np.int64)
        restarts = np.array([1], dtype=np.int64)
        counts = {k: np.zeros(1, dtype=np.int64) for k in counts}
        counts["nodes"][:] = 1
    counts["elements"] = elements
    counts["stream_restarts"] = restarts
    return counts, np.ones(elements.shape[0], dtype=np.int64)


def _programmable(programs: Programs, pm: str, kind: str, role: int, counts: dict[str, np.ndarray],
                  items: np.ndarray, entries: np.ndarray | None = None) -> JobSpec:
    norm, flushes, misses = programs.cost(pm, kind, counts, items)
    return JobSpec(pm, kind, role, norm, misses, flushes, items, entries)


def _intersection(programs: Programs, kind: str, rays: np.ndarray, tris: np.ndarray,
                  misses: np.ndarray) -> JobSpec:
    fx = programs.intersection
    norm = fx["ray_load_cycles"] * rays + fx["triangle_cycles"] * tris
    if norm.shape[0]:
        norm = norm.copy()
        norm[-1] += fx["stages"] * fx["triangle_cycles"]  # the pipeline drains at the job's end
    return JobSpec("intersection", kind, 1, norm.astype(np.int64), misses.astype(np.int64),
                   np.zeros_like(rays), rays.astype(np.int64), tris.astype(np.int64))


@dataclass(frozen=True)
class TraceFields:
    """Which work fields a traversal + intersection phase reads for the fixed-function
    Intersection PM (the Traversal PM's job is priced by name, ``programs.yaml``)."""

    rays: tuple[str, ...]  # rays loaded (ray_load_cycles each)
    tris: str  # triangles tested (triangle_cycles each): the FIFO's entries
    isect_misses: str  # the Intersection PM's page misses


RAY_TRACE = TraceFields(("primary_rays", "secondary_rays"), "tri_tests", "isect_misses")  # RayPassWork
SHADOW_TRACE = TraceFields(("shadow_rays",), "shadow_tri_tests", "shadow_isect_misses")  # RayPassWork
PHOTON_TRACE = TraceFields(("rays",), "tri_tests", "isect_misses")  # PhotonWork


class _PacketSums:
    """``split("sub", {k: v[idx] for k, v in work.items()}, packet_size).counts``, read with ``get``.

    Each key is gathered and summed per packet when it is first asked for: a phase's
    costs read a few of the many work keys.
    """

    def __init__(self, work: WorkArrays, idx: np.ndarray, packet_size: int, starts: np.ndarray | None = None):
        self.work, self.idx = work, idx
        self.ones = packet_size == 1  # packets of one: the sums are the items' own values
        self.starts = _starts_and_sizes(int(idx.shape[0]), packet_size)[0] if starts is None else starts
        self.sums: dict[str, np.ndarray] = {}

    def get(self, key: str, default=None):
        got = self.sums.get(key)
        if got is None:
            v = self.work.get(key)
            if v is None:
                return default
            flat = np.asarray(v[self.idx]).reshape(-1)
            if flat.shape[0] != self.idx.shape[0]:
                raise ValueError("work arrays of 'sub' differ in length")
            # (no copy of an int64 gather: a second array of the selection's size costs more than the sums)
            if self.ones:  # (the gather is a new array: nothing else holds it)
                got = flat.astype(np.int64, copy=False)
            else:
                got = np.add.reduceat(flat.astype(np.int64, copy=False), self.starts) if flat.shape[0] \
                    else np.zeros(0, np.int64)
            self.sums[key] = got
        return got


class _Builder:
    """Builds phases over a selection of pixels or photons (a tile's ray buffer)."""

    def __init__(self, fn: Functional, programs: Programs, arch: ArchConfig):
        self.fn, self.programs, self.arch = fn, programs, arch
        g = fn.geometry
        self.tree_words = g.nodes + -(-g.slots // 4)  # nodes, and the leaves' triangle indices (4 per word)
        self.vertex_words = 3 * g.slots
        self.copy_mode = arch.memory == "copy"

    def packets(self, work: WorkArrays, idx: np.ndarray):
        """The work of items ``idx`` in packets: (its counts, lazily per key, as ``split`` gives them; sizes)."""
        size = self.arch.packet_size
        _check_packet_size(size)
        starts, sizes = _starts_and_sizes(int(idx.shape[0]), size)
        return _PacketSums(work, idx, size, starts), sizes

    def ti(self, name: str, t_kind: str, work: WorkArrays, idx: np.ndarray, trace: TraceFields,
           copy_words: int, copy_to: int | None = None) -> PhaseSpec:
        counts, items = self.packets(work, idx)
        zero = np.zeros(items.shape[0], dtype=np.int64)
        rays = sum((counts.get(k, zero) for k in trace.rays), zero)
        tris = counts.get(trace.tris, zero)
        t = _programmable(self.programs, "traversal", t_kind, 0, counts, items, tris)
        i = _intersection(self.programs, t_kind, rays, tris, counts.get(trace.isect_misses, zero))
        if self.copy_mode:
            copy_words += self.tree_words + self.vertex_words
        return PhaseSpec(name, (t, i), copy_words, copy_to)

    def f(self, name: str, kind: str, work: WorkArrays, idx: np.ndarray) -> PhaseSpec:
        counts, items = self.packets(work, idx)
        copy_words = WORDS_PER_HIT * int(items.sum()) if self.copy_mode else 0
        return PhaseSpec(name, (_programmable(self.programs, "fragment", kind, 1, counts, items),), copy_words)

    def pixel_tile(self, idx: np.ndarray, passes: list[str], with_gather: bool) -> list[PhaseSpec]:
        """The ray passes and the gather of the pixels ``idx`` (row-major)."""
        return list(self.pixel_phases(idx, passes, with_gather))

    def pixel_phases(self, idx: np.ndarray, passes: list[str], with_gather: bool,
                     ti_only: bool = False) -> Iterator[PhaseSpec]:
        """:meth:`pixel_tile`'s phases, each built when it is asked for; with ``ti_only``
        its Traversal/Intersection phases alone (no other phase is built)."""
        for name in passes:
            w: RayPassWork = self.fn.ray_work(name)
            rays = w.primary_rays[idx] + w.secondary_rays[idx]
            sel = idx[rays > 0]
            del rays
            if not sel.size:
                continue
            # a secondary pass receives the Fragment PM's new rays (towards the Traversal PM's module)
            yield self.ti(f"{name}.rays", "rays", w, sel, RAY_TRACE,
                          WORDS_PER_RAY * int(w.secondary_rays[sel].sum()), 0)
            if not ti_only:
                yield self.f(f"{name}.shade", "shade", w, sel)
            ssel = idx[w.shadow_rays[idx] > 0]
            if ssel.size:
                yield self.ti(f"{name}.shadow", "shadow", w, ssel, SHADOW_TRACE,
                              WORDS_PER_RAY * int(w.shadow_rays[ssel].sum()))
                if not ti_only:
                    yield self.f(f"{name}.light", "light", w, ssel)
        g = self.fn.gather_work if with_gather and not ti_only else None
        if g is not None:
            gsel = idx[g.gathers[idx] > 0]
            if gsel.size:
                yield self.f("pmap.gather", "gather", g, gsel)

    def photon_chunk(self, idx: np.ndarray) -> tuple[list[PhaseSpec], int]:
        pw: PhotonWork = self.fn.photon_work
        phases = [self.photon_trace(idx)]
        stored_sel = idx[pw.bounces[idx] > 0]
        if stored_sel.size:
            phases.append(self.f("photons.store", "photons", pw, stored_sel))
        return phases, WORDS_PER_PHOTON * int(pw.stored[idx].sum())

    def photon_trace(self, idx: np.ndarray) -> PhaseSpec:
        """The Traversal/Intersection phase of the photons ``idx`` (a chunk of the photon list)."""
        return self.ti("photons.trace", "photons", self.fn.photon_work, idx, PHOTON_TRACE, 0)


def _ray_passes(fn: Functional, left_out: dict[str, str]) -> list[str]:
    """The ray passes of the frame program, in order; what it leaves out, and why, into ``left_out``."""
    passes = []
    for name in RAY_PASSES:
        if name not in fn.passes:
            left_out[f"{name} frames"] = "the plan does not render this pass"
            continue
        w = fn.ray_work(name)
        if not (w.primary_rays + w.secondary_rays).any():
            left_out[f"{name} frames"] = "no ray of this pass: no eye path meets its material"
            continue
        passes.append(name)
        if not w.shadow_rays.any():
            left_out[f"{name} shadow frames"] = "no shadow ray (no light, or no Lambertian hit)"
    return passes


def _with_pmap(fn: Functional) -> bool:
    """Whether the frame has the photon stages (a photon-map pass, its photons and their tree)."""
    return fn.gather_work is not None and fn.photon_work is not None and fn.photon_tree is not None


def _photon_chunks(n: int, n_tiles: int) -> list[np.ndarray]:
    """The photon list cut into ``n_tiles`` chunks (the photon stage's tiles), in order."""
    edges = _edges(n, n_tiles)
    return [np.arange(lo, hi, dtype=np.int64) for lo, hi in pairwise(edges)]


def ti_phases(fn: Functional, programs: Programs, arch: ArchConfig) -> Iterator[Iterator[PhaseSpec]]:
    """Per tile of ``frame_program(fn, programs, arch)``'s tiled stages, in program order:
    its Traversal/Intersection phases, the same :class:`PhaseSpec` s, each built when it is
    asked for; no other phase, and no shared stage, is built (what the coarse-packet
    estimate reads of the program in packets of one: ``tlm.arch.granularity.fine_ti_cycles``)."""
    b = _Builder(fn, programs, arch)
    n_tiles = SCHEDULERS[arch.scheduler]().tiles(arch)
    passes = _ray_passes(fn, {})
    if _with_pmap(fn):
        for idx in _photon_chunks(fn.photon_work.n, n_tiles):
            yield iter((b.photon_trace(idx),) if idx.size else ())
    tiles_idx, _ = image_tiles(fn.width, fn.height, n_tiles)
    for idx in tiles_idx:
        yield b.pixel_phases(idx, passes, False, ti_only=True)


def frame_program(fn: Functional, programs: Programs, arch: ArchConfig) -> FrameProgram:
    """The stages of one frame, in the order the control unit runs them."""
    b = _Builder(fn, programs, arch)
    n_pipes = arch.pipelines
    n_tiles = SCHEDULERS[arch.scheduler]().tiles(arch)
    left_out: dict[str, str] = {}
    if n_pipes > 1:
        left_out["vertex PMs of pipelines 1.." + str(n_pipes - 1)] = (
            "one Vertex PM builds the shared structures for every pipeline (§V.D)")
    stages: list[Stage] = []

    counts, items = _level_packets(fn.geometry)
    shared = [PhaseSpec("geometry", (_programmable(programs, "vertex", "geometry_bsp", 0, counts, items),), 0)]
    # every pipeline's Traversal PM reads the tree, its Intersection PM the vertices
    geometry_out = (FanOut("tree", b.tree_words, 0, 0), FanOut("vertices", b.vertex_words, 0, 1))

    passes = _ray_passes(fn, left_out)

    with_pmap = _with_pmap(fn)
    pixel_out = geometry_out
    if with_pmap:
        pw = fn.photon_work
        n = pw.n
        emit = split("emit", {"photons_emitted": pw.photons_emitted}, arch.packet_size)
        emit_counts = dict(emit.counts)
        emit_counts["stream_restarts"] = np.zeros(emit.n, dtype=np.int64)
        if emit.n:
            emit_counts["stream_restarts"][0] = 1
        shared.append(PhaseSpec("photons.emit", (_programmable(programs, "vertex", "photon_emit", 0, emit_counts,
                                                               emit.sizes),), 0))
        stages.append(Stage("geometry", True, (Tile("geometry", tuple(shared)),)))
        tiles = []
        for i, idx in enumerate(_photon_chunks(n, n_tiles)):
            phases, returns = b.photon_chunk(idx) if idx.size else ([], 0)
            tiles.append(Tile(f"photons {i}", tuple(phases), 0, returns))
        stages.append(Stage("photons", False, tuple(tiles),
                            (*geometry_out, FanOut("photon rays", WORDS_PER_RAY * n, 0, 0))))
        counts, items = _level_packets(fn.photon_tree)
        bsp = PhaseSpec("photons.bsp", (_programmable(programs, "vertex", "photon_bsp", 0, counts, items),), 0)
        stages.append(Stage("photon tree", True, (Tile("photon tree", (bsp,)),), (), fan_in_role=0))
        # the gather reads the photon tree and its photons on the Fragment PM's module
        pixel_out = (FanOut("photon tree", WORDS_PER_PHOTON * fn.photon_tree.n_elements + fn.photon_tree.nodes,
                            0, 1),)
    else:
        left_out["photon programs, photon memory and photon tree"] = "the plan has no pmap pass"
        stages.append(Stage("geometry", True, (Tile("geometry", tuple(shared)),)))

    tiles_idx, tiling = image_tiles(fn.width, fn.height, n_tiles)
    tiles = []
    for i, idx in enumerate(tiles_idx):
        phases = b.pixel_tile(idx, passes, with_pmap)
        tiles.append(Tile(f"tile {i}", tuple(phases), int(idx.size) if n_pipes > 1 else 0))
    stages.append(Stage("pixels", False, tuple(tiles), pixel_out))
    return FrameProgram(tuple(stages), left_out, n_pipes, arch.scheduler, tiling)


__all__ = ["PMS", "PM_TABLE_NAMES", "FanOut", "FrameProgram", "JobSpec", "Packets", "PhaseSpec", "Stage", "Tile",
           "frame_program", "grid_shape", "image_tiles", "split", "ti_phases"]
