"""The Traversal PM's algorithm (§III.B.2): ordered leaf lists, then leaf-by-leaf tests.

"There are 3 directional bits associated with each ray R ... An array of leaf-voxels,
through which R passes, is constructed. The algorithm is similar to algorithm 2. The
directional bits direct the sorted voxel list such that the ray always traverses the
voxel nearer to the origin first. Once a minimum intersection point is found for a ray,
the current ray traversal loop is terminated and a new traversal list is loaded."

So a ray's work has two phases, both vectorized over all rays of a packet:

1. **Leaf list** (like Fig. 8's level-by-level node lists): starting from the root
   clipped to the ray's segment, every level replaces each (ray, node, t-interval) by
   the children the interval enters, near child first by the ray's direction bit on
   the level's axis. After the last level, each ray owns its crossed leaves in
   near-to-far order. Every (ray, inner node) pair formed is a node visit.
2. **Leaf loop**: the ray tests the triangles of its leaves in order and stops after
   the first leaf whose exit distance is not below the closest hit found so far
   (closest-hit), or at the first leaf with any hit (any-hit, for shadow rays).

Phase 2 of the numpy reference walk (:mod:`tlm.kernels.traverse_numpy`; the compiled
engine, :mod:`tlm.kernels._jit`, gives the same results) is evaluated leaf-major to keep
numpy vectors long: a batch of the next few leaves of every unfinished ray is grouped
by leaf, each leaf's triangles are tested against all its rays in one block, and the
sequential stopping rule is applied afterwards; tests beyond a ray's stopping leaf are
discarded and not counted. Results and counts are exactly those of the sequential loop,
for any packet of rays.

Zero direction components (+0.0 or -0.0, and subnormal ones, which are flushed to
zero where they enter) are handled explicitly: such a ray never
crosses a split plane on that axis and stays in the child that holds its origin (an
origin exactly on the plane belongs to the right child, as ``x >= split`` does in
Algorithm 1).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from tlm.kernels import threads
from tlm.kernels.bsp import BSPTree, build_triangle_tree
from tlm.kernels.engine import ENGINES, engine  # noqa: F401  (re-exported)
from tlm.kernels.engine import numba_available as _numba_available  # noqa: F401  (for tests)
from tlm.kernels.intersect import (
    EDGE_EPS,
    TriangleSoA,
    check,
    lossy32,
    scale_directions,
    unscale_t,
)
from tlm.kernels.traverse_numpy import _clip_root, _loop_numpy


@dataclass(frozen=True)
class TriangleAccel:
    """A triangle BSP and its leaf-ordered triangle constants (the Traversal PM's memory).

    ``soa`` (float32, the test datapath) and ``soa64`` (float64, exact hit values)
    hold one slot per (leaf, triangle) entry, in ``tree.items`` order, so a leaf
    ``k``'s triangles are slots ``leaf_first[k]:leaf_last[k]``. Vertices are stored
    relative to ``origin``, the centre of the root box.

    Both are computed from ``triangles`` (the scene's array, not a copy: a scene is
    never changed in place) on first use and kept: the numpy engine reads them. The
    compiled engine reads only its own padded copy (:attr:`jit_layout`), which is built
    from the triangles without keeping them, so a frame rendered by it holds the
    constants once (a slot is about 200 bytes there, not 450).
    """

    tree: BSPTree
    triangles: np.ndarray  # (n, 3, 3) float64, the scene's (not copied)
    origin: np.ndarray  # (3,) float64: the centre of the root box
    leaf_first: np.ndarray
    leaf_last: np.ndarray
    n_triangles: int
    scale: float  # length of the root box diagonal (for relative epsilons)

    @property
    def leaf_size(self) -> np.ndarray:
        return self.leaf_last - self.leaf_first

    def constants(self, dtype: type = np.float64) -> TriangleSoA:
        """The leaf-ordered constants in ``dtype`` (computed anew: :attr:`soa` and
        :attr:`soa64` keep theirs)."""
        cached = self.__dict__.get("soa64" if np.dtype(dtype) == np.float64 else "soa")
        if cached is not None:
            return cached
        return TriangleSoA.from_triangles(self.triangles, origin=self.origin, dtype=dtype).take(self.tree.items)

    @functools.cached_property
    def soa(self) -> TriangleSoA:
        """float32 constants (the test datapath), one per slot."""
        return self.constants(np.float32)

    @functools.cached_property
    def soa64(self) -> TriangleSoA:
        """float64 constants (exact hit values), one per slot."""
        return self.constants(np.float64)

    @functools.cached_property
    def jit_layout(self):
        """The compiled kernel's padded copy of the constants (built on first use)."""
        from tlm.kernels import _jit

        return _jit.layout(self)

    def prepare(self) -> TriangleAccel:
        """Build what the selected engine reads (:attr:`jit_layout`, or :attr:`soa` and
        :attr:`soa64`) now, by one thread (the caller's, or a worker's: the photon trace
        builds it while it emits), before threads trace at once (a ``cached_property`` is
        not built under a lock: two threads could each build it)."""
        if engine() == "numba":
            self.jit_layout  # noqa: B018
        else:
            self.soa, self.soa64  # noqa: B018
        return self


def build_accel(
    triangles: np.ndarray, levels: int | None = None, memory_factor: float = 20.0
) -> TriangleAccel:
    """Build the triangle BSP (Algorithm 1 + expansion) and the per-slot constants."""
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    tree = build_triangle_tree(tri, levels=levels, memory_factor=memory_factor)
    centre = 0.5 * (tree.lo[0] + tree.hi[0])
    first, last = tree.leaf_ranges()
    scale = float(np.linalg.norm(tree.hi[0] - tree.lo[0]))
    return TriangleAccel(tree, tri, centre, first.copy(), last.copy(), tri.shape[0], scale)


@dataclass(frozen=True)
class Counts:
    """Per-ray work of the Traversal and Intersection PMs, each (r,) int64.

    node_visits : inner nodes entered while building the leaf list.
    leaves_crossed : leaves on the ray's list (its segment crosses them).
    leaf_visits : leaves whose triangles were tested before the loop stopped.
    tri_tests : triangles tested (sum of the sizes of the visited leaves).
    """

    node_visits: np.ndarray
    leaves_crossed: np.ndarray
    leaf_visits: np.ndarray
    tri_tests: np.ndarray

    def totals(self) -> dict[str, int]:
        return {
            "rays": int(self.node_visits.shape[0]),
            "node_visits": int(self.node_visits.sum()),
            "leaves_crossed": int(self.leaves_crossed.sum()),
            "leaf_visits": int(self.leaf_visits.sum()),
            "tri_tests": int(self.tri_tests.sum()),
        }


@dataclass(frozen=True)
class Touched:
    """Memory a packet touched, in visiting order, as CSR lists per ray.

    Ray ``i`` entered inner nodes ``node_ids[node_ptr[i]:node_ptr[i+1]]`` (heap indices,
    int32 unless the tree has more nodes; level by level, near first) and tested the
    leaves ``leaf_ids[leaf_ptr[i]:leaf_ptr[i+1]]``
    (leaf numbers, 0-based; heap index = leaf + ``tree.leaf_offset``), that is the
    triangle slots ``leaf_first[leaf]:leaf_last[leaf]`` of each.
    """

    node_ptr: np.ndarray
    node_ids: np.ndarray
    leaf_ptr: np.ndarray
    leaf_ids: np.ndarray


@dataclass(frozen=True)
class Hits:
    """Closest hits: ``t`` (inf on a miss), ``triangle`` (-1 on a miss), ``u``, ``v``."""

    t: np.ndarray
    triangle: np.ndarray
    u: np.ndarray
    v: np.ndarray
    counts: Counts
    touched: Touched | None = None


@dataclass(frozen=True)
class Occlusion:
    """Any-hit answers: ``occluded`` (r,) bool."""

    occluded: np.ndarray
    counts: Counts
    touched: Touched | None = None


def _rows3(a) -> np.ndarray:
    """``a`` as a contiguous (r, 3) float64 array (itself where it already is one)."""
    if type(a) is np.ndarray and a.dtype == np.float64 and a.ndim == 2 and a.shape[1] == 3 and a.flags.c_contiguous:
        return a
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64).reshape(-1, 3))


