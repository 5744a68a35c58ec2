"""The balanced axis-aligned BSP tree of thesis Algorithm 1 ("Fig. 7"), for points and triangles.

The thesis builds one structure for photons (§III.A.1) and, with an extra expansion
pass, for triangles (§III.B.1):

* nodes live in a heap: node ``i`` has children ``2i+1`` and ``2i+2``; level ``j``
  holds nodes ``2**j - 1 .. 2**(j+1) - 2``; each node is ``(first, last, split)``,
  two indices into the element list and the partition value;
* level ``j`` splits along axis ``j mod 3`` at the *centre of mass* of the node's
  elements (equal weights), not the median;
* a node's elements are written to a second buffer ``P'`` in two storage passes, the
  left child's (``x < split``) then the right child's (``x >= split``), keeping their
  order (a stable partition); then ``P`` and ``P'`` swap;
* for triangles, a triangle that straddles the split is copied into both children
  (the expansion pass); the thesis reserves 20x the triangle list for the copies;
* ``floor(ln n)`` levels by default.

Everything here is vectorized per level: one pass over all the nodes of a level, no
recursion and no Python loop over nodes or elements. The per-element passes run
compiled (:mod:`tlm.kernels._jit_bsp`, numba) unless ``TLM_KERNELS=numpy`` selects the
numpy reference; the two build bit-identical trees. The builder also
returns, per level, the work the Vertex PM does (elements read by the centre-of-mass
pass, read by the two storage passes, written, and copied by the expansion), which the
timing model turns into cycles.

Memory reservation (documented behaviour): when the expansion of a level would need
more than ``memory_factor * n`` element slots, that level is not built and the tree
stops one level early; ``BSPTree.truncated`` says so and ``levels`` is the depth built,
``requested_levels`` the depth asked for.

Centre of mass of triangles: the mass of a triangle inside a node is taken at the
centre of its bounding box clipped to the node's box, so that the split of a node
always lies inside the node (a triangle that straddles into a sibling does not drag
the split outside the region being divided).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from tlm.kernels import threads
from tlm.kernels.engine import engine


def default_levels(n: int) -> int:
    """The thesis's depth, ``floor(ln n)`` (0 for n < 3)."""
    return math.floor(math.log(n)) if n >= 3 else 0


@dataclass(frozen=True)
class LevelWork:
    """What one level of Algorithm 1 did (the Vertex PM's work items)."""

    level: int
    nodes: int
    elements_in: int  # elements of the level (read once by the centre-of-mass pass)
    storage_reads: int  # elements read by the left and right storage passes (2x in)
    elements_out: int  # elements written to P'
    expansion_copies: int  # elements_out - elements_in (triangles copied to both sides)


@dataclass(frozen=True)
class BSPTree:
    """A built tree. Arrays are heap-indexed over ``2**(levels+1) - 1`` nodes.

    first, last : (nodes,) int64, the node's element range ``items[first:last]``
        (``last`` exclusive).
    split : (nodes,) float64, partition value (NaN on leaves); axis is level mod 3.
    lo, hi : (nodes, 3) float64, the node's closed box.
    items : (m,) int64, element ids (photon or triangle ids) in the final buffer order;
        for triangles ``m >= n`` because of the expansion copies.
    """

    levels: int
    requested_levels: int
    first: np.ndarray
    last: np.ndarray
    split: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    items: np.ndarray
    n_elements: int
    capacity: int
    truncated: bool
    work: tuple[LevelWork, ...]

    @property
    def n_nodes(self) -> int:
        return int(self.first.shape[0])

    @property
    def n_leaves(self) -> int:
        return 1 << self.levels

    @property
    def leaf_offset(self) -> int:
        """Heap index of the first leaf."""
        return (1 << self.levels) - 1

    def leaf_ranges(self) -> tuple[np.ndarray, np.ndarray]:
        off = self.leaf_offset
        return self.first[off:], self.last[off:]

    def stats(self) -> dict:
        sizes = self.last[self.leaf_offset :] - self.first[self.leaf_offset :]
        return {
            "levels": self.levels,
            "requested_levels": self.requested_levels,
            "truncated": self.truncated,
            "nodes": self.n_nodes,
            "leaves": self.n_leaves,
            "elements": self.n_elements,
            "slots_used": int(self.items.shape[0]),
            "slots_reserved": self.capacity,
            "expansion": float(self.items.shape[0] / max(self.n_elements, 1)),
            "leaf_size_mean": float(sizes.mean()) if sizes.size else 0.0,
            "leaf_size_max": int(sizes.max()) if sizes.size else 0,
            "empty_leaves": int((sizes == 0).sum()),
        }


def _check_levels(levels: int | None, n: int) -> int:
    if levels is None:
        return default_levels(n)
    if isinstance(levels, bool) or not isinstance(levels, (int, np.integer)):
        raise ValueError(f"levels (={levels!r}) must be an integer or None")
    if levels < 0 or levels > 24:
        raise ValueError(f"levels (={levels}) must be between 0 and 24")
    return int(levels)


