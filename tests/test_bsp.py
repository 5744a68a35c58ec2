"""Algorithm 1 (the balanced BSP of §III.A.1/§III.B.1): layout, splits, contents, memory, work.

The tree is checked against the thesis's rules directly and against an independent,
recursive (node by node, element by element) re-implementation written here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tlm.kernels.bsp import build_point_tree, build_triangle_tree, default_levels
from tlm.scenes.loader import load_scene

# ---------------------------------------------------------------- helpers


def random_soup(seed: int, n: int, size: float = 0.15) -> np.ndarray:
    rng = np.random.default_rng(seed)
    c = rng.uniform(0.0, 1.0, size=(n, 1, 3))
    return c + rng.uniform(-size, size, size=(n, 3, 3))


def node_level(i: int) -> int:
    return (i + 1).bit_length() - 1


def leaf_items(tree, k: int) -> np.ndarray:
    i = tree.leaf_offset + k
    return tree.items[tree.first[i] : tree.last[i]]


def leaf_sets(tree) -> list[set[int]]:
    return [set(leaf_items(tree, k).tolist()) for k in range(tree.n_leaves)]


def hi_is_split(tree) -> np.ndarray:
    """(leaves, 3) bool: the leaf's high face on an axis comes from a split it is left of.

    Algorithm 1 sends an element left when ``lo < split`` and right when ``hi >= split``,
    so a leaf's box is closed on its low faces and on its high faces that are the root's,
    and open on the high faces that are splits.
    """
    out = np.zeros((tree.n_leaves, 3), dtype=bool)
    for k in range(tree.n_leaves):
        i = tree.leaf_offset + k
        while i > 0:
            parent = (i - 1) // 2
            if i == 2 * parent + 1:  # a left child
                out[k, node_level(parent) % 3] = True
            i = parent
    return out


def expected_membership(tree, tlo: np.ndarray, thi: np.ndarray) -> list[set[int]]:
    """Which elements each leaf must hold, from its box and the split rule alone."""
    flags = hi_is_split(tree)
    out = []
    for k in range(tree.n_leaves):
        i = tree.leaf_offset + k
        lo, hi = tree.lo[i], tree.hi[i]
        below = np.where(flags[k], tlo < hi, tlo <= hi)
        ok = np.all(below & (thi >= lo), axis=1)
        out.append(set(np.flatnonzero(ok).tolist()))
    return out


def reference_build(tlo: np.ndarray, thi: np.ndarray, levels: int):
    """Algorithm 1, one node at a time, written out plainly.

    Returns per heap node: split value (NaN on leaves), box lo/hi and the element list.
    """
    n_nodes = (1 << (levels + 1)) - 1
    split = np.full(n_nodes, np.nan)
    lo = np.zeros((n_nodes, 3))
    hi = np.zeros((n_nodes, 3))
    members: list[list[int]] = [[] for _ in range(n_nodes)]
    if tlo.shape[0]:
        lo[0], hi[0] = tlo.min(axis=0), thi.max(axis=0)
    members[0] = list(range(tlo.shape[0]))
    for i in range((1 << levels) - 1):
        axis = node_level(i) % 3
        nlo, nhi = lo[i, axis], hi[i, axis]
        els = members[i]
        if els:
            total = 0.0
            for e in els:  # centre of the element's extent clipped to the node, in id order
                total += 0.5 * (max(tlo[e, axis], nlo) + min(thi[e, axis], nhi))
            s = total / len(els)
        else:
            s = 0.5 * (nlo + nhi)
        s = min(max(s, nlo), nhi)
        split[i] = s
        left, right = 2 * i + 1, 2 * i + 2
        members[left] = [e for e in els if tlo[e, axis] < s]
        members[right] = [e for e in els if thi[e, axis] >= s]
        lo[left], hi[left] = lo[i], hi[i]
        lo[right], hi[right] = lo[i], hi[i]
        hi[left, axis] = s
        lo[right, axis] = s
    return split, lo, hi, members


def descend(tree, p: np.ndarray) -> int:
    """Leaf number a point falls in under the rule ``x >= split`` -> right."""
    i = 0
    for j in range(tree.levels):
        i = 2 * i + (2 if p[j % 3] >= tree.split[i] else 1)
    return i - tree.leaf_offset


# ---------------------------------------------------------------- layout


@pytest.mark.parametrize("levels", [0, 1, 2, 5])
def test_heap_layout(levels):
    tri = random_soup(1, 300)
    tree = build_triangle_tree(tri, levels=levels)
    assert tree.levels == tree.requested_levels == levels
    assert not tree.truncated
    n_nodes = 2 ** (levels + 1) - 1
    assert tree.n_nodes == n_nodes
    for a in (tree.first, tree.last, tree.split):
        assert a.shape == (n_nodes,)
    assert tree.lo.shape == tree.hi.shape == (n_nodes, 3)
    assert tree.n_leaves == 2**levels
    assert tree.leaf_offset == 2**levels - 1
    # split is finite exactly on the inner nodes (levels 0 .. L-1), NaN on the leaves
    for j in range(levels + 1):
        nodes = np.arange(2**j - 1, 2 ** (j + 1) - 1)
        assert np.all(np.isfinite(tree.split[nodes]) == (j < levels))
    # an inner node spans exactly its two children's ranges, which are adjacent
    for i in range(tree.leaf_offset):
        left, right = 2 * i + 1, 2 * i + 2
        assert tree.first[i] == tree.first[left]
        assert tree.last[left] == tree.first[right]
        assert tree.last[i] == tree.last[right]
    # the leaves tile the element buffer in order
    first, last = tree.leaf_ranges()
    assert first[0] == 0
    assert last[-1] == tree.items.shape[0]
    np.testing.assert_array_equal(first[1:], last[:-1])
    assert np.all(last >= first)
    assert tree.first[0] == 0 and tree.last[0] == tree.items.shape[0]


@pytest.mark.parametrize("n", [0, 1, 2, 3, 7, 8, 20, 21, 54, 55, 100, 1000, 2604])
def test_default_levels_floor_ln(n):
    want = math.floor(math.log(n)) if n >= 3 else 0
    assert default_levels(n) == want
    tri = random_soup(2, n, size=0.01)
    tree = build_triangle_tree(tri)
    assert tree.requested_levels == want
    assert tree.levels == want  # small triangles: no truncation
    pts = build_point_tree(tri[:, 0])
    assert pts.requested_levels == pts.levels == want


def test_levels_argument_checked():
    tri = random_soup(3, 10)
    for bad in (-1, 25, 1.5, True, "3"):
        with pytest.raises(ValueError):
            build_triangle_tree(tri, levels=bad)
    with pytest.raises(ValueError):
        build_triangle_tree(tri, memory_factor=0.5)


# ---------------------------------------------------------------- splits and boxes


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_split_axis_and_child_boxes(seed):
    tri = random_soup(seed, 400, size=0.2)
    tree = build_triangle_tree(tri, levels=6)
    flat = tri.reshape(-1, 3)
    np.testing.assert_array_equal(tree.lo[0], flat.min(axis=0))
    np.testing.assert_array_equal(tree.hi[0], flat.max(axis=0))
    for i in range(tree.leaf_offset):
        axis = node_level(i) % 3
        s = tree.split[i]
        assert tree.lo[i, axis] <= s <= tree.hi[i, axis]
        left, right = 2 * i + 1, 2 * i + 2
        others = [a for a in range(3) if a != axis]
        # left child = parent box with hi[axis] = split; right child: lo[axis] = split
        assert tree.hi[left, axis] == s and tree.lo[right, axis] == s
        assert tree.lo[left, axis] == tree.lo[i, axis]
        assert tree.hi[right, axis] == tree.hi[i, axis]
        for c in (left, right):
            np.testing.assert_array_equal(tree.lo[c, others], tree.lo[i, others])
            np.testing.assert_array_equal(tree.hi[c, others], tree.hi[i, others])


def test_split_is_centre_of_mass_hand_built():
    """Four boxes-shaped triangles with known extents; splits computed by hand."""
    def tri(x0, x1, y0, y1, z0=0.0, z1=1.0):
        # a triangle whose bounding box is exactly [x0,x1] x [y0,y1] x [z0,z1]
        return [[x0, y0, z0], [x1, y1, z0], [x0, y1, z1]]

    t = np.array(
        [tri(0, 1, 0, 2), tri(2, 3, 4, 8), tri(4, 6, 1, 3), tri(9, 10, 0, 10)], dtype=np.float64
    )
    tree = build_triangle_tree(t, levels=2)
    # level 0, axis x: centres 0.5, 2.5, 5, 9.5 -> 17.5 / 4
    s0 = (0.5 + 2.5 + 5.0 + 9.5) / 4
    assert tree.split[0] == pytest.approx(s0, rel=1e-15)  # 4.375
    # left child x in [0, 4.375]: triangles 0, 1, 2 (x_lo < 4.375); 2 straddles
    # right child x in [4.375, 10]: triangles 2, 3
    # level 1, axis y, node 1: y in [0, 10], centres 1, 6, 2 -> 3
    assert tree.split[1] == pytest.approx(3.0, rel=1e-15)
    # node 2: centres 2 (tri 2), 5 (tri 3) -> 3.5
    assert tree.split[2] == pytest.approx(3.5, rel=1e-15)
    got = leaf_sets(tree)
    # node 1 split y=3: left (y_lo < 3) {0, 2}, right (y_hi >= 3) {1, 2}
    # node 2 split y=3.5: left {2, 3}, right {3}
    assert got == [{0, 2}, {1, 2}, {2, 3}, {3}]
    assert tree.work[0].expansion_copies == 1 and tree.work[1].expansion_copies == 2


def test_triangle_centre_is_clipped_to_the_node():
    """A triangle straddling into a node weighs at its extent clipped to that node."""
    big = [[0.0, 0.0, 0.0], [10.0, 1.0, 0.0], [0.0, 1.0, 1.0]]  # x in [0, 10]
    small = [[8.0, 0.0, 0.0], [9.0, 1.0, 0.0], [8.0, 1.0, 1.0]]  # x in [8, 9]
    t = np.array([big, small])
    tree = build_triangle_tree(t, levels=4)
    s0 = (5.0 + 8.5) / 2  # 6.75
    assert tree.split[0] == pytest.approx(s0, rel=1e-15)
    # level 3 is x again; node 7 (left, left, left) has x in [0, 6.75] and only `big`,
    # whose clipped centre is 6.75 / 2, not 5
    assert tree.split[7] == pytest.approx(s0 / 2, rel=1e-15)
    # node 14 (right, right, right): x in [6.75, 10], both; centres (6.75+10)/2 and 8.5
    assert tree.split[14] == pytest.approx(((6.75 + 10.0) / 2 + 8.5) / 2, rel=1e-15)


def test_point_split_is_mean():
    p = np.array([[0.0, 0, 0], [1.0, 5, 0], [2.0, 1, 0], [7.0, 2, 0]])
    tree = build_point_tree(p, levels=2)
    assert tree.split[0] == pytest.approx(2.5)
    # left: x < 2.5 -> points 0, 1, 2 -> y mean 2; right: point 3 -> y 2
    assert tree.split[1] == pytest.approx(2.0)
    assert tree.split[2] == pytest.approx(2.0)
    assert leaf_sets(tree) == [{0, 2}, {1}, set(), {3}]


@pytest.mark.parametrize("seed,n,levels,size", [(0, 50, 3, 0.3), (1, 300, 6, 0.1), (2, 120, 8, 0.25)])
def test_matches_recursive_reference(seed, n, levels, size):
    tri = random_soup(seed, n, size=size)
    tlo, thi = tri.min(axis=1), tri.max(axis=1)
    tree = build_triangle_tree(tri, levels=levels, memory_factor=1000)
    assert tree.levels == levels
    split, lo, hi, members = reference_build(tlo, thi, levels)
    np.testing.assert_allclose(tree.split, split, rtol=1e-14, atol=0, equal_nan=True)
    np.testing.assert_allclose(tree.lo, lo, rtol=1e-14, atol=0)
    np.testing.assert_allclose(tree.hi, hi, rtol=1e-14, atol=0)
    for k in range(tree.n_leaves):
        np.testing.assert_array_equal(leaf_items(tree, k), members[tree.leaf_offset + k])


# ---------------------------------------------------------------- contents


@pytest.mark.parametrize("seed,levels", [(0, 0), (0, 1), (1, 4), (2, 7), (3, None)])
def test_leaves_hold_exactly_the_overlapping_triangles(seed, levels):
    """Random soup: a triangle is in a leaf iff its AABB overlaps the leaf's closed box."""
    tri = random_soup(seed, 500)
    tlo, thi = tri.min(axis=1), tri.max(axis=1)
    tree = build_triangle_tree(tri, levels=levels)
    for k in range(tree.n_leaves):
        i = tree.leaf_offset + k
        items = leaf_items(tree, k)
        overlap = np.all((tlo <= tree.hi[i]) & (thi >= tree.lo[i]), axis=1)
        assert set(items.tolist()) == set(np.flatnonzero(overlap).tolist()), k