_TINY = float(np.finfo(np.float64).tiny)


def _prepare(origins, directions, tmin, tmax, ignore, compiled_engine=None):
    """The rays as the traversal reads them: ``o, d, tmin, tmax, ignore, scale``
    (``compiled_engine``: whether the numba engine runs, when the caller knows)."""
    o = _rows3(origins)
    d = _rows3(directions)
    r = o.shape[0]
    if d.shape[0] != r:
        raise ValueError(f"origins ({r}) and directions ({d.shape[0]}) differ in length")
    tmin, tmax = np.asarray(tmin, dtype=np.float64), np.asarray(tmax, dtype=np.float64)
    if tmin.ndim == 0:  # (one value for every ray: filled, not broadcast and copied)
        tmin = _filled(r, np.maximum(tmin, 0.0), np.float64)
    else:
        tmin = np.maximum(np.broadcast_to(tmin, (r,)), 0.0)
    tmax = _filled(r, tmax, np.float64) if tmax.ndim == 0 else _per_ray(tmax, r)
    # every row's largest component in [2**-32, 2**32] (its sum of three, rounded, at
    # least 2**-30): no row is rescaled, and the row maxima need not be formed; and
    # whether a component is subnormal (or zero). Compiled: one pass, no temporaries
    compiled = r > 0 and (engine() == "numba" if compiled_engine is None else compiled_engine)
    mag = None  # (the magnitudes, where numpy formed them)
    if compiled:
        plain, any_tiny = _compiled()[1].direction_checks(d)
    else:
        mag = np.abs(d)
        with np.errstate(invalid="ignore"):
            plain = r > 0 and mag.max() < 2.0**32 and (mag[:, 0] + mag[:, 1] + mag[:, 2]).min() >= 2.0**-30
    if plain:
        scale = np.zeros(r, dtype=np.intc)
    else:
        d, tmin, tmax, scale = scale_directions(d, tmin, tmax)
        mag = np.abs(d)
    if mag is not None:
        any_tiny = bool((mag < _TINY).any())
    if any_tiny:  # a subnormal component (negligible beside the row's largest) is a zero
        d = np.where(np.abs(d) < _TINY, 0.0, d)
    if ignore is None:
        ignore = _filled(r, -1, np.int64)
    else:
        ignore = _per_ray(np.asarray(ignore, dtype=np.int64), r)
    return o, d, tmin, tmax, ignore, scale