GROUP_MIN_ELEMENTS = 1 << 15  # a level's elements a thread's group of nodes holds at least


def _node_groups(starts: np.ndarray, n: int) -> list[tuple[int, int]]:
    """The buffer ``0 .. n`` cut into ranges of whole nodes (``starts``: each node's
    first element, ascending), about equal, one per thread of :func:`threads.current`
    (one range on one thread, or for a level of fewer elements or nodes)."""
    parts = min(threads.current(), n // GROUP_MIN_ELEMENTS, starts.shape[0])
    if parts <= 1:
        return [(0, n)]
    cuts = starts[np.minimum(np.searchsorted(starts, n * np.arange(1, parts) // parts), starts.shape[0] - 1)]
    bounds = np.unique(np.concatenate([[0], cuts, [n]]))
    return [(int(a), int(b)) for a, b in itertools.pairwise(bounds)]


def _each(kernel, groups: list[tuple[int, int]], before: tuple, after: tuple) -> None:
    """``kernel(*before, lo, hi, *after)`` of every group ``(lo, hi)``, on the threads
    when there are several."""
    for _ in threads.ordered(lambda g: kernel(*before, *g, *after), groups):
        pass


def _build(
    key_lo: np.ndarray,
    key_hi: np.ndarray,
    root_lo: np.ndarray,
    root_hi: np.ndarray,
    levels: int,
    capacity: int,
) -> BSPTree:
    """Algorithm 1 over elements with extents ``[key_lo, key_hi]`` (equal for points).

    An element goes left when ``key_lo[axis] < split`` and right when
    ``key_hi[axis] >= split``: for points exactly one of the two, for triangles both
    when the triangle straddles the split (the expansion pass).
    """
    n = key_lo.shape[0]
    points = key_lo is key_hi
    n_nodes_max = (1 << (levels + 1)) - 1
    first = np.zeros(n_nodes_max, dtype=np.int64)
    last = np.zeros(n_nodes_max, dtype=np.int64)
    split = np.full(n_nodes_max, np.nan)
    lo = np.empty((n_nodes_max, 3))
    hi = np.empty((n_nodes_max, 3))
    lo[0], hi[0] = root_lo, root_hi
    last[0] = n

    items = np.arange(n, dtype=np.int64)  # buffer P
    # node label (index within its level) of every element of P
    label = np.zeros(n, dtype=np.int64)
    lo_cols = [np.ascontiguousarray(key_lo[:, k]) for k in range(3)]
    hi_cols = lo_cols if points else [np.ascontiguousarray(key_hi[:, k]) for k in range(3)]
    jit = None
    if engine() == "numba" and n > 0:
        from tlm.kernels import _jit_bsp as jit
    work: list[LevelWork] = []
    built = 0
    for j in range(levels):
        axis = j % 3
        k0 = (1 << j) - 1
        nodes = 1 << j
        nlo = lo[k0 : k0 + nodes, axis]
        nhi = hi[k0 : k0 + nodes, axis]
        if jit is not None:  # the same passes, compiled (tlm/kernels/_jit_bsp.py), in groups of whole nodes
            n_in = items.shape[0]
            groups = _node_groups(first[k0 : k0 + nodes], n_in)
            counts = np.zeros(nodes, dtype=np.int64)
            sums = np.zeros(nodes)
            _each(jit.level_sums, groups, (items, label, lo_cols[axis], hi_cols[axis], nlo, nhi),
                  (counts, sums, points))
        else:
            x_lo = lo_cols[axis][items]
            x_hi = x_lo if points else hi_cols[axis][items]
            # pass 1: centre of mass of every node of the level
            if points:
                c = x_lo
            else:
                c = 0.5 * (np.maximum(x_lo, nlo[label]) + np.minimum(x_hi, nhi[label]))
            counts = np.bincount(label, minlength=nodes)
            sums = np.bincount(label, weights=c, minlength=nodes)
            n_in = c.shape[0]
        with np.errstate(invalid="ignore", divide="ignore"):
            com = sums / counts
        s = np.where(counts > 0, com, 0.5 * (nlo + nhi))
        s = np.minimum(np.maximum(s, nlo), nhi)  # rounding never leaves the node
        # passes 2 and 3: left child's elements, then the right child's, stable
        if jit is not None:
            side = np.empty(n_in, dtype=np.uint8)
            n_left = np.zeros(nodes, dtype=np.int64)
            n_right = np.zeros(nodes, dtype=np.int64)
            _each(jit.level_sides, groups, (items, label, lo_cols[axis], hi_cols[axis], s),
                  (side, n_left, n_right, points))
            n_out = int(n_left.sum() + n_right.sum())
            if n_out > capacity:
                break  # the expansion would overflow the reserved memory: stop here
            put_left = np.cumsum(n_left + n_right) - (n_left + n_right)
            put_right = put_left + n_left
            new_items = np.empty(n_out, dtype=np.int64)
            new_label = np.empty(n_out, dtype=np.int64)
            _each(jit.level_write, groups, (items, label, side), (put_left, put_right, new_items, new_label))
            del side
            items, label = new_items, new_label  # swap P <=> P'
            child_counts = np.empty(2 * nodes, dtype=np.int64)
            child_counts[0::2], child_counts[1::2] = n_left, n_right
        else:
            s_el = s[label]
            go_left = x_lo < s_el
            go_right = ~go_left if points else x_hi >= s_el
            n_out = int(go_left.sum() + go_right.sum())
            if n_out > capacity:
                break  # the expansion would overflow the reserved memory: stop here
            child_label = np.concatenate([2 * label[go_left], 2 * label[go_right] + 1])
            child_items = np.concatenate([items[go_left], items[go_right]])
            order = np.argsort(child_label, kind="stable")
            items = child_items[order]  # swap P <=> P'
            label = child_label[order]
            child_counts = np.bincount(label, minlength=2 * nodes)
        split[k0 : k0 + nodes] = s
        # children boxes and ranges
        c0 = 2 * k0 + 1
        cnodes = 2 * nodes
        ends = np.cumsum(child_counts)
        first[c0 : c0 + cnodes] = ends - child_counts
        last[c0 : c0 + cnodes] = ends
        parent_lo = np.repeat(lo[k0 : k0 + nodes], 2, axis=0)
        parent_hi = np.repeat(hi[k0 : k0 + nodes], 2, axis=0)
        s2 = np.repeat(s, 2)
        parent_hi[0::2, axis] = s2[0::2]
        parent_lo[1::2, axis] = s2[1::2]
        lo[c0 : c0 + cnodes] = parent_lo
        hi[c0 : c0 + cnodes] = parent_hi
        # the parents' ranges in the final buffer are set below
        work.append(
            LevelWork(
                level=j,
                nodes=nodes,
                elements_in=int(n_in),
                storage_reads=2 * int(n_in),
                elements_out=int(n_out),
                expansion_copies=int(n_out) - int(n_in),
            )
        )
        built = j + 1

    n_nodes = (1 << (built + 1)) - 1
    first, last, split = first[:n_nodes].copy(), last[:n_nodes].copy(), split[:n_nodes].copy()
    split[(1 << built) - 1 :] = np.nan
    # Inner nodes' (first, last) index the leaves' final buffer: a node spans from its
    # leftmost leaf's first to its rightmost leaf's last (with copies counted).
    for j in range(built - 1, -1, -1):
        k0, nodes = (1 << j) - 1, 1 << j
        c0 = 2 * k0 + 1
        first[k0 : k0 + nodes] = first[c0 : c0 + 2 * nodes : 2]
        last[k0 : k0 + nodes] = last[c0 + 1 : c0 + 2 * nodes : 2]
    return BSPTree(
        levels=built,
        requested_levels=levels,
        first=first,
        last=last,
        split=split,
        lo=lo[:n_nodes].copy(),
        hi=hi[:n_nodes].copy(),
        items=items,
        n_elements=n,
        capacity=capacity,
        truncated=built < levels,
        work=tuple(work),
    )


def bounds(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(points.min(axis=0), points.max(axis=0))`` of (n, 3) points (n >= 1), equal
    values (where a column's extreme is a zero held as both 0.0 and -0.0, its sign may
    differ: the box is the same), column by column, several times faster than numpy's
    reduction over the rows of an (n, 3) array (a serial step of every render that holds
    the other threads)."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    return (np.array([p[:, k].min() for k in range(3)]), np.array([p[:, k].max() for k in range(3)]))


def build_point_tree(points: np.ndarray, levels: int | None = None) -> BSPTree:
    """Algorithm 1 over points (photons): every point ends in exactly one leaf.

    points : (n, 3) float64, finite.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    n = p.shape[0]
    levels = _check_levels(levels, n)
    if n == 0:
        root_lo = root_hi = np.zeros(3)
    else:
        root_lo, root_hi = bounds(p)
    return _build(p, p, root_lo, root_hi, levels, capacity=max(n, 1))


def build_triangle_tree(
    triangles: np.ndarray, levels: int | None = None, memory_factor: float = 20.0
) -> BSPTree:
    """Algorithm 1 plus the expansion pass over triangles (§III.B.1).

    triangles : (n, 3, 3) float64, finite.
    memory_factor : element slots reserved per triangle (the thesis: 20).
    """
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    n = tri.shape[0]
    levels = _check_levels(levels, n)
    if not memory_factor >= 1.0:
        raise ValueError(f"memory_factor (={memory_factor}) must be >= 1")
    # each triangle's box (tri.min(axis=1), tri.max(axis=1): the same values, faster)
    tmin = np.minimum(np.minimum(tri[:, 0], tri[:, 1]), tri[:, 2])
    tmax = np.maximum(np.maximum(tri[:, 0], tri[:, 1]), tri[:, 2])
    if n == 0:
        root_lo = root_hi = np.zeros(3)
    else:
        root_lo = np.array([tmin[:, k].min() for k in range(3)])  # (bounds, one side each)
        root_hi = np.array([tmax[:, k].max() for k in range(3)])
    capacity = math.floor(memory_factor * max(n, 1))
    return _build(tmin, tmax, root_lo, root_hi, levels, capacity=capacity)