@pytest.mark.slow
@pytest.mark.parametrize("name", ["cornell", "ring", "room"])
def test_scene_leaves_follow_the_split_rule(name):
    """Thesis scenes (axis-aligned, coplanar geometry): membership per the x<s / x>=s rule.

    Every entry overlaps its leaf's closed box, and every triangle whose AABB overlaps a
    leaf's box is in it, except where it only touches a high face that is a split
    (``lo == split`` goes right only, per Algorithm 1).
    """
    tri = load_scene(name).triangles
    tlo, thi = tri.min(axis=1), tri.max(axis=1)
    tree = build_triangle_tree(tri)
    expected = expected_membership(tree, tlo, thi)
    for k in range(tree.n_leaves):
        i = tree.leaf_offset + k
        items = leaf_items(tree, k)
        assert np.all((tlo[items] <= tree.hi[i]) & (thi[items] >= tree.lo[i]))
        assert set(items.tolist()) == expected[k], k
    # every point of a triangle's AABB is in a leaf (by the descent rule) that holds it
    rng = np.random.default_rng(5)
    sample = rng.choice(tri.shape[0], size=min(400, tri.shape[0]), replace=False)
    sets = leaf_sets(tree)
    for t in sample:
        w = rng.dirichlet([1, 1, 1], size=3)
        for p in [*tri[t], *(w @ tri[t]), tri[t].mean(axis=0)]:
            p = np.clip(p, tlo[t], thi[t])  # rounding may step off a flat triangle's plane
            assert t in sets[descend(tree, p)]