def _filled(r: int, value, dtype) -> np.ndarray:
    """``np.full(r, value, dtype)`` without its Python layers."""
    out = np.empty(r, dtype=dtype)
    out.fill(value)
    return out


def _per_ray(a: np.ndarray, r: int) -> np.ndarray:
    """``a`` as one contiguous value per ray: itself where it already is (read, never
    written, by the kernels; a broadcast view would be read-only, which the compiled
    engine copies), else broadcast to ``(r,)`` and copied."""
    if a.shape == (r,):
        return np.ascontiguousarray(a)
    return np.ascontiguousarray(np.broadcast_to(a, (r,)))


def _same_rows(o: np.ndarray) -> bool:
    """``(o == o[:1]).all()`` (compiled under the numba engine: one pass, stopping early)."""
    if engine() == "numba":
        return bool(_compiled()[1].same_rows(o))
    return bool((o == o[:1]).all())


# the compiled kernel's starting buffers: the widest level list (entries), and the
# visited leaves and entered nodes per ray (or what earlier calls on the accel needed,
# _learn); one that overflows is doubled and the packet rerun
JIT_BUFFERS = (1 << 12, 8, 16)


# rays per chunk at the least when a packet is split between threads (a chunk's call
# allocates its buffers: shorter chunks would spend more time there than tracing)
JIT_MIN_CHUNK = 2048


_KERNELS: dict = {}  # the compiled kernel, imported once (an import statement per call holds the lock)


def _compiled() -> tuple:
    """:mod:`tlm.kernels._jit_glue` and :mod:`tlm.kernels._jit_rays`, imported once."""
    mods = _KERNELS.get("glue")
    if mods is None:
        from tlm.kernels import _jit_glue, _jit_rays

        mods = _KERNELS["glue"] = (_jit_glue, _jit_rays)
    return mods


def _jit_trace(*args):
    fn = _KERNELS.get("trace")
    if fn is None:
        from tlm.kernels import _jit

        fn = _KERNELS["trace"] = _jit.trace
    return fn(*args)


