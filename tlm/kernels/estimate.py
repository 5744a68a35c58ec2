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
* :func:`kvoxel_estimate` — eqs. 3.4/3.5, the stochastic *k-voxel* filter, read as
  follows. Sample points are ``x_0 = x`` and ``k - 1`` points uniform in the disk of
  radius ``r`` on the tangent plane at ``x``; each is located in the tree (right iff
  ``coord >= split``; but see the layers below), giving ``k`` voxels (a voxel sampled
  twice is searched once but keeps its multiplicity). Voxel ``s`` gives the estimate (3.4) ``sum_p w_p
  power_p / dA_s`` over its own front photons within ``r`` of ``x`` (cone weights as
  above), where ``dA_s`` is the part of the search disk the voxel covers, measured
  with a fixed sunflower pattern of ``PROBES = 64`` equal-area probe points of the
  disk: ``dA_s = (1 - 2 / (3 cone_k)) pi r**2 * sum_{probes in s} c_m / sum_all c_m``
  with probe weights ``c_m = 1 - rho_m / cone_k`` (the cone at the probe's radius).
  A voxel is the *cell* of its leaf (the points that descend to it, the same rule as
  for photons and sample points); it equals the leaf's box inside the root box and
  extends beyond the root box's faces. A voxel covering no probe contributes
  nothing. Eq. 3.5 is the mean over the ``k`` samples (with multiplicity). With the
  cone-weighted ``dA_s`` each voxel's estimate is unbiased for a locally uniform
  density whatever the splits, up to the probes' discretisation (~1% measured); with
  plain area fractions the voxel that holds ``x`` sees only the heavy centre of the
  cone and biases the mean upwards (+3% at k = 8, +23% at k = 1). When one voxel
  covers the whole disk the estimate is exactly the m-voxel one. At a fixed depth it
  converges to the m-voxel estimate as photons are added; at the default depth
  ``floor(ln n)`` leaves keep ~40-60 photons, so its own noise does not shrink.

  *Splits lying on the query's surface (layers).* A traced photon lies on its plane
  only to within rounding (~1e-13 of the scene's size), on either side. When all of a
  node's photons lie on one axis-aligned plane, its centre-of-mass split along that
  axis lands on the plane, and the photons fall into the two children by the sign of
  their rounding error: each child holds a random share of the surface's photons over
  the same region of the plane (a *layer*), while a disk on the plane (x, its sample
  points, its probes) descends into one of them. Its voxel then holds only one
  layer's share but is credited with the disk's whole area: on the Cornell box the
  estimate was 8% (30k photons, 9 levels) to 11% (120k, 11 levels) below the m-voxel
  one, 5% to 38% on its axis-aligned surfaces, more with depth as more splits land on
  planes (the m-voxel search covers both sides and is immune). So a
  split is *flat* when both children hold photons and all the node's photons lie
  within ``delta = min(COPLANAR_TOL * S, 2**-20 * E)`` of it along its axis (``S``:
  the largest coordinate magnitude of the root box, ``E`` its largest extent:
  rounding in the traced positions and in the centre-of-mass sums is orders of
  magnitude smaller, any modelled feature larger, even for a small scene placed far
  from the origin),
  and a query's disk *lies on* a flat split when ``|x_a - D| + r |(t1_a, t2_a)| <=
  delta`` (it is flat along the axis and on the plane, to within ``delta``). There
  every sample point and probe of the query descends into both children, so a sample
  reaches one leaf per layer (``2**c`` leaves for ``c`` such splits on its path; ``c``
  is 0 off such surfaces); each leaf reached gives its own estimate (3.4), its photons
  over the part of the disk its cell covers *within its layer* (the probes reaching
  it), and the sample's estimate is the sum over its leaves: the layers' shares add
  up to the surface's density whatever the rounding did. (Pooling them instead, all
  the leaves' photons over the area their cells cover together, stays biased low
  where the layers' cells differ: -6% on the Cornell box's flat surfaces.) Photons are
  still tested per distinct (query, leaf) pair, once, with the multiplicity of the
  samples reaching the leaf. Where exactly one child of a split holds photons, the
  split is moved by ``2 delta`` towards the empty child, so that rounding cannot send
  a point of a disk lying on the split to the empty side (no photon changes side; the
  empty cell loses a sliver). The descent stays ``levels`` comparisons per point and
  branch, and the extra leaves are those holding the other layers' photons of the
  sample's region, all of which the m-voxel search lists as well. On the Cornell box
  (120k photons, k = 8) the leaves searched per query went from 2.4 to 3.0, the
  photons tested from 124 to 145, the probes located from 64 to 85 (m-voxel: 7.4
  leaves, 245 photons).
* :func:`knn_estimate` — the exact reference: Jensen's k-nearest-photon estimate with
  a cone filter (``scipy.spatial.cKDTree``); ``r_k`` is the largest distance among the
  ``k`` found, photons from behind are dropped but ``r_k`` is kept. Photons tied at
  the k-th distance are chosen by cKDTree.

Work counts (per query, int64): ``node_visits`` (inner nodes on the search lists, the
root included: one split comparison each; for the k-voxel filter ``k * levels`` plus
the inner nodes below flat splits visited by the samples' extra branches),
``leaves_visited`` (distinct leaves searched), ``photons_tested`` (the sizes of the
leaves searched; for k-NN the neighbours examined), ``photons_accepted`` (within ``r``
and from the front), ``probe_tests`` (k-voxel only: leaves the probe points reach,
``PROBES`` per query plus one per extra branch at flat splits) and ``gather_misses``:
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
and area 0 give density 0, never NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from tlm.kernels.bsp import BSPTree
from tlm.kernels.engine import engine
from tlm.kernels.memory import PHOTON_WORDS, Accesses, Streams
from tlm.kernels.shade import hash_uniform

PROBES = 64  # probe points of the k-voxel filter's area measure
CHUNK = 1 << 16  # photon tests per block of the gather (bounds memory, keeps data in cache)
QUERY_BLOCK = 16384  # queries traversed together
PAIR_BUDGET = 1 << 22  # (query, node) pairs at most per traversal level before a block is halved
_SLACK = 2.0**-40
JIT_PAIRS = 1 << 16  # the compiled gather's first (query, leaf) pair buffer (grown when a block needs more)
COPLANAR_TOL = 2.0**-32  # k-voxel: flat splits and disks lying on them, relative to the scene's size
_GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


@dataclass(frozen=True)
class Estimate:
    """Result of a radiance estimate for ``q`` queries.

    density : (q, 3) float64, reflected flux density ``sum w power / area`` (W/m^2).
    node_visits, leaves_visited, photons_tested, photons_accepted, probe_tests,
    gather_misses : (q,) int64 work counts (see the module docstring).
    """

    density: np.ndarray
    node_visits: np.ndarray
    leaves_visited: np.ndarray
    photons_tested: np.ndarray
    photons_accepted: np.ndarray
    probe_tests: np.ndarray
    gather_misses: np.ndarray


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


def _check_radius(radius: float) -> float:
    r = float(radius)
    if not (math.isfinite(r) and r >= 0.0):
        raise ValueError(f"radius (={radius!r}) must be finite and >= 0")
    return r


def _check_cone(cone_k: float) -> float:
    c = float(cone_k)
    if not (math.isfinite(c) and c >= 1.0):
        raise ValueError(f"cone_k (={cone_k!r}) must be >= 1")
    return c


def _prepare(position, power, incoming, tree, points, normals, prepared):
    if prepared is not None and prepared.tree is not tree:
        raise ValueError("prepared was made for another tree")
    lp = prepared if prepared is not None else leaf_photons(position, power, incoming, tree)
    pts, nrm = _rows(points, "points"), _rows(normals, "normals")
    if pts.shape != nrm.shape:
        raise ValueError("points and normals must have the same shape (q, 3)")
    return lp, np.ascontiguousarray(pts.T), np.ascontiguousarray(nrm.T)


def _empty(q: int) -> Estimate:
    z = np.zeros(q, dtype=np.int64)
    return Estimate(np.zeros((q, 3)), z, z.copy(), z.copy(), z.copy(), z.copy(), z.copy())


GATHER_STREAM = "photons"  # the Fragment PM's stream reading photon leaves (tlm.kernels.memory.PM_STREAMS)


def _charge_leaves(streams: Streams, lp: LeafPhotons, query: np.ndarray, leaf: np.ndarray, into: np.ndarray,
                   stream: str = GATHER_STREAM) -> None:
    """Add to ``into`` (m,) the misses of reading the photons of leaf ``leaf[i]`` for query
    ``query[i]`` (in ``[0, m)``), pairs in order, on the pair of ``stream`` (default: the
    Fragment PM's ``photons``; the caustic map's leaves are read as ``caustic_photons``).
    ``into`` is a block of the estimate's ``gather_misses``, where a
    :class:`~tlm.kernels.memory.Deferred` ``streams`` corrects them later."""
    first = lp.first[leaf] * PHOTON_WORDS
    acc = Accesses.of_ranges(first, first + lp.size[leaf] * PHOTON_WORDS, query, streams.page_words)
    streams.charge(stream, acc, into.shape[0], into)


def _per_query(index: np.ndarray, values: np.ndarray, q: int) -> np.ndarray:
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


def _gather(lp: LeafPhotons, pts, nrm, pq, leaf, radius: float, cone_k: float | None):
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
    lp, pts, nrm = _prepare(position, power, incoming, tree, points, normals, prepared)
    streams = Streams() if streams is None else streams
    r = _check_radius(radius)
    q = pts.shape[1]
    out = _empty(q)
    density = out.density
    norm = math.pi * r * r * (1.0 if cone_k is None else 1.0 - 2.0 / (3.0 * cone_k))
    if engine() == "numba":
        return _fixed_radius_jit(lp, pts, nrm, r, cone_k, norm, streams, stream, out)
    todo = [(q0, min(q0 + QUERY_BLOCK, q)) for q0 in range(0, q, QUERY_BLOCK)][::-1]
    while todo:
        q0, q1 = todo.pop()
        lists = _mvoxel_lists(lp.tree, pts, r, q0, q1)
        if lists is None:  # too many pairs: halve the block
            mid = (q0 + q1) // 2
            todo += [(mid, q1), (q0, mid)]
            continue
        pq, leaf, visits = lists
        acc, sums = _gather(lp, pts, nrm, pq, leaf, r, cone_k)
        m, loc = q1 - q0, pq - q0
        out.node_visits[q0:q1] = visits
        out.leaves_visited[q0:q1] = np.bincount(loc, minlength=m)
        out.photons_tested[q0:q1] = np.bincount(loc, weights=lp.size[leaf], minlength=m)
        out.photons_accepted[q0:q1] = np.bincount(loc, weights=acc, minlength=m)
        _charge_leaves(streams, lp, loc, leaf, out.gather_misses[q0:q1], stream)  # blocks run in order
        if norm > 0.0:  # r * r underflows to 0 for r below ~1e-162: then the density is 0
            for c in range(3):
                density[q0:q1, c] = _per_query(loc, sums[c], m) / norm
    return out


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
        m = q1 - q0
        parts = []
        while at < len(chunks) and chunks[at][0] == q0:
            visits, accepted, sums, pq, leaf = next(results)
            parts.append((visits, accepted, sums, pq + chunks[at][2], leaf))  # the query's place in the block
            at += 1
        visits, accepted, sums, pq, leaf = (np.concatenate(col, axis=-1) for col in zip(*parts, strict=True))
        out.node_visits[q0:q1] = visits
        out.leaves_visited[q0:q1] = np.bincount(pq, minlength=m)
        out.photons_tested[q0:q1] = np.bincount(pq, weights=lp.size[leaf], minlength=m)
        out.photons_accepted[q0:q1] = accepted
        _charge_leaves(streams, lp, pq, leaf, out.gather_misses[q0:q1], stream)
        if norm > 0.0:
            out.density[q0:q1] = (sums / norm).T
    return out


GATHER_MIN_CHUNK = 512  # queries per chunk at the least when a block is split between threads


def _gather_chunk(lp: LeafPhotons, pts, nrm, r: float, cone_k: float | None, a: int, b: int,
                  per_query: list[float]):
    """The compiled gather of queries ``a:b``: ``visits, accepted`` (m,), ``sums`` (3, m) and
    the (query, leaf) pairs in order (the query numbered from ``a``), its pair buffer grown
    until it holds them (``per_query``: the pairs per query to size it by, raised by a chunk that
    needed more, so that the next chunks do not run twice)."""
    from tlm.kernels._jit_gather import fixed_radius

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
    return visits, accepted, sums, pq[:need], leaf[:need]


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
    return _fixed_radius(position, power, incoming, tree, points, normals, radius, _check_cone(cone_k), prepared,
                         streams, stream)


def _tangent_basis(nrm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal (t1, t2), each (3, q), perpendicular to unit normals (3, q) (Duff et al. 2017)."""
    nx, ny, nz = nrm
    sign = np.copysign(1.0, nz)
    a = -1.0 / (sign + nz)
    b = nx * ny * a
    t1 = np.stack([1.0 + sign * nx * nx * a, sign * b, -sign * nx])
    t2 = np.stack([b, sign + ny * ny * a, -ny])
    return t1, t2


def _probe_pattern(cone_k: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sunflower pattern of ``PROBES`` equal-area points of the unit disk, and their cone weights.

    Weights are multiples of ``2**-20`` so that any sum of them is exact.
    """
    m = np.arange(PROBES)
    rho = np.sqrt((m + 0.5) / PROBES)
    phi = m * _GOLDEN_ANGLE
    weight = np.round((1.0 - rho / cone_k) * 2.0**20) * 2.0**-20
    return rho * np.cos(phi), rho * np.sin(phi), weight


@dataclass(frozen=True)
class _Layers:
    """The k-voxel filter's view of the tree's splits (see the module docstring).

    delta : the coplanarity tolerance, ``COPLANAR_TOL * S`` (S: the largest coordinate
        magnitude of the root box), but at most ``2**-20`` of the box's largest extent, so
        that a small scene far from the origin does not see its features as flat.
    split : (nodes,) the splits, moved by ``2 delta``
        towards a child that holds no photon when its sibling does. flat : (inner nodes,)
        bool, both children hold photons and all the node's photons lie within ``delta``
        of the split along its axis. flat_level : (levels,) bool, a level holds a flat node.
    """

    delta: float
    split: np.ndarray
    flat: np.ndarray
    flat_level: np.ndarray


def _layers(lp: LeafPhotons) -> _Layers:
    tree = lp.tree
    extent = float(np.max(tree.hi[0] - tree.lo[0]))
    delta = min(COPLANAR_TOL * float(np.abs(np.concatenate([tree.lo[0], tree.hi[0]])).max()), 2.0**-20 * extent)
    split = tree.split.copy()
    inner = tree.leaf_offset
    if inner == 0:
        return _Layers(delta, split, np.zeros(0, dtype=bool), np.zeros(0, dtype=bool))
    # extent of every node's photons along each axis, from the leaves up
    lo = np.full((tree.n_nodes, 3), np.inf)
    hi = np.full((tree.n_nodes, 3), -np.inf)
    full = np.flatnonzero(lp.size > 0)
    if full.shape[0]:  # leaves are contiguous in slot order: reduce from each non-empty leaf's first slot
        for c in range(3):
            lo[inner + full, c] = np.minimum.reduceat(lp.pos[c], lp.first[full])
            hi[inner + full, c] = np.maximum.reduceat(lp.pos[c], lp.first[full])
    for j in range(tree.levels - 1, -1, -1):
        i = np.arange((1 << j) - 1, (1 << (j + 1)) - 1)
        lo[i] = np.minimum(lo[2 * i + 1], lo[2 * i + 2])
        hi[i] = np.maximum(hi[2 * i + 1], hi[2 * i + 2])
    i = np.arange(inner)
    level = np.repeat(np.arange(tree.levels), 1 << np.arange(tree.levels))
    axis = level % 3
    d = split[:inner]
    has = tree.last > tree.first
    left, right = has[2 * i + 1], has[2 * i + 2]
    flat = left & right & (np.maximum(d - lo[i, axis], hi[i, axis] - d) <= delta)
    split[:inner] = np.where(left & ~right, d + 2.0 * delta, np.where(right & ~left, d - 2.0 * delta, d))
    flat_level = np.bincount(level[flat], minlength=tree.levels) > 0
    return _Layers(delta, split, flat, flat_level)


def _on_flat(layers: _Layers, a: int, x, lim, p: int, w, rows, node, right, cur):
    """The branches ``w`` (of points ``rows``) standing at a flat split that their query's disk lies on.

    Returns their points, sibling children (the child they do not descend to), coordinates
    (3, .) and queries.
    """
    pn = node.take(w)
    hit = np.flatnonzero(layers.flat.take(pn))
    w, rows, pn = w[hit], rows[hit], pn[hit]
    qn = rows // p
    on = np.flatnonzero(np.abs(x[a].take(qn) - layers.split.take(pn)) <= lim[a].take(qn))
    w, rows, pn, qn = w[on], rows[on], pn[on], qn[on]
    return rows, 2 * pn + 2 - right[w], cur[:, w], qn


def _locate_layers(tree: BSPTree, layers: _Layers, coords: np.ndarray, x: np.ndarray, lim: np.ndarray):
    """Leaves reached by the points ``coords`` (3, m, p) of ``m`` queries (disk centres ``x`` (3, m)).

    Right iff ``coord >= layers.split``, except at a flat split on which the query's disk
    lies (``|x_a - split| <= lim[a]``, ``lim = delta - r |(t1_a, t2_a)|``): there every
    point of the query goes to both children. Returns (leaf, xrow, xleaf, extra): leaf
    (m * p,) the leaf reached by each point's own descent (point ``query * p + i``);
    point ``xrow[e]`` also reaches ``xleaf[e]`` through the sibling branches; extra (m,)
    int64, inner nodes visited by the sibling branches.
    """
    m, p = coords.shape[1], coords.shape[2]
    cur = coords.reshape(3, m * p)
    node = np.zeros(m * p, dtype=np.int64)
    xrow = np.zeros(0, dtype=np.int64)  # the sibling branches: point, node, coordinates
    xnode = np.zeros(0, dtype=np.int64)
    xcur = np.zeros((3, 0))
    extra = np.zeros(m, dtype=np.int64)
    flatq = lim >= 0.0  # (3, m): the query's disk is flat along the axis
    # the points of the queries flat along each axis: the only ones that may meet a flat split
    watch = [np.flatnonzero(np.repeat(flatq[a], p)) if layers.flat_level[a::3].any() else None for a in range(3)]
    for j in range(tree.levels):
        a = j % 3
        right = cur[a] >= layers.split.take(node)
        xright = xcur[a] >= layers.split.take(xnode)
        found = []
        if layers.flat_level[j] and watch[a] is not None:
            found.append(_on_flat(layers, a, x, lim, p, watch[a], watch[a], node, right, cur))
            w = np.flatnonzero(flatq[a].take(xrow // p))
            found.append(_on_flat(layers, a, x, lim, p, w, xrow.take(w), xnode, xright, xcur))
        node *= 2
        node += 1
        node += right
        xnode = 2 * xnode + 1 + xright
        for rows, sibling, coord, qn in found:
            if rows.shape[0]:
                xrow = np.concatenate([xrow, rows])
                xnode = np.concatenate([xnode, sibling])
                xcur = np.concatenate([xcur, coord], axis=1)
                extra += np.bincount(qn, minlength=m) * (tree.levels - 1 - j)
    node -= tree.leaf_offset
    return node, xrow, xnode - tree.leaf_offset, extra


def kvoxel_estimate(position, power, incoming, tree: BSPTree, points, normals, radius: float, k: int = 8,
                    cone_k: float = 1.1, seed: int = 0, keys: np.ndarray | None = None,
                    *, prepared: LeafPhotons | None = None, streams: Streams | None = None,
                    stream: str = GATHER_STREAM) -> Estimate:
    """Eqs. 3.4/3.5, the stochastic k-voxel filter (reading in the module docstring).

    Shapes and ``streams`` as :func:`disk_estimate`. k : voxels sampled (x itself and ``k - 1`` random
    points of the tangent disk). keys : (q,) int64 random-stream key per query (default
    ``arange(q)``); sample ``s`` uses ``hash_uniform(seed, key, 7, s, dim)``. The samples
    and probes of a disk lying on a flat split search both of its layers (module docstring).
    """
    lp, pts, nrm = _prepare(position, power, incoming, tree, points, normals, prepared)
    r, cone_k = _check_radius(radius), _check_cone(cone_k)
    if isinstance(k, bool) or int(k) != k or k < 1:
        raise ValueError(f"k (={k!r}) must be an integer >= 1")
    k = int(k)
    q = pts.shape[1]
    keys = np.arange(q, dtype=np.int64) if keys is None else np.asarray(keys, dtype=np.int64).reshape(-1)
    if keys.shape[0] != q:
        raise ValueError(f"keys must have shape ({q},), got {keys.shape}")
    out = _empty(q)
    streams = Streams() if streams is None else streams
    tree = lp.tree
    t1, t2 = _tangent_basis(nrm)
    pu, pv, pweight = _probe_pattern(cone_k)
    total_weight = float(pweight.sum())
    norm = (1.0 - 2.0 / (3.0 * cone_k)) * math.pi * r * r
    layers = _layers(lp)
    lim = layers.delta - r * np.sqrt(t1 * t1 + t2 * t2)  # (3, q): on a flat split D iff |x_a - D| <= lim[a]
    n_leaves = tree.n_leaves
    s = np.arange(1, k)
    block = max(1, min(QUERY_BLOCK // 8, (1 << 18) // max(k, PROBES)))
    for q0 in range(0, q, block):
        q1 = min(q0 + block, q)
        m, sl = q1 - q0, slice(q0, q1)
        x, a1, a2 = pts[:, sl, None], t1[:, sl, None], t2[:, sl, None]
        rho = r * np.sqrt(hash_uniform(seed, keys[sl, None], 7, s[None, :], 0))
        phi = 2.0 * math.pi * hash_uniform(seed, keys[sl, None], 7, s[None, :], 1)
        u, v = rho * np.cos(phi), rho * np.sin(phi)
        samples = np.concatenate([pts[:, sl, None], x + (u * a1 + v * a2)], axis=2)  # (3, m, k)
        sleaf, xrow, xleaf, extra = _locate_layers(tree, layers, samples, pts[:, sl], lim[:, sl])
        key = np.repeat(np.arange(m, dtype=np.int64) * n_leaves, k) + sleaf
        if xrow.shape[0]:
            key = np.concatenate([key, (xrow // k) * n_leaves + xleaf])
        key = np.sort(key)
        fresh = np.ones(key.shape[0], dtype=bool)
        fresh[1:] = key[1:] != key[:-1]
        starts = np.flatnonzero(fresh)
        mult = np.diff(np.append(starts, key.shape[0]))  # samples reaching each distinct voxel
        key = key[starts]  # distinct (query, leaf) pairs in (query, leaf) order
        pq = key // n_leaves
        leaf = key - pq * n_leaves
        # area of the disk in each distinct voxel, from the probes' cells
        probes = x + (r * pu * a1 + r * pv * a2)  # (3, m, PROBES)
        pleaf, xrow, xleaf, _ = _locate_layers(tree, layers, probes, pts[:, sl], lim[:, sl])
        # the probes' own leaves, then the sibling branches
        in_cell = pleaf.reshape(m, PROBES)[pq] == leaf[:, None]
        cover = in_cell @ pweight
        if xrow.shape[0]:
            xkey = (xrow // PROBES) * n_leaves + xleaf
            at = np.minimum(np.searchsorted(key, xkey), key.shape[0] - 1)
            hit = np.flatnonzero(key[at] == xkey)
            cover += np.bincount(at[hit], weights=pweight[xrow[hit] % PROBES], minlength=key.shape[0])
        frac = cover / total_weight  # weights are multiples of 2**-20: the sums are exact
        acc, sums = _gather(lp, pts, nrm, pq + q0, leaf, r, cone_k)
        out.node_visits[sl] = k * tree.levels + extra
        out.leaves_visited[sl] = np.bincount(pq, minlength=m)
        out.photons_tested[sl] = np.bincount(pq, weights=lp.size[leaf], minlength=m)
        out.photons_accepted[sl] = np.bincount(pq, weights=acc, minlength=m)
        out.probe_tests[sl] = PROBES + np.bincount(xrow // PROBES, minlength=m)
        _charge_leaves(streams, lp, pq, leaf, out.gather_misses[sl], stream)  # blocks run in order
        if r > 0.0:
            area = norm * frac
            share = mult / k
            for c in range(3):
                e = np.divide(sums[c], area, out=np.zeros_like(area), where=area > 0.0)  # eq. 3.4
                out.density[sl, c] = _per_query(pq, e * share, m)  # eq. 3.5
    return out


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
    cone_k = _check_cone(cone_k)
    if isinstance(k_nearest, bool) or int(k_nearest) != k_nearest or k_nearest < 1:
        raise ValueError(f"k_nearest (={k_nearest!r}) must be an integer >= 1")
    q, n = pts.shape[0], position.shape[0]
    out = _empty(q)
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
    return out


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
        sums = _per_query(row, (w * power[idx, c]).ravel(), q)
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