@pytest.mark.parametrize("seed,levels", [(0, 3), (1, 6), (4, None)])
def test_random_soup_follows_split_rule_too(seed, levels):
    tri = random_soup(seed, 300, size=0.3)
    tree = build_triangle_tree(tri, levels=levels)
    expected = expected_membership(tree, tri.min(axis=1), tri.max(axis=1))
    assert leaf_sets(tree) == expected


@pytest.mark.slow
@pytest.mark.parametrize("levels", [2, 5, None])
def test_leaf_items_ascending_stable(levels):
    tri = random_soup(7, 400, size=0.25)
    tree = build_triangle_tree(tri, levels=levels)
    for k in range(tree.n_leaves):
        items = leaf_items(tree, k)
        assert np.all(np.diff(items) > 0), k  # ascending, and no duplicates in a leaf
    for name in ("cornell", "room"):
        tree = build_triangle_tree(load_scene(name).triangles)
        for k in range(tree.n_leaves):
            assert np.all(np.diff(leaf_items(tree, k)) > 0)


def test_every_triangle_is_somewhere():
    tri = random_soup(8, 250)
    tree = build_triangle_tree(tri, levels=5)
    np.testing.assert_array_equal(np.unique(tree.items), np.arange(250))
    assert tree.items.dtype == np.int64