def _jit_chunk(accel: TriangleAccel, o, d, tmin, tmax, ignore, has_ignore, shared_o32, pre, record, first_only,
               shared_origin, a: int, b: int):
    """The compiled kernel on rays ``a:b`` (its buffers grown until they hold them):
    ``t, u, v, slot, node_visits, cnt, leaf_visits, tri_tests, node_ids, leaf_ids``."""
    tree_args, eps_args = _jit_constants(accel)
    widest, leaves, nodes = JIT_BUFFERS
    learned = accel.__dict__.get("_jit_per_ray") if record else None  # (leaves, nodes) a ray took before
    if learned is not None:
        leaves, nodes = max(leaves, learned[0]), max(nodes, learned[1])
    r = b - a
    caps = [min(1 << tree_args[4], widest), leaves * r + 1, nodes * r + 1]
    while True:
        status, *out = _jit_trace(
            o[a:b], d[a:b], tmin[a:b], tmax[a:b], ignore[a:b], has_ignore, *tree_args, pre, *eps_args, first_only,
            shared_origin, shared_o32, record, *caps)
        if status == 0:  # (tlm.kernels._jit.OK; else the buffer that overflowed, 1 to 3)
            if record and r >= LEARN_MIN_RAYS:  # (the recorded lists hold every ray's leaves and nodes)
                _learn(accel, out[9].shape[0], out[8].shape[0], r)
            return out
        caps[status - 1] = max(2 * caps[status - 1], 1)  # a buffer was too small: rerun with it doubled


def _jit_constants(accel: TriangleAccel) -> tuple[tuple, tuple]:
    """What every call of the compiled kernel on ``accel`` passes alike, formed on the
    accel's first call and kept on it (one assignment: threads see it whole; two that
    form it at once form the same): the tree's and the layout's arrays (``levels`` 5th),
    and the edge epsilons. Kept with the tree and layout they were formed from, and formed
    again where the accel now has others (a copy of it given another layout, as
    ``benchmarks/bench_raytrace.py``'s walk floor is)."""
    tree, lay = accel.tree, accel.jit_layout
    kept = accel.__dict__.get("_jit_constants")
    if kept is not None and kept[0] is tree and kept[1] is lay:
        return kept[2]
    eps32, eps64 = EDGE_EPS[np.dtype(np.float32)], EDGE_EPS[np.dtype(np.float64)]
    got = (
        (tree.lo[0], tree.hi[0], accel.origin, tree.split, tree.levels, tree.leaf_offset, lay.soa32, lay.first,
         lay.last, lay.back, lay.soa64, lay.ids, lay.size),
        (np.float32(eps32), eps32, eps64),
    )
    accel.__dict__["_jit_constants"] = (tree, lay, got)
    return got


LEARN_MIN_RAYS = 256  # a call of fewer rays (a tail, one pixel) says too little about the rest


