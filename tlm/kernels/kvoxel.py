"""The k-voxel filter of thesis §III.A.3 (eqs. 3.4/3.5): :func:`kvoxel_estimate`, the stochastic
estimate from the photons of the voxels that ``k`` sample points of the search disk reach.

The thesis's filter, read as follows. Sample points are ``x_0 = x`` and ``k - 1`` points
uniform in the disk of radius ``r`` on the tangent plane at ``x``; each is located in the tree (right iff
``coord >= split``; but see the layers below), giving ``k`` voxels (a voxel sampled
twice is searched once but keeps its multiplicity). Voxel ``s`` gives the estimate (3.4) ``sum_p w_p
power_p / dA_s`` over its own front photons within ``r`` of ``x`` (cone weights as
in the m-voxel filter, :mod:`tlm.kernels.estimate`), where ``dA_s`` is the part of the
search disk the voxel covers, measured
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

What the estimate returns (:class:`~tlm.kernels.estimate.Estimate`), its work counts
(``probe_tests`` is this filter's own), its page misses (the distinct leaves, each read once, in
leaf order) and its packet invariance are those of :mod:`tlm.kernels.estimate`, whose
blocks of queries (:data:`~tlm.kernels.estimate.QUERY_BLOCK`) size this filter's too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from tlm.kernels import estimate
from tlm.kernels.bsp import BSPTree
from tlm.kernels.estimate import (
    GATHER_STREAM,
    Estimate,
    LeafPhotons,
    charge_leaves,
    check_cone,
    check_radius,
    empty_estimate,
    gather_inputs,
    gather_pairs,
    per_query,
    weigh_all,
)
from tlm.kernels.memory import Streams
from tlm.kernels.shade import hash_uniform

PROBES = 64  # probe points of the k-voxel filter's area measure
COPLANAR_TOL = 2.0**-32  # flat splits and disks lying on them, relative to the scene's size
_GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


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
    lp, pts, nrm = gather_inputs(position, power, incoming, tree, points, normals, prepared)
    r, cone_k = check_radius(radius), check_cone(cone_k)
    if isinstance(k, bool) or int(k) != k or k < 1:
        raise ValueError(f"k (={k!r}) must be an integer >= 1")
    k = int(k)
    q = pts.shape[1]
    keys = np.arange(q, dtype=np.int64) if keys is None else np.asarray(keys, dtype=np.int64).reshape(-1)
    if keys.shape[0] != q:
        raise ValueError(f"keys must have shape ({q},), got {keys.shape}")
    out = empty_estimate(q)
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
    block = max(1, min(estimate.QUERY_BLOCK // 8, (1 << 18) // max(k, PROBES)))
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
        acc, sums = gather_pairs(lp, pts, nrm, pq + q0, leaf, r, cone_k)
        out.node_visits[sl] = k * tree.levels + extra
        out.leaves_visited[sl] = np.bincount(pq, minlength=m)
        out.photons_tested[sl] = np.bincount(pq, weights=lp.size[leaf], minlength=m)
        out.photons_accepted[sl] = np.bincount(pq, weights=acc, minlength=m)
        out.probe_tests[sl] = PROBES + np.bincount(xrow // PROBES, minlength=m)
        charge_leaves(streams, lp, pq, leaf, out.gather_misses[sl], stream)  # blocks run in order
        if r > 0.0:
            area = norm * frac
            share = mult / k
            for c in range(3):
                e = np.divide(sums[c], area, out=np.zeros_like(area), where=area > 0.0)  # eq. 3.4
                out.density[sl, c] = per_query(pq, e * share, m)  # eq. 3.5
    return weigh_all(out)  # (every accepted photon cone-weighted, as the m-voxel filter's)