# ---------------------------------------------------------------- memory reservation


def test_memory_reservation_truncates():
    rng = np.random.default_rng(0)
    n = 40
    # huge triangles, each spanning the whole box: every one straddles every split
    base = np.array([[[-10.0, -10, -10], [10, 10, -10], [10, -10, 10]]])
    tri = base + rng.uniform(-0.1, 0.1, size=(n, 3, 3))
    tree = build_triangle_tree(tri, levels=6, memory_factor=3.0)
    assert tree.truncated
    assert tree.requested_levels == 6
    assert tree.levels < tree.requested_levels
    assert tree.levels == 1  # level 0 doubles to 2n <= 3n; level 1 would need 4n
    assert tree.capacity == 3 * n
    assert tree.items.shape[0] <= tree.capacity
    assert tree.n_nodes == 2 ** (tree.levels + 1) - 1
    assert len(tree.work) == tree.levels
    assert np.all(np.isnan(tree.split[tree.leaf_offset :]))
    st = tree.stats()
    assert st["truncated"] is True
    assert st["slots_used"] <= st["slots_reserved"]
    # the tree that was built is still a correct tree
    expected = expected_membership(tree, tri.min(axis=1), tri.max(axis=1))
    assert leaf_sets(tree) == expected
    # with the thesis's 20x it goes deeper, still never over the reservation
    deep = build_triangle_tree(tri, levels=6, memory_factor=20.0)
    assert deep.levels == 4 and deep.truncated
    assert deep.items.shape[0] <= deep.capacity == 20 * n