def _learn(accel: TriangleAccel, leaves: int, nodes: int, r: int) -> None:
    """Keep on the accel the recorded leaves and nodes per ray a call of at least
    :data:`LEARN_MIN_RAYS` rays needed (with a quarter to spare; never less than
    before), so the next calls size their buffers for the scene's rays and seldom trace
    a chunk again (the long photon rays of a large scene overflowed the starting buffers
    three times a chunk). Only sizes: no result depends on them."""
    before = accel.__dict__.get("_jit_per_ray", (0, 0))
    need = (-(-5 * leaves // (4 * r)), -(-5 * nodes // (4 * r)))
    if need[0] > before[0] or need[1] > before[1]:
        accel.__dict__["_jit_per_ray"] = (max(need[0], before[0]), max(need[1], before[1]))  # (one assignment)


_INT32_MAX = int(np.iinfo(np.int32).max)
_NO_STACK = np.empty((0, 0), dtype=np.float32)  # the kernel's ``pre`` where no origin is shared


def _shared_stack(accel: TriangleAccel, o32: np.ndarray) -> np.ndarray:
    """The ray-independent rows of the shared-origin test for the float32 origin
    ``o32`` (:func:`tlm.kernels._jit_leaf.shared_stack`), kept on the accel for the last
    origin: the eye rays of a frame share one, and every chunk and batch reads it."""
    from tlm.kernels import _jit_leaf

    key = o32.tobytes()
    last = accel.__dict__.get("_shared_stack")
    if last is None or last[0] != key:
        last = (key, _jit_leaf.shared_stack(accel.jit_layout.soa32, o32))
        accel.__dict__["_shared_stack"] = last  # one assignment: threads see either pair whole
    return last[1]


def _traverse_jit(accel: TriangleAccel, o, d, tmin, tmax, ignore, scale, record, first_only, shared_origin):
    """The whole of :func:`_traverse` for prepared rays, compiled (:func:`tlm.kernels._jit.trace`).

    On several threads (:mod:`tlm.kernels.threads`) the rays are cut into contiguous
    chunks traced at once and joined in order: every output is per ray (the recorded
    nodes and leaves ray-major), and the shared origin is the packet's first ray's for
    every chunk, so the result is the one-call result bit for bit.
    """
    _jit_glue, _jit_rays = _compiled()
    tree, lay = accel.tree, accel.jit_layout
    r = o.shape[0]
    # one compiled signature: numba types a read-only array (a broadcast's view) apart
    if not (o.flags.writeable and d.flags.writeable and tmin.flags.writeable and tmax.flags.writeable
            and ignore.flags.writeable):
        o, d, tmin, tmax, ignore = (a if a.flags.writeable else a.copy() for a in (o, d, tmin, tmax, ignore))
    # the kernel compares ids as int32 (ids are < 2**31): an ignore outside that range
    # can match no triangle, as in the numpy engine, so it becomes -1 (none)
    has_ignore, remap = _jit_rays.ignore_flags(ignore)
    if remap:
        ignore = np.where((ignore < 0) | (ignore > _INT32_MAX), -1, ignore)
    # the float32 test of shared-origin rays takes the packet's first origin (the kernel's docstring)
    shared_o32 = np.zeros(3, dtype=np.float32)
    if shared_origin and r > 0:
        with np.errstate(over="ignore"):
            shared_o32 = np.array([np.float32(o[0, k] - accel.origin[k]) for k in range(3)], dtype=np.float32)
    pre = _shared_stack(accel, shared_o32) if shared_origin and r > 0 else _NO_STACK
    parts = threads.chunked(
        lambda a, b: _jit_chunk(accel, o, d, tmin, tmax, ignore, has_ignore, shared_o32, pre, record, first_only,
                                shared_origin, a, b), r, JIT_MIN_CHUNK)
    if len(parts) == 1:
        t, u, v, slot, node_visits, cnt, leaf_visits, tri_tests, node_ids, leaf_ids = parts[0]
    else:
        t, u, v, slot, node_visits, cnt, leaf_visits, tri_tests, node_ids, leaf_ids = (
            np.concatenate(col) for col in zip(*parts, strict=True))
    counts = Counts(node_visits, cnt, leaf_visits, tri_tests)
    touched = None
    if record:
        node_ptr, leaf_ptr = _jit_glue.touched_ptrs(node_visits, leaf_visits)
        touched = Touched(node_ptr, node_ids.astype(np.int32 if tree.n_nodes <= _INT32_MAX else np.int64), leaf_ptr,
                          leaf_ids)
    if first_only:
        return Occlusion(slot >= 0, counts, touched)
    triangle = _jit_rays.triangles_of(slot, lay.ids)  # (-1 where no slot: no triangles, nothing found)
    if np.count_nonzero(scale):  # back to the caller's direction; a hit beyond float64's range is a miss
        t = unscale_t(t, scale)
        far = np.isinf(t)
        triangle, u, v = np.where(far, -1, triangle), np.where(far, 0.0, u), np.where(far, 0.0, v)
    return Hits(t, triangle, u, v, counts, touched)


def _traverse(accel: TriangleAccel, origins, directions, tmin, tmax, ignore, record, first_only, batch,
              shared_origin=False, exact64=False):
    """Both phases for a packet; ``first_only``: stop at any hit (shadow rays).

    ``exact64``: test in float64 (the fallback of rays whose float32 answer failed its
    float64 check); otherwise test in float32 and check every ray's answer.
    """
    tree = accel.tree
    compiled = engine() == "numba"
    o, d, tmin, tmax, ignore, scale = _prepare(origins, directions, tmin, tmax, ignore, compiled)
    # one origin as the float32 test sees it (equal float64 rows are: the quick test)
    if shared_origin and o.shape[0] > 0 and not _same_rows(o):
        with np.errstate(over="ignore"):
            o32 = (o - accel.origin).astype(np.float32)
        if not (o32 == o32[:1]).all():
            raise ValueError("shared_origin=True but the rays do not share one origin")
    if not exact64 and compiled:
        return _traverse_jit(accel, o, d, tmin, tmax, ignore, scale, record, first_only, shared_origin)
    r = o.shape[0]
    ta, tb, inv = _clip_root(tree, o, d, tmin, tmax)
    soa, soa64 = accel.soa, accel.soa64
    o_local = o - accel.origin
    dt = np.float64 if exact64 else np.float32
    with np.errstate(over="ignore"):  # beyond float32's range: inf (such rays go to float64, below)
        o_t = np.ascontiguousarray(o_local.T, dtype=dt)
        d_t = np.ascontiguousarray(d.T, dtype=dt)
        tmin_t = tmin.astype(dt)
        tmax_t = tmax.astype(dt)
    best_slot, last_k, pray, pleaf, cnt, node_visits, touched_nodes = _loop_numpy(
        accel, o, d, inv, ta, tb, o_t, d_t, tmin_t, tmax_t, ignore, record, first_only, batch,
        shared_origin, exact64)
    npairs = pray.shape[0]
    start = np.cumsum(cnt) - cnt
    size = accel.leaf_size[pleaf]

    # the float64 check of every ray's float32 answer; the rays whose answer fails it
    # (rare: grazing hits at the end of their segment) are traversed again in float64
    hit = np.flatnonzero(best_slot >= 0)
    t, u, v = np.full(r, np.inf), np.zeros(r), np.zeros(r)
    t[hit], u[hit], v[hit], ok = check(o_local[hit], d[hit], tmin[hit], tmax[hit], soa64, best_slot[hit])
    found = best_slot >= 0
    triangle = soa.ids[np.maximum(best_slot, 0)] if soa.ids.shape[0] else np.zeros(r, dtype=np.int64)
    triangle = np.where(found, triangle, -1)  # (no triangles: nothing is found)
    bad = hit[~ok]
    if not exact64:
        # a miss is not checked, so rays that float32 cannot carry go to float64 whole:
        # a direction or origin that over- or underflows (a subnormal direction is zero)
        lossy = lossy32(d, d_t) | lossy32(o_local, o_t)
        if lossy.any():
            bad = np.union1d(bad, np.flatnonzero(lossy))
    if bad.shape[0] and not exact64:
        again = _traverse(accel, o[bad], d[bad], tmin[bad], tmax[bad], ignore[bad], False, first_only, batch,
                          exact64=True)
        last_k[bad] = again.counts.leaf_visits - 1
        if first_only:
            found[bad] = again.occluded
        else:
            found[bad] = again.triangle >= 0
            triangle[bad], t[bad], u[bad], v[bad] = again.triangle, again.t, again.u, again.v

    leaf_visits = np.where(cnt > 0, last_k + 1, 0)
    k_in_ray = np.arange(npairs) - start[pray]
    visited = k_in_ray <= last_k[pray]
    tri_tests = np.bincount(pray, weights=size * visited, minlength=r).astype(np.int64)
    counts = Counts(node_visits, cnt.astype(np.int64), leaf_visits.astype(np.int64), tri_tests)
    touched = None
    if record:
        leaf_ptr = np.zeros(r + 1, dtype=np.int64)
        np.cumsum(leaf_visits, out=leaf_ptr[1:])
        touched = Touched(touched_nodes[0], touched_nodes[1], leaf_ptr, pleaf[visited])
    if first_only:
        return Occlusion(found, counts, touched)
    if scale.any():  # back to the caller's direction; a hit beyond float64's range is a miss
        t = unscale_t(t, scale)
        far = np.isinf(t)
        triangle, u, v = np.where(far, -1, triangle), np.where(far, 0.0, u), np.where(far, 0.0, v)
    return Hits(t, triangle, u, v, counts, touched)


def closest_hit(
    accel: TriangleAccel,
    origins: np.ndarray,
    directions: np.ndarray,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
    ignore: np.ndarray | None = None,
    record: bool = False,
    batch: int = 4,
    shared_origin: bool = False,
) -> Hits:
    """Closest hit of every ray inside ``(tmin, tmax)``, never on its ``ignore`` triangle.

    origins, directions : (r, 3) float64 (directions need not be unit; ``t`` is in units
        of the direction's length).
    record : also return the nodes and leaves touched (:class:`Touched`).
    batch : leaves per ray evaluated together (speed only; results do not depend on it).
    shared_origin : the rays share one origin by construction (eye rays); the test
        then hoists the origin's terms. Results can differ in the last float32 bit
        from ``shared_origin=False``, so pass it for a kind of ray, always or never.
    """
    return _traverse(accel, origins, directions, tmin, tmax, ignore, record, False, batch, shared_origin)


def any_hit(
    accel: TriangleAccel,
    origins: np.ndarray,
    directions: np.ndarray,
    tmin: float | np.ndarray = 0.0,
    tmax: float | np.ndarray = np.inf,
    ignore: np.ndarray | None = None,
    record: bool = False,
    batch: int = 2,
) -> Occlusion:
    """Whether each ray hits anything inside ``(tmin, tmax)`` (shadow rays)."""
    return _traverse(accel, origins, directions, tmin, tmax, ignore, record, True, batch)
