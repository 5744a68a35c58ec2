"""Reflected-radiance estimation from the photon map: the filters of thesis §III.A.2–3.

The thesis (eqs. 3.1–3.5, "Fig. 8") estimates the reflected radiance at a point ``x``
from the photons stored near it. Every estimator here returns the reflected *flux
density* ``sum_p w_p * power_p / area`` (W/m^2); the renderer multiplies it by the
Lambertian BRDF ``albedo / pi``. A photon counts only if it arrived from the front,
``dot(incoming_p, normal_x) < 0``, and only if ``|x_p - x|**2 <= r**2`` with
``|d|**2 = (dx*dx + dy*dy) + dz*dz`` (the acceptance test, evaluated exactly so).

* :func:`disk_estimate` — eq. 3.2: weight 1, area ``pi r**2``.
* :func:`mvoxel_estimate` — eq. 3.3 with Fig. 8, the *m-voxel* filter. The node lists
  are built level by level from the root: at level ``j`` (axis ``j mod 3``, split
  ``D``) the left child (coordinates ``< D``) is kept if ``D > x - r`` and the right
  child (coordinates ``>= D``) if ``D <= x + r``. Fig. 8 writes ``D < BBmax``; we use
  ``<=`` so that a photon lying exactly on a split plane at distance ``r`` is not lost.
  The cube is widened by a relative ``2**-40`` so that rounding in ``x +- r`` can never
  drop a leaf holding a photon the distance test accepts. Every photon of every
  listed leaf is tested. Cone weight ``w = 1 - d / (cone_k r)`` ("C" and "Delta D" of
  eq. 3.3), normalised as Jensen's cone filter: area ``(1 - 2 / (3 cone_k)) pi r**2``.
* :func:`~tlm.kernels.kvoxel.kvoxel_estimate` — eqs. 3.4/3.5, the stochastic *k-voxel* filter
  (:mod:`tlm.kernels.kvoxel`, which reads it and its layers at length).
* :func:`knn_estimate` — the exact reference: Jensen's k-nearest-photon estimate with
  a cone filter (``scipy.spatial.cKDTree``); ``r_k`` is the largest distance among the
  ``k`` found, photons from behind are dropped but ``r_k`` is kept. Photons tied at
  the k-th distance are chosen by cKDTree.

Work counts (per query, int64): ``node_visits`` (inner nodes on the search lists, the
root included: one split comparison each; for the k-voxel filter ``k * levels`` plus
the inner nodes below flat splits visited by the samples' extra branches),
``leaves_visited`` (distinct leaves searched), ``photons_tested`` (the sizes of the
leaves searched; for k-NN the neighbours examined), ``photons_accepted`` (within ``r``
and from the front), ``photons_weighted`` (the accepted photons whose weight the filter
computes: all of them for the cone filters, m-voxel, k-voxel and k-NN; none for the disk,
whose weight is 1), ``probe_tests`` (k-voxel only: leaves the probe points reach,
:data:`~tlm.kernels.kvoxel.PROBES` per query plus one per extra branch at flat splits) and ``gather_misses``:
the page misses (:mod:`tlm.kernels.memory`) of the Fragment PM's photon-leaf pair reading
the photons of every leaf searched (``PHOTON_WORDS`` = 2 words per photon, leaves in
slot order, one address space), queries in order and each query's leaves in the order
searched (the m-voxel lists' left-to-right order; the k-voxel filter's distinct leaves,
each read once, in leaf order). k-NN reads no photon leaves of this tree (it is the
``cKDTree`` reference, not hardware): 0.

Packet invariance: a query's numbers (but ``gather_misses``) never depend on the other
queries computed with it. Photons are summed per (query, leaf) pair in photon-slot order with
``np.bincount`` (which adds in array order), then per query over its pairs in leaf
order; the probe weights are multiples of ``2**-20`` so their sums are exact. The misses
depend on the gathers before, so each filter takes ``streams``
(:class:`~tlm.kernels.memory.Streams`, the pair's state, its page size and the pairs per PM,
which say which Fragment PM pair serves the stream ``photons``; default: cold, the
thesis's 1024-word blocks), and queries computed in consecutive packets with one such
object get the misses of one call.
Randomness comes from :func:`~tlm.kernels.shade.hash_uniform` keyed by the query's key
(``keys``; the default ``arange(q)`` depends on the position in the packet, so pass
stable keys, e.g. pixel ids, when invariance matters). Radius 0, empty maps or leaves
and area 0 give density 0, never NaN; a radius whose area ``pi r**2`` overflows float64
(over :data:`MAX_RADIUS`, 7.6e153) is refused (:func:`check_radius`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tlm.errors import InputError
from tlm.kernels.bsp import BSPTree
from tlm.kernels.engine import engine
from tlm.kernels.memory import PHOTON_WORDS, Accesses, Streams

CHUNK = 1 << 16  # photon tests per block of the gather (bounds memory, keeps data in cache)
QUERY_BLOCK = 16384  # queries traversed together
PAIR_BUDGET = 1 << 22  # (query, node) pairs at most per traversal level before a block is halved
_SLACK = 2.0**-40
JIT_PAIRS = 1 << 16  # the compiled gather's first (query, leaf) pair buffer (grown when a block needs more)


@dataclass(frozen=True)
class Estimate:
    """Result of a radiance estimate for ``q`` queries.

    density : (q, 3) float64, reflected flux density ``sum w power / area`` (W/m^2).
    node_visits, leaves_visited, photons_tested, photons_accepted, probe_tests,
    gather_misses, photons_weighted : (q,) int64 work counts (see the module docstring).
    ``photons_weighted`` left out (an estimator written before it) is ``photons_accepted``:
    every accepted photon charged a weight, as the cone filters are.
    """

    density: np.ndarray
    node_visits: np.ndarray
    leaves_visited: np.ndarray
    photons_tested: np.ndarray
    photons_accepted: np.ndarray
    probe_tests: np.ndarray
    gather_misses: np.ndarray
    photons_weighted: np.ndarray | None = None

    def __post_init__(self) -> None:
        if self.photons_weighted is None:
            object.__setattr__(self, "photons_weighted", self.photons_accepted)


@dataclass(frozen=True)
class LeafPhotons:
    """The photon map in leaf order, one contiguous row per coordinate (what a gather reads).

    pos, inc, pow : (3, n) float64 position, incoming direction, power of photon slot ``i``
        (``tree.items[i]``). first, size : (leaves,) int64 slot range of each leaf.
    pairs : radius -> the (query, leaf) pairs per query the compiled gather's buffers are
        sized by (:func:`_gather_chunk`: learned from earlier calls at that radius, so the
        next calls, a render's batches, seldom gather a chunk twice; sizes only).
    """

    tree: BSPTree
    pos: np.ndarray
    inc: np.ndarray
    pow: np.ndarray
    first: np.ndarray
    size: np.ndarray
    pairs: dict = field(default_factory=dict, compare=False, repr=False)


def leaf_photons(position: np.ndarray, power: np.ndarray, incoming: np.ndarray, tree: BSPTree) -> LeafPhotons:
    """Reorder the photon arrays (n, 3) into ``tree``'s leaf order; pass as ``prepared=`` to reuse."""
    position, power, incoming = (_rows(a, "photon arrays") for a in (position, power, incoming))
    if not position.shape == power.shape == incoming.shape:
        raise ValueError("position, power and incoming must have the same shape (n, 3)")
    if tree.n_elements != position.shape[0] or tree.items.shape[0] != position.shape[0]:
        raise ValueError(f"tree holds {tree.n_elements} points, the photon map {position.shape[0]}")
    items = tree.items
    first, last = tree.leaf_ranges()
    return LeafPhotons(
        tree=tree,
        pos=_leaf_rows(position, items),
        inc=_leaf_rows(incoming, items),
        pow=_leaf_rows(power, items),
        first=first.astype(np.int64),
        size=(last - first).astype(np.int64),
    )


def _leaf_rows(a: np.ndarray, items: np.ndarray) -> np.ndarray:
    """``a[items].T`` (a: (n, 3)) as one C-contiguous (3, m) array, each row gathered
    straight from its column (``np.ascontiguousarray(a[items].T)`` makes the same values
    through an (m, 3) copy: 6-7x slower on 455k photons)."""
    out = np.empty((3, items.shape[0]), dtype=a.dtype)
    for c in range(3):
        np.take(a[:, c], items, out=out[c])
    return out


# ---------------------------------------------------------------- helpers


def _rows(a: np.ndarray, what: str) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{what} must have shape (n, 3), got {a.shape}")
    return a


MAX_RADIUS = math.sqrt(np.finfo(np.float64).max / math.pi)  # 7.6e153: pi r**2, the estimate's area, overflows past it
CAUSTIC_STREAM = "caustic_photons"  # the caustic map's leaf reads (tlm.render.pmap.CAUSTIC_STREAM)


def check_radius(radius: float, stream: str | None = None) -> float:
    """``radius`` as a float: finite and >= 0 (else ValueError), and with a finite area
    ``pi r**2``, which the estimate divides by (else an InputError naming the config key:
    ``estimate.caustic_radius`` for the caustic map's ``stream``, ``estimate.radius`` for the
    others; both when ``stream`` is not given): past :data:`MAX_RADIUS` every density
    would be 0."""
    r = float(radius)
    if not (math.isfinite(r) and r >= 0.0):
        raise ValueError(f"radius (={radius!r}) must be finite and >= 0")
    if not math.isfinite(math.pi * r * r):
        key = ("estimate.radius or estimate.caustic_radius" if stream is None else
               "estimate.caustic_radius" if stream == CAUSTIC_STREAM else "estimate.radius")
        raise InputError(f"{r:g}: the photon-map estimate divides by the search area pi r^2, which overflows float64 "
                         f"for a radius over {MAX_RADIUS:.2g}, so every density would be 0: give a radius of a few "
                         "hundredths of the scene's diagonal (or radius_fraction)", key=key)
    return r


def check_cone(cone_k: float) -> float:
    c = float(cone_k)
    if not (math.isfinite(c) and c >= 1.0):
        raise ValueError(f"cone_k (={cone_k!r}) must be >= 1")
    return c


def gather_inputs(position, power, incoming, tree, points, normals, prepared):
    if prepared is not None and prepared.tree is not tree:
        raise ValueError("prepared was made for another tree")
    lp = prepared if prepared is not None else leaf_photons(position, power, incoming, tree)
    pts, nrm = _rows(points, "points"), _rows(normals, "normals")
    if pts.shape != nrm.shape:
        raise ValueError("points and normals must have the same shape (q, 3)")
    return lp, np.ascontiguousarray(pts.T), np.ascontiguousarray(nrm.T)


def empty_estimate(q: int) -> Estimate:
    z = np.zeros(q, dtype=np.int64)
    return Estimate(np.zeros((q, 3)), z, z.copy(), z.copy(), z.copy(), z.copy(), z.copy(), z.copy())


def weigh_all(out: Estimate) -> Estimate:
    """``out`` with every accepted photon weighted (``photons_weighted = photons_accepted``):
    what a cone filter computes per accepted photon, as a disk filter does not."""
    out.photons_weighted[:] = out.photons_accepted
    return out


GATHER_STREAM = "photons"  # the Fragment PM's stream reading photon leaves (tlm.kernels.memory.PM_STREAMS)


def charge_leaves(streams: Streams, lp: LeafPhotons, query: np.ndarray, leaf: np.ndarray, into: np.ndarray,
                   stream: str = GATHER_STREAM) -> None:
    """Add to ``into`` (m,) the misses of reading the photons of leaf ``leaf[i]`` for query
    ``query[i]`` (in ``[0, m)``), pairs in order, on the pair of ``stream`` (default: the
    Fragment PM's ``photons``; the caustic map's leaves are read as ``caustic_photons``).
    ``into`` is a block of the estimate's ``gather_misses``, where a
    :class:`~tlm.kernels.recording.Deferred` ``streams`` corrects them later."""
    first = lp.first[leaf] * PHOTON_WORDS
    charge_words(streams, first, first + lp.size[leaf] * PHOTON_WORDS, query, into, stream)


def charge_words(streams: Streams, lo: np.ndarray, hi: np.ndarray, query: np.ndarray, into: np.ndarray,
                 stream: str = GATHER_STREAM) -> None:
    """:func:`charge_leaves` of pairs whose word ranges ``lo[i] .. hi[i]`` are made already
    (the compiled gather's chunks make them: :func:`tlm.kernels._jit_pmap.pair_words`)."""
    acc = Accesses.of_ranges(lo, hi, query, streams.page_words)
    streams.charge(stream, acc, into.shape[0], into)


def per_query(index: np.ndarray, values: np.ndarray, q: int) -> np.ndarray:
    """Sum ``values`` per query in array order (bincount adds sequentially)."""
    return np.bincount(index, weights=values, minlength=q)


def _mvoxel_lists(tree: BSPTree, pts: np.ndarray, radius: float, q0: int, q1: int):
    """Fig. 8 for queries ``q0:q1``: (query, leaf) pairs in (query, leaf) order, inner-node visits.

    Returns None when a level would exceed ``PAIR_BUDGET`` pairs (the caller halves the block).
    """
    m = q1 - q0
    sl = slice(q0, q1)
    pad = radius + _SLACK * (np.abs(pts[:, sl]) + radius)
    lo, hi = pts[:, sl] - pad, pts[:, sl] + pad
    qi = np.arange(m, dtype=np.int64)
    node = np.zeros(m, dtype=np.int64)
    visits = np.zeros(m, dtype=np.int64)
    for j in range(tree.levels):
        axis = j % 3
        visits += np.bincount(qi, minlength=m)
        d = tree.split[node]
        keep = np.empty((qi.shape[0], 2), dtype=bool)
        np.greater(d, lo[axis][qi], out=keep[:, 0])
        np.less_equal(d, hi[axis][qi], out=keep[:, 1])
        keep = keep.ravel()
        if np.count_nonzero(keep) > PAIR_BUDGET and m > 1:
            return None
        node = (2 * node[:, None] + np.array([1, 2])).ravel()[keep]  # left child before right
        qi = np.repeat(qi, 2)[keep]
    return qi + q0, node - tree.leaf_offset, visits


def gather_pairs(lp: LeafPhotons, pts, nrm, pq, leaf, radius: float, cone_k: float | None):
    """Test every photon of leaf ``leaf[i]`` against query ``pq[i]``, for all pairs ``i``.

    Returns (accepted (P,) int64, weighted power sums (3, P)), each pair's photons summed
    in slot order. ``cone_k=None`` means weight 1 (the disk filter).
    """
    n_pairs = pq.shape[0]
    accepted = np.zeros(n_pairs, dtype=np.int64)
    sums = np.zeros((3, n_pairs))
    if n_pairs == 0:
        return accepted, sums
    start, size = lp.first[leaf], lp.size[leaf]
    ends = np.cumsum(size)
    r2 = radius * radius
    span = cone_k * radius if cone_k is not None else 0.0  # the cone's base, Delta D of eq. 3.3
    a = 0
    while a < n_pairs:
        base = ends[a] - size[a]
        b = max(int(np.searchsorted(ends, base + CHUNK, side="right")), a + 1)
        sz = size[a:b]
        total = int(ends[b - 1] - base)
        if total == 0:
            a = b
            continue
        q = pq[a:b]
        loc = np.repeat(np.arange(b - a, dtype=np.int64), sz)
        slot = np.arange(total, dtype=np.int64)
        slot += np.repeat(start[a:b] - (ends[a:b] - sz - base), sz)
        d2 = None
        for c in range(3):
            dc = lp.pos[c].take(slot)
            dc -= np.repeat(pts[c].take(q), sz)
            dc *= dc
            d2 = dc if d2 is None else np.add(d2, dc, out=d2)
        near = np.flatnonzero(d2 <= r2)
        s, ln = slot[near], loc[near]
        qn = q[ln]
        cos = lp.inc[0][s] * nrm[0][qn] + lp.inc[1][s] * nrm[1][qn] + lp.inc[2][s] * nrm[2][qn]
        front = cos < 0.0
        s, ln = s[front], ln[front]
        accepted[a:b] = np.bincount(ln, minlength=b - a)
        w = None
        if cone_k is not None:  # 1 - d / (cone_k r); d = 0 when r = 0 (a photon exactly at x)
            d = np.sqrt(d2[near[front]])
            w = 1.0 - np.divide(d, span, out=np.zeros_like(d), where=span > 0.0)
        for c in range(3):
            pw = lp.pow[c][s]
            sums[c, a:b] = np.bincount(ln, weights=pw if w is None else pw * w, minlength=b - a)
        a = b
    return accepted, sums


def _fixed_radius(position, power, incoming, tree, points, normals, radius, cone_k, prepared, streams,
                  stream: str = GATHER_STREAM) -> Estimate:
    lp, pts, nrm = gather_inputs(position, power, incoming, tree, points, normals, prepared)
    streams = Streams() if streams is None else streams
    r = check_radius(radius, stream)
    q = pts.shape[1]
    out = empty_estimate(q)
    density = out.density
    norm = math.pi * r * r * (1.0 if cone_k is None else 1.0 - 2.0 / (3.0 * cone_k))
    if engine() == "numba":
        out = _fixed_radius_jit(lp, pts, nrm, r, cone_k, norm, streams, stream, out)
        return out if cone_k is None else weigh_all(out)
    todo = [(q0, min(q0 + QUERY_BLOCK, q)) for q0 in range(0, q, QUERY_BLOCK)][::-1]
    while todo:
        q0, q1 = todo.pop()
        lists = _mvoxel_lists(lp.tree, pts, r, q0, q1)
        if lists is None:  # too many pairs: halve the block
            mid = (q0 + q1) // 2
            todo += [(mid, q1), (q0, mid)]
            continue
        pq, leaf, visits = lists
        acc, sums = gather_pairs(lp, pts, nrm, pq, leaf, r, cone_k)
        m, loc = q1 - q0, pq - q0
        out.node_visits[q0:q1] = visits
        out.leaves_visited[q0:q1] = np.bincount(loc, minlength=m)
        out.photons_tested[q0:q1] = np.bincount(loc, weights=lp.size[leaf], minlength=m)
        out.photons_accepted[q0:q1] = np.bincount(loc, weights=acc, minlength=m)
        charge_leaves(streams, lp, loc, leaf, out.gather_misses[q0:q1], stream)  # blocks run in order
        if norm > 0.0:  # r * r underflows to 0 for r below ~1e-162: then the density is 0
            for c in range(3):
                density[q0:q1, c] = per_query(loc, sums[c], m) / norm
    return out if cone_k is None else weigh_all(out)


def _fixed_radius_jit(lp: LeafPhotons, pts, nrm, r: float, cone_k: float | None, norm: float, streams: Streams,
                      stream: str, out: Estimate) -> Estimate:
    """:func:`_fixed_radius` by the compiled kernel (:mod:`tlm.kernels._jit_gather`): the same
    bits, query blocks in order (their leaf reads charged block by block, as the numpy path's).

    On several threads (:mod:`tlm.kernels.threads`) each block's queries are cut into
    chunks gathered at once; a chunk's (query, leaf) pairs are query-major, so joined in
    order they are the block's, and the block is charged in this thread, in order, while
    the next blocks' chunks run.
    """
    from tlm.kernels import threads

    q = pts.shape[1]
    blocks = [(q0, min(q0 + QUERY_BLOCK, q)) for q0 in range(0, q, QUERY_BLOCK)]
    chunks = [(q0, q1, a, b) for q0, q1 in blocks for a, b in threads.spans(q1 - q0, GATHER_MIN_CHUNK)]
    # pairs a query needs, as seen so far at this radius (buffer sizes only: no result depends
    # on them; threads may lose one another's raise, and a chunk then runs twice)
    per_query = lp.pairs.setdefault(float(r), [JIT_PAIRS / QUERY_BLOCK])
    results = threads.ordered(
        lambda c: _gather_chunk(lp, pts, nrm, r, cone_k, c[0] + c[2], c[0] + c[3], per_query), chunks)
    at = 0
    for q0, q1 in blocks:
        parts = []
        while at < len(chunks) and chunks[at][0] == q0:
            got = next(results)
            if chunks[at][2]:
                got = (*got[:3], got[3] + chunks[at][2], *got[4:])  # the query's place in the block
            parts.append(got)
            at += 1
        visits, accepted, sums, pq, lo, hi, leaves, tested = (
            parts[0] if len(parts) == 1 else (np.concatenate(col, axis=-1) for col in zip(*parts, strict=True)))
        out.node_visits[q0:q1] = visits
        out.leaves_visited[q0:q1] = leaves
        out.photons_tested[q0:q1] = tested
        out.photons_accepted[q0:q1] = accepted
        charge_words(streams, lo, hi, pq, out.gather_misses[q0:q1], stream)
        if norm > 0.0:
            out.density[q0:q1] = (sums / norm).T
    return out


GATHER_MIN_CHUNK = 512  # queries per chunk at the least when a block is split between threads


def _gather_chunk(lp: LeafPhotons, pts, nrm, r: float, cone_k: float | None, a: int, b: int,
                  per_query: list[float]):
    """The compiled gather of queries ``a:b``: ``visits, accepted`` (m,), ``sums`` (3, m), the
    (query, leaf) pairs' queries in order (numbered from ``a``) and the word ranges of their
    leaves' photons (:data:`PHOTON_WORDS` a photon), and each query's leaves and photons
    tested (m,) (:func:`tlm.kernels._jit_pmap.pair_words`, on this thread without the
    interpreter lock); the pair buffer grown until it holds them (``per_query``: the pairs per
    query to size it by, raised by a chunk that needed more, so that the next chunks do not
    run twice)."""
    from tlm.kernels._jit_gather import fixed_radius
    from tlm.kernels._jit_pmap import pair_words

    tree = lp.tree
    m = b - a
    visits = np.zeros(m, dtype=np.int64)
    sums = np.zeros((3, m))
    accepted = np.zeros(m, dtype=np.int64)
    pairs = max(int(per_query[0] * m) + 1, 64)
    while True:
        pq, leaf = np.empty(pairs, dtype=np.int64), np.empty(pairs, dtype=np.int64)
        need = fixed_radius(tree.split, tree.levels, tree.leaf_offset, lp.pos, lp.inc, lp.pow, lp.first, lp.size,
                            pts, nrm, a, b, r, _SLACK, cone_k is not None, 0.0 if cone_k is None else cone_k * r,
                            pq, leaf, visits, sums, accepted)
        if need <= pairs:
            break
        pairs = int(need)
        if m >= GATHER_MIN_CHUNK:  # (a few queries in a dense spot would size every later buffer)
            per_query[0] = max(per_query[0], 1.25 * need / m)
    pq = pq[:need]
    leaves, tested, lo, hi = pair_words(pq, leaf[:need], lp.first, lp.size, m, PHOTON_WORDS)
    return visits, accepted, sums, pq, lo, hi, leaves, tested


# ---------------------------------------------------------------- the filters


def disk_estimate(position, power, incoming, tree: BSPTree, points, normals, radius: float,
                  *, prepared: LeafPhotons | None = None, streams: Streams | None = None,
                  stream: str = GATHER_STREAM) -> Estimate:
    """Eq. 3.2, the disk filter: every front photon within ``radius`` counts, area ``pi r**2``.

    position, power, incoming : (n, 3) photon map; tree : ``build_point_tree(position)``.
    points, normals : (q, 3) query points and unit normals facing the shaded side.
    prepared : optional :func:`leaf_photons` of the same map (skips the reordering).
    streams : the photon-leaf pair's state before these queries, left in the state after
    them (default: a cold pair). stream : the name the leaf reads are charged under
    (:data:`GATHER_STREAM`; the caustic map's: ``caustic_photons``, a pair of its own).
    Candidate leaves are found by Fig. 8 exactly as in :func:`mvoxel_estimate`.
    """
    return _fixed_radius(position, power, incoming, tree, points, normals, radius, None, prepared, streams, stream)


def mvoxel_estimate(position, power, incoming, tree: BSPTree, points, normals, radius: float,
                    cone_k: float = 1.1, *, prepared: LeafPhotons | None = None,
                    streams: Streams | None = None, stream: str = GATHER_STREAM) -> Estimate:
    """Eq. 3.3 with Fig. 8, the m-voxel cone filter (see the module docstring).

    Shapes and ``streams`` as :func:`disk_estimate`; weight ``1 - d / (cone_k r)``, area
    ``(1 - 2 / (3 cone_k)) pi r**2``.
    """
    return _fixed_radius(position, power, incoming, tree, points, normals, radius, check_cone(cone_k), prepared,
                         streams, stream)


def knn_estimate(position, power, incoming, points, normals, k_nearest: int = 50, cone_k: float = 1.1,
                 kdtree=None) -> Estimate:
    """Jensen's k-nearest-photon estimate with a cone filter: the exact reference.

    position, power, incoming : (n, 3); points, normals : (q, 3). kdtree : optional
    prebuilt ``scipy.spatial.cKDTree(position)``. The ``k`` nearest photons are found
    (fewer if the map holds fewer), their distances recomputed in numpy and sorted by
    (distance, photon id); ``r_k`` is the largest; photons from behind are dropped.
    Density ``sum w power / ((1 - 2 / (3 cone_k)) pi r_k**2)`` with ``w = 1 - d / (cone_k
    r_k)``; 0 when ``r_k = 0`` or the map is empty. ``photons_tested`` = neighbours found.
    ``gather_misses`` is 0: the ``cKDTree`` is the exact reference, not a memory layout
    of the thesis hardware, so it has no photon-leaf stream to charge.
    """
    position, power, incoming = (_rows(a, "photon arrays") for a in (position, power, incoming))
    pts, nrm = _rows(points, "points"), _rows(normals, "normals")
    cone_k = check_cone(cone_k)
    if isinstance(k_nearest, bool) or int(k_nearest) != k_nearest or k_nearest < 1:
        raise ValueError(f"k_nearest (={k_nearest!r}) must be an integer >= 1")
    q, n = pts.shape[0], position.shape[0]
    out = empty_estimate(q)
    kk = min(int(k_nearest), n)
    if q == 0 or kk == 0:
        return out
    if kdtree is None:
        from scipy.spatial import cKDTree

        kdtree = cKDTree(position)
    block = max(1, min(QUERY_BLOCK, (1 << 20) // kk))
    for q0 in range(0, q, block):
        q1 = min(q0 + block, q)
        _knn_block(position, power, incoming, kdtree, pts[q0:q1], nrm[q0:q1], kk, cone_k, out, slice(q0, q1))
    out.photons_tested[:] = kk
    return weigh_all(out)


def _knn_block(position, power, incoming, kdtree, pts, nrm, kk: int, cone_k: float, out: Estimate, sl) -> None:
    q = pts.shape[0]
    _, idx = kdtree.query(pts, k=kk, workers=1)
    idx = np.asarray(idx, dtype=np.int64).reshape(q, kk)
    d2 = None
    for c in range(3):
        dc = position[idx, c] - pts[:, c, None]
        d2 = dc * dc if d2 is None else d2 + dc * dc
    order = np.lexsort((idx, d2), axis=1)
    idx = np.take_along_axis(idx, order, axis=1)
    d = np.sqrt(np.take_along_axis(d2, order, axis=1))
    rk = d[:, -1:]
    front = (incoming[idx, 0] * nrm[:, 0, None] + incoming[idx, 1] * nrm[:, 1, None]
             + incoming[idx, 2] * nrm[:, 2, None]) < 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        w = np.where(front & (rk > 0.0), 1.0 - d / (cone_k * rk), 0.0)
        norm = (1.0 - 2.0 / (3.0 * cone_k)) * math.pi * rk[:, 0] ** 2
    row = np.repeat(np.arange(q), kk)
    for c in range(3):
        sums = per_query(row, (w * power[idx, c]).ravel(), q)
        out.density[sl, c] = np.divide(sums, norm, out=np.zeros(q), where=norm > 0.0)
    out.photons_accepted[sl] = front.sum(axis=1)


# ---------------------------------------------------------------- the density rule of the radius

DENSITY_SAMPLE = 256  # stored photons whose k-th neighbour distance sets the density rule's radius


def density_radius(position: np.ndarray, k: int, sample: int = DENSITY_SAMPLE) -> float | None:
    """The search radius that holds about ``k`` of a map's photons: the median, over a fixed
    sample of the map, of the distance from a photon to its ``k``-th nearest other photon.

    position : (n, 3) the map's photons. The sample is ``min(sample, n)`` photons evenly
    spaced in storage order (``i * n // s``); the neighbours are found with
    ``scipy.spatial.cKDTree`` and their distances recomputed in numpy, so the radius
    depends on the map alone (not on packets, threads or the gather points) and a map
    scaled by ``s`` gives ``s`` times the radius, up to rounding. ``k`` is capped at
    ``n - 1``. None when the map holds fewer than 2 photons or the median is 0 (photons
    stacked on one point): the caller's fallback applies. A map keeps its radii
    (:meth:`tlm.kernels.photons.PhotonMap.density_radius`): every packet asks again.
    """
    if isinstance(k, bool) or int(k) != k or k < 1:
        raise ValueError(f"k (={k!r}) must be an integer >= 1")
    pos = _rows(position, "position")
    n = pos.shape[0]
    radius = None
    if n >= 2:
        from scipy.spatial import cKDTree

        kk = min(int(k), n - 1)
        s = min(int(sample), n)
        at = np.arange(s, dtype=np.int64) * n // s
        # (an unbalanced tree without shrunk boxes: built in under half the time, for 256
        # queries; the neighbours' distances are the same, recomputed below)
        tree = cKDTree(pos, balanced_tree=False, compact_nodes=False)
        _, idx = tree.query(pos[at], k=kk + 1, workers=1)
        idx = np.asarray(idx, dtype=np.int64).reshape(s, kk + 1)
        d2 = ((pos[idx] - pos[at][:, None, :]) ** 2).sum(axis=2)
        d2 = np.where(idx == at[:, None], np.inf, d2)  # the photon itself is not its neighbour
        d2.sort(axis=1)
        med = float(np.median(np.sqrt(d2[:, kk - 1])))
        radius = med if math.isfinite(med) and med > 0.0 else None
    return radius