def test_memory_factor_one_with_disjoint_triangles():
    tri = random_soup(9, 200, size=1e-4)
    tree = build_triangle_tree(tri, levels=5, memory_factor=1.0)
    assert tree.items.shape[0] <= tree.capacity == 200
    # tiny disjoint triangles rarely straddle; whatever depth it reached is consistent
    assert tree.levels <= 5
    assert tree.truncated == (tree.levels < 5)


# ---------------------------------------------------------------- point tree


@pytest.mark.parametrize("seed,n,levels", [(0, 1000, None), (1, 37, 4), (2, 500, 9)])
def test_point_tree_each_point_once_in_its_box(seed, n, levels):
    p = np.random.default_rng(seed).normal(size=(n, 3))
    tree = build_point_tree(p, levels=levels)
    assert tree.items.shape[0] == n
    np.testing.assert_array_equal(np.sort(tree.items), np.arange(n))
    assert all(w.expansion_copies == 0 for w in tree.work)
    for k in range(tree.n_leaves):
        i = tree.leaf_offset + k
        items = leaf_items(tree, k)
        assert np.all(np.diff(items) > 0)
        q = p[items]
        assert np.all((q >= tree.lo[i]) & (q <= tree.hi[i]))
        for e in items[:5]:
            assert descend(tree, p[e]) == k
    split, _lo, _hi, members = reference_build(p, p, tree.levels)
    np.testing.assert_allclose(tree.split, split, rtol=1e-13, equal_nan=True)
    for k in range(tree.n_leaves):
        np.testing.assert_array_equal(leaf_items(tree, k), members[tree.leaf_offset + k])


@pytest.mark.parametrize(
    "points",
    [
        np.zeros((0, 3)),
        np.array([[1.0, 2.0, 3.0]]),
        np.array([[1.0, 2.0, 3.0], [1.0, 2.0, 3.0]]),
        np.array([[0.0, 0, 0], [1, 1, 1], [2, 0, 1]]),
        np.tile([[0.5, -0.25, 4.0]], (200, 1)),  # coincident
        np.c_[np.random.default_rng(1).normal(size=(300, 2)), np.zeros(300)],  # one plane
        np.c_[np.zeros(100), np.zeros(100), np.linspace(0, 1, 100)],  # one line
    ],
    ids=["0", "1", "2-coincident", "3", "200-coincident", "plane", "line"],
)
@pytest.mark.parametrize("levels", [None, 6])
def test_point_tree_degenerate_inputs(points, levels):
    tree = build_point_tree(points, levels=levels)
    n = points.shape[0]
    want = default_levels(n) if levels is None else levels
    assert tree.levels == want  # bounded depth, whatever the data
    assert tree.n_nodes == 2 ** (want + 1) - 1
    assert tree.items.shape[0] == n
    np.testing.assert_array_equal(np.sort(tree.items), np.arange(n))
    assert np.all(np.isfinite(tree.lo)) and np.all(np.isfinite(tree.hi))
    assert np.all(np.isfinite(tree.split[: tree.leaf_offset]))
    for k in range(tree.n_leaves):
        i = tree.leaf_offset + k
        q = points[leaf_items(tree, k)]
        assert np.all((q >= tree.lo[i]) & (q <= tree.hi[i]))
    sizes = tree.last[tree.leaf_offset :] - tree.first[tree.leaf_offset :]
    assert sizes.sum() == n


def test_coincident_points_all_in_one_leaf():
    p = np.tile([[1.0, 1.0, 1.0]], (50, 1))
    tree = build_point_tree(p)
    sizes = tree.last[tree.leaf_offset :] - tree.first[tree.leaf_offset :]
    assert sorted(sizes.tolist())[-1] == 50  # x >= split -> right: all in the last leaf
    assert sizes[-1] == 50


@pytest.mark.parametrize("n", [0, 1, 2, 3])
def test_tiny_triangle_trees(n):
    tri = random_soup(3, n)
    for levels in (None, 0, 3):
        tree = build_triangle_tree(tri, levels=levels)
        assert tree.n_elements == n
        assert set(tree.items.tolist()) == set(range(n))


# ---------------------------------------------------------------- work records


@pytest.mark.parametrize("kind", ["triangles", "points", "scene"])
def test_level_work_adds_up(kind):
    if kind == "triangles":
        tree = build_triangle_tree(random_soup(4, 300, size=0.3), levels=7)
    elif kind == "points":
        tree = build_point_tree(np.random.default_rng(4).uniform(size=(700, 3)), levels=7)
    else:
        tree = build_triangle_tree(load_scene("cornell").triangles)
    assert len(tree.work) == tree.levels
    n_in = tree.n_elements
    for j, w in enumerate(tree.work):
        assert w.level == j
        assert w.nodes == 2**j
        assert w.elements_in == n_in
        assert w.storage_reads == 2 * w.elements_in
        assert w.elements_out - w.elements_in == w.expansion_copies
        assert w.expansion_copies >= 0
        if kind == "points":
            assert w.expansion_copies == 0
        n_in = w.elements_out
    assert n_in == tree.items.shape[0]
    assert tree.items.shape[0] <= tree.capacity


@pytest.mark.parametrize("n", [1, 2, 7, 5000])
def test_bounds_are_numpys_reduction_over_the_rows(n):
    from tlm.kernels.bsp import bounds

    rng = np.random.default_rng(n)
    p = rng.normal(size=(n, 3)) * [1.0, 1e-300, 1e300]
    p[rng.random((n, 3)) < 0.1] = np.inf
    p[rng.random((n, 3)) < 0.1] = 0.0  # (zeros of both signs: equal values, a zero's sign may differ)
    p[rng.random((n, 3)) < 0.1] = -0.0
    lo, hi = bounds(p)
    assert lo.tolist() == p.min(axis=0).tolist() and hi.tolist() == p.max(axis=0).tolist()
    assert lo.shape == hi.shape == (3,) and lo.dtype == hi.dtype == np.float64
