"""Stiff geometry: closed meshes hit through shared edges and vertices, rays in a
triangle's plane, axis-parallel rays with -0.0, origins on BSP split planes,
zero-thickness voxels, degenerate and sliver triangles, and tree depth.

Each test states the behaviour it expects in its docstring. Tolerances: hit distances
are recomputed in float64 from eq. 3.6, so where the answer is exact in real numbers
(a target point on a convex surface, an axis-aligned plane) we ask for 1e-9 relative;
where the float32 decision may pick either of two triangles meeting at an edge, we
ask for the same distance (a tie), not the same triangle.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from tlm.kernels.intersect import brute_force
from tlm.kernels.traverse import any_hit, build_accel, closest_hit
from tlm.scenes.builders import cornell
from tlm.scenes.shapes import aabox, quad, uv_sphere

from .util import no_nan_hits, rotation

LEVELS = [0, 1, 3, None, 9]


def unique_vertices(tri: np.ndarray) -> np.ndarray:
    return np.unique(tri.reshape(-1, 3), axis=0)


def edge_points(tri: np.ndarray, fractions=(0.5, 0.25, 1.0 / 3.0)) -> np.ndarray:
    """Points on every edge of every triangle (shared edges, diagonals included)."""
    out = []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        for f in fractions:
            out.append(tri[:, a] + f * (tri[:, b] - tri[:, a]))
    return np.concatenate(out)


def assert_all_hit_at(accel, o, d, t_expected, rtol=1e-9):
    h = closest_hit(accel, o, d)
    no_nan_hits(h)
    miss = np.flatnonzero(h.triangle < 0)
    assert miss.shape[0] == 0, f"{miss.shape[0]} of {o.shape[0]} rays leaked, first {o[miss[0]]} -> {d[miss[0]]}"
    np.testing.assert_allclose(h.t, t_expected, rtol=rtol)
    occ = any_hit(accel, o, d)
    assert occ.occluded.all(), f"any_hit: {(~occ.occluded).sum()} rays leaked"
    return h


# ---------------------------------------------------------------- closed meshes


@pytest.mark.parametrize("levels", LEVELS)
def test_closed_box_through_shared_vertices_and_edges(levels):
    """A tessellated box (4 x 4 cells a face, vertices on a 0.5 grid, exactly
    representable): rays from inside aimed exactly at every vertex (box corners shared by
    3 faces, seam vertices by up to 6 triangles) and at points on every edge
    (diagonals, face seams, box edges) never miss, and hit at the target (t = 1).
    any_hit agrees."""
    tri = aabox([-1.0, -1.0, -1.0], [1.0, 1.0, 1.0], n=4)
    accel = build_accel(tri, levels=levels)
    targets = np.concatenate([unique_vertices(tri), edge_points(tri)])
    rng = np.random.default_rng(1)
    origins = np.concatenate([
        np.zeros((1, 3)),  # the centre: lies on the root split planes
        [[0.5, 0.0, 0.0], [0.0, -0.5, 0.5], [0.5, 0.5, 0.5]],  # on tessellation lines
        rng.uniform(-0.9, 0.9, size=(4, 3)),
    ])
    for o in origins:
        oo = np.broadcast_to(o, targets.shape)
        assert_all_hit_at(accel, oo, targets - oo, np.ones(targets.shape[0]))


@pytest.mark.parametrize("levels", LEVELS)
def test_box_exit_through_its_corners_and_edges(levels):
    """From the centre of a tessellated box, the 8 diagonal directions (+-1, +-1, +-1)
    leave exactly through the corners and the 12 directions (+-1, +-1, 0) exactly
    through the middles of the box edges, with +0.0 and -0.0 in the zero slot: all hit
    at t = 1 and the sign of zero changes neither the triangle nor t."""
    tri = aabox([-2.0, -2.0, -2.0], [2.0, 2.0, 2.0], n=3)
    accel = build_accel(tri, levels=levels)
    corners = np.array(list(itertools.product([-2.0, 2.0], repeat=3)))
    edges = []
    for k in range(3):
        for s in itertools.product([-2.0, 2.0], repeat=2):
            e = np.zeros(3)
            e[[i for i in range(3) if i != k]] = s
            edges.append(e)
    edges = np.array(edges)
    d = np.concatenate([corners, edges])
    o = np.zeros_like(d)
    h = assert_all_hit_at(accel, o, d, np.ones(d.shape[0]))
    d_neg = np.where(d == 0.0, -0.0, d)
    h_neg = closest_hit(accel, o, d_neg)
    np.testing.assert_array_equal(h_neg.triangle, h.triangle)
    np.testing.assert_array_equal(h_neg.t, h.t)


@pytest.mark.parametrize("levels", [0, 2, None])
@pytest.mark.parametrize("where", ["origin", "far"])
def test_closed_sphere_through_vertices_never_leaks(levels, where):
    """A UV sphere (poles: 16 triangles share one vertex), rotated off the axes and
    optionally moved 1e5 from the world origin: rays from interior points aimed at every
    vertex and at points on every edge never miss, and hit at the target to 1e-6
    (the facets are convex, so the target is the first hit). From outside, rays that
    enter through the same points (aimed through them at an interior point) always hit,
    at the target: no leak between the triangles around a vertex or along an edge."""
    shift = np.zeros(3) if where == "origin" else np.array([1e5, -3e4, 7e4])
    rot = rotation([1.0, 2.0, 3.0], 37.0)
    tri = uv_sphere((0.0, 0.0, 0.0), 1.0, 16, 8) @ rot.T + shift
    accel = build_accel(tri, levels=levels)
    targets = np.concatenate([unique_vertices(tri), edge_points(tri, (0.5, 0.1))])
    rng = np.random.default_rng(2)
    for o in np.concatenate([shift[None], shift + rng.uniform(-0.4, 0.4, size=(3, 3))]):
        oo = np.broadcast_to(o, targets.shape)
        assert_all_hit_at(accel, oo, targets - oo, np.ones(targets.shape[0]), rtol=1e-6)
    inner = shift + rng.uniform(-0.5, 0.5, size=targets.shape)
    outside = targets + 2.0 * (targets - inner)
    assert_all_hit_at(accel, outside, targets - outside, np.ones(targets.shape[0]), rtol=1e-6)


# ---------------------------------------------------------------- rays in a triangle's plane


@pytest.mark.parametrize("levels", [0, 2, None])
def test_rays_in_the_plane_of_a_floor_pass_over_it(levels):
    """A tessellated floor y = 0 and a wall x = 3: rays lying in the floor's plane
    (starting on the floor, on its seams, or beyond it) never hit a floor triangle
    (they are parallel to it) and hit the wall where a straight line meets it."""
    floor = quad([-2.0, 0.0, -2.0], [0.0, 0.0, 4.0], [4.0, 0.0, 0.0], 8, 8)
    wall = quad([3.0, -1.0, -10.0], [0.0, 2.0, 0.0], [0.0, 0.0, 20.0], 2, 2)
    tri = np.concatenate([floor, wall])
    accel = build_accel(tri, levels=levels)
    rng = np.random.default_rng(3)
    n = 400
    o = np.c_[rng.uniform(-3.0, 2.0, n), np.zeros(n), rng.uniform(-2.0, 2.0, n)]
    o[:50, 0] = np.round(o[:50, 0] * 2) / 2  # on the floor's seams (a 0.5 grid)
    o[50:100, 2] = np.round(o[50:100, 2] * 2) / 2
    ang = rng.uniform(-0.9, 0.9, n)  # all reach the wall (|z| < 10 there)
    d = np.c_[np.cos(ang), np.where(np.arange(n) % 2 == 0, 0.0, -0.0), np.sin(ang)]
    h = closest_hit(accel, o, d)
    no_nan_hits(h)
    assert np.all(h.triangle >= floor.shape[0]), "a ray lying in the floor's plane hit the floor"
    np.testing.assert_allclose(h.t, (3.0 - o[:, 0]) / d[:, 0], rtol=1e-9)
    _, k, _, _ = brute_force(o, d, tri)
    assert np.all(k >= floor.shape[0])


@pytest.mark.parametrize("levels", [0, 2, None])
def test_ray_in_a_face_plane_of_a_closed_box_hits_the_rim(levels):
    """A ray that starts on a face of a closed box and runs inside that face's plane
    leaves the face at the box's edge; the perpendicular face meets it exactly there
    (on its edge), so it is hit at the edge and the ray does not leak. This includes
    rays running exactly along the face's shared edges (the seams x = 1 and z = 1 and
    the cells' diagonals), which end on a vertex shared by the rim's triangles. The
    face's own coplanar triangles are never hit."""
    tri = aabox([0.0, 0.0, 0.0], [2.0, 2.0, 2.0], n=2)
    accel = build_accel(tri, levels=levels)
    rng = np.random.default_rng(4)
    n = 200
    o = np.c_[rng.uniform(0.1, 1.9, n), np.full(n, 2.0), rng.uniform(0.1, 1.9, n)]  # on the top face
    ang = rng.uniform(0, 2 * np.pi, n)
    d = np.c_[np.cos(ang), np.zeros(n), np.sin(ang)]
    seam_o = np.array([[1.0, 2.0, 0.3], [1.0, 2.0, 1.7], [0.4, 2.0, 1.0], [1.6, 2.0, 1.0],
                       [0.5, 2.0, 0.5], [1.5, 2.0, 1.5], [1.0, 2.0, 1.0], [1.0, 2.0, 1.0]])
    seam_d = np.array([[0.0, 0.0, -1.0], [-0.0, 0.0, 1.0], [-1.0, -0.0, 0.0], [1.0, 0.0, -0.0],
                       [-1.0, 0.0, -1.0], [1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [-1.0, 0.0, -1.0]])
    o, d = np.concatenate([o, seam_o]), np.concatenate([d, seam_d])
    n = o.shape[0]
    h = closest_hit(accel, o, d)
    no_nan_hits(h)
    assert np.all(h.triangle >= 0), f"{(h.triangle < 0).sum()} rays leaked along the top face"
    top = np.abs(tri[:, :, 1] - 2.0).max(axis=1) == 0.0
    assert not top[h.triangle].any(), "a coplanar top triangle was hit"
    # the exit distance through the rim
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(d[:, 0] > 0, (2.0 - o[:, 0]) / d[:, 0], np.where(d[:, 0] < 0, -o[:, 0] / d[:, 0], np.inf))
        tz = np.where(d[:, 2] > 0, (2.0 - o[:, 2]) / d[:, 2], np.where(d[:, 2] < 0, -o[:, 2] / d[:, 2], np.inf))
    np.testing.assert_allclose(h.t, np.minimum(tx, tz), rtol=1e-9)


def test_rays_in_a_tilted_triangle_plane_give_no_nan():
    """Tilted (non axis-aligned) tessellated plane: rays computed to lie in its plane
    have a determinant that is zero only up to rounding. Any answer is acceptable (the
    ray is ill-conditioned) but nothing is NaN, every reported hit has a finite t > 0,
    and closest_hit, brute_force and any_hit do not crash."""
    rot = rotation([0.3, 1.0, -0.7], 23.0)
    floor = quad([-1.0, 0.0, -1.0], [0.0, 0.0, 2.0], [2.0, 0.0, 0.0], 6, 6) @ rot.T
    rng = np.random.default_rng(5)
    n = 300
    o_local = np.c_[rng.uniform(-1.5, 1.5, n), np.zeros(n), rng.uniform(-1.5, 1.5, n)]
    ang = rng.uniform(0, 2 * np.pi, n)
    d_local = np.c_[np.cos(ang), np.zeros(n), np.sin(ang)]
    o, d = o_local @ rot.T, d_local @ rot.T
    for levels in (0, None):
        accel = build_accel(floor, levels=levels)
        h = closest_hit(accel, o, d)
        no_nan_hits(h)
        hit = h.triangle >= 0
        assert np.all(np.isfinite(h.t[hit]) & (h.t[hit] > 0))
        any_hit(accel, o, d)
    t, _, u, v = brute_force(o, d, floor)
    assert not (np.isnan(t).any() or np.isnan(u).any() or np.isnan(v).any())


# ---------------------------------------------------------------- axis-parallel, -0.0, split planes


@pytest.mark.parametrize("levels", [0, 1, 2, None, 9])
def test_axis_parallel_rays_with_signed_zeros_along_seams(levels):
    """Axis-parallel rays from inside a tessellated box, travelling along the lines of
    its tessellation (so they end exactly on shared edges and vertices), with every
    combination of +0.0 / -0.0 in the other two components: all hit the face they
    point at, at the exact distance, with bitwise the same triangle and t whatever the
    signs of the zeros."""
    tri = aabox([-1.0, -1.0, -1.0], [1.0, 1.0, 1.0], n=4)
    accel = build_accel(tri, levels=levels)
    g = np.array([-0.5, 0.0, 0.5, 0.25])
    o = np.array(list(itertools.product(g, repeat=3)))
    for axis in range(3):
        for sign in (1.0, -1.0):
            results = []
            for zeros in itertools.product([0.0, -0.0], repeat=2):
                d = np.zeros((o.shape[0], 3))
                d[:, axis] = sign
                d[:, [k for k in range(3) if k != axis]] = zeros
                h = assert_all_hit_at(accel, o, d, 1.0 - sign * o[:, axis])
                results.append(h)
            for h in results[1:]:
                np.testing.assert_array_equal(h.triangle, results[0].triangle)
                np.testing.assert_array_equal(h.t, results[0].t)


@pytest.mark.parametrize("levels", [3, None, 8])
def test_origin_on_every_split_plane_with_zero_component(levels):
    """A closed box with a sphere inside: for every inner node of the BSP, rays whose
    origin lies exactly on the node's split plane and whose direction has +0.0 or -0.0
    on that axis (so they run inside the plane) hit exactly what the one-leaf tree
    (levels=0) and brute force hit: same distance (the triangle may differ only on an
    exact tie), never a miss (the box is closed)."""
    box = aabox([-3.0, -3.0, -3.0], [3.0, 3.0, 3.0], n=3)
    ball = uv_sphere((0.4, -0.3, 0.2), 1.3, 12, 6)
    tri = np.concatenate([box, ball])
    accel = build_accel(tri, levels=levels)
    flat = build_accel(tri, levels=0)
    tree = accel.tree
    rng = np.random.default_rng(6)
    o, d = [], []
    for node in range(tree.leaf_offset):
        axis = ((node + 1).bit_length() - 1) % 3
        for _ in range(6):
            p = rng.uniform(-2.5, 2.5, 3)
            p[axis] = tree.split[node]
            q = rng.normal(size=3)
            q[axis] = rng.choice([0.0, -0.0])
            o.append(p)
            d.append(q)
    o, d = np.array(o), np.array(d)
    assert np.all(np.isfinite(o))
    h = closest_hit(accel, o, d)
    no_nan_hits(h)
    assert np.all(h.triangle >= 0)
    ref = closest_hit(flat, o, d)
    t_bf, k_bf, _, _ = brute_force(o, d, tri)
    for t, k in ((ref.t, ref.triangle), (t_bf, k_bf)):
        np.testing.assert_allclose(h.t, t, rtol=1e-9)
        differ = h.triangle != k
        assert differ.mean() < 0.01  # ties only (shared edges)
    np.testing.assert_array_equal(any_hit(accel, o, d).occluded, True)


# ---------------------------------------------------------------- zero-thickness voxels


@pytest.mark.parametrize("axis", [0, 1, 2])
@pytest.mark.parametrize("levels", [0, 3, None, 10])
def test_flat_wall_zero_thickness_voxels(axis, levels):
    """All triangles in one plane (a 12 x 12 tessellated wall plus a coplanar random
    soup): the root box and every voxel split on that axis have zero thickness. Rays
    from both sides (oblique, perpendicular with signed zeros, through seams) hit the
    plane exactly where a line meets it and agree with the one-leaf tree and brute
    force; rays inside the plane never hit; work counts stay finite."""
    c = 0.75
    rng = np.random.default_rng(7 + axis)
    wall = quad([-1.0, -1.0, c], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0], 12, 12)
    xy = rng.uniform(-1, 1, size=(40, 1, 2)) + rng.uniform(-0.2, 0.2, size=(40, 3, 2))
    soup = np.concatenate([xy, np.full((40, 3, 1), c)], axis=2)
    tri = np.concatenate([wall, soup])
    perm = np.roll(np.arange(3), axis - 2)  # move the plane's normal (z) to ``axis``
    tri = tri[:, :, perm]
    accel = build_accel(tri, levels=levels)
    assert accel.tree.hi[0][axis] == accel.tree.lo[0][axis] == c
    n = 600
    o = rng.uniform(-1.2, 1.2, size=(n, 3))
    o[:, 2] = np.where(np.arange(n) % 2 == 0, c + rng.uniform(0.1, 2, n), c - rng.uniform(0.1, 2, n))
    target = np.c_[rng.uniform(-0.95, 0.95, size=(n, 2)), np.full(n, c)]
    target[:100, :2] = np.round(target[:100, :2] * 6) / 6  # wall seams and vertices
    o[100:200, :2] = target[100:200, :2]  # perpendicular, with signed zeros
    d = target - o
    d[100:200, :2] = np.where(np.arange(100)[:, None] % 2 == 0, 0.0, -0.0)
    d[200:250, 2] = 0.0  # in the plane (origins off it): never hit
    o, d = o[:, perm], d[:, perm]
    h = closest_hit(accel, o, d)
    no_nan_hits(h)
    inplane = np.zeros(n, dtype=bool)
    inplane[200:250] = True
    assert np.all(h.triangle[inplane] == -1)
    expect = np.abs(o[:, axis] - c) / np.abs(np.where(inplane, 1.0, d[:, axis]))
    sees = ~inplane & (h.triangle >= 0)
    assert sees[:200].all(), "a ray aimed at the wall missed it"
    np.testing.assert_allclose(h.t[sees], expect[sees], rtol=1e-9)
    ref = closest_hit(build_accel(tri, levels=0), o, d)
    np.testing.assert_array_equal(ref.triangle >= 0, h.triangle >= 0)
    np.testing.assert_allclose(h.t[sees], ref.t[sees], rtol=1e-9)
    t_bf, k_bf, _, _ = brute_force(o, d, tri)
    np.testing.assert_array_equal(k_bf >= 0, h.triangle >= 0)
    np.testing.assert_allclose(h.t[sees], t_bf[sees], rtol=1e-9)
    np.testing.assert_array_equal(any_hit(accel, o, d).occluded, h.triangle >= 0)


# ---------------------------------------------------------------- degenerate and sliver triangles


@pytest.mark.parametrize("levels", [0, 2, None])
def test_degenerate_triangles_on_the_edges_of_a_closed_box(levels):
    """Zero-area triangles lying exactly on the seams and edges of a closed box (a
    T-junction-like sliver of zero width, a repeated vertex, a point at a corner) are
    never hit, produce no NaN, and do not hide the real faces: rays aimed at those
    seams from inside still hit a face at the target."""
    box = aabox([-1.0, -1.0, -1.0], [1.0, 1.0, 1.0], n=2)
    a, b = box[:, 0], box[:, 1]
    mid = 0.5 * (a + b)
    degenerate = np.concatenate([
        np.stack([a, mid, b], axis=1),  # collinear: on a seam, zero area
        np.stack([a, a, b], axis=1),  # repeated vertex
        np.stack([a, a, a], axis=1),  # a point
    ])
    assert np.all(np.cross(degenerate[:, 1] - degenerate[:, 0], degenerate[:, 2] - degenerate[:, 0]) == 0.0)
    tri = np.concatenate([degenerate, box])  # degenerate first: they would win every tie
    accel = build_accel(tri, levels=levels)
    targets = np.concatenate([mid, a, 0.3 * a + 0.7 * b])
    rng = np.random.default_rng(8)
    for o in np.concatenate([np.zeros((1, 3)), rng.uniform(-0.8, 0.8, size=(3, 3))]):
        oo = np.broadcast_to(o, targets.shape)
        h = assert_all_hit_at(accel, oo, targets - oo, np.ones(targets.shape[0]))
        assert np.all(h.triangle >= degenerate.shape[0]), "a zero-area triangle was hit"
        _, k, _, _ = brute_force(oo, targets - oo, tri)
        assert np.all(k >= degenerate.shape[0])


@pytest.mark.slow
@pytest.mark.parametrize("levels", [0, 3, None])
def test_sliver_fan_covers_its_quad(levels):
    """A unit square tiled by a fan of 2000 slivers from one corner (angles ~8e-4 rad,
    aspect ratio up to ~2500) and a strip of 1000 slivers 1e-6 wide and 2e-3 long:
    perpendicular rays
    at random points and exactly at the slivers' shared edges never leak, hit the plane
    at the exact distance, and produce no NaN."""
    m = 2000
    s = np.linspace(0.0, 1.0, m // 2 + 1)
    far = np.concatenate([np.c_[np.ones_like(s), s], np.c_[s[::-1], np.ones_like(s)][1:]])
    fan = np.stack([np.zeros((far.shape[0] - 1, 2)), far[:-1], far[1:]], axis=1)
    fan = np.concatenate([fan, np.zeros(fan.shape[:2] + (1,))], axis=2)
    w = 1e-6
    xs = np.linspace(0.0, 1.0, 501)
    strip = np.concatenate([
        np.stack([np.c_[xs[:-1], np.full(500, 2.0)], np.c_[xs[1:], np.full(500, 2.0)],
                  np.c_[xs[1:], np.full(500, 2.0 + w)]], axis=1),
        np.stack([np.c_[xs[:-1], np.full(500, 2.0)], np.c_[xs[1:], np.full(500, 2.0 + w)],
                  np.c_[xs[:-1], np.full(500, 2.0 + w)]], axis=1),
    ])
    strip = np.concatenate([strip, np.zeros(strip.shape[:2] + (1,))], axis=2)
    tri = np.concatenate([fan, strip])
    accel = build_accel(tri, levels=levels)
    rng = np.random.default_rng(9)
    pts = np.concatenate([
        np.c_[rng.uniform(0, 1, (800, 2)), np.zeros(800)],
        fan[:, 0] + rng.uniform(0.05, 1.0, (fan.shape[0], 1)) * (fan[:, 1] - fan[:, 0]),  # on shared edges
        strip.mean(axis=1),
        np.c_[rng.uniform(0, 1, 300), np.full(300, 2.0 + 0.5 * w), np.zeros(300)],
    ])
    o = pts + np.array([0.0, 0.0, 1.0])
    d = np.tile([-0.0, 0.0, -1.0], (pts.shape[0], 1))
    assert_all_hit_at(accel, o, d, np.ones(pts.shape[0]))
    _, k, u, v = brute_force(o, d, tri)
    assert np.all(k >= 0) and not (np.isnan(u).any() or np.isnan(v).any())
    # oblique rays too: never NaN, and where they hit, at the plane
    dd = np.c_[rng.normal(0, 0.3, (pts.shape[0], 2)), -np.ones(pts.shape[0])]
    h = closest_hit(accel, o, dd)
    no_nan_hits(h)
    hit = h.triangle >= 0
    np.testing.assert_allclose(h.t[hit], 1.0, rtol=1e-9)


def test_needle_triangles_no_nan():
    """Needles: triangles whose third vertex lies 1e-12 from the second (area ~1e-12 of
    their length squared), scattered among ordinary ones. Rays aimed at their centroids
    and anywhere else never yield NaN. A needle's plane is ill-conditioned (its normal
    comes out of a 1e-12 cancellation), so a hit on one is only placed to ~1e-3 of its
    length (measured: 2e-3 at worst); we ask that it lie within 1e-2 of the segment."""
    rng = np.random.default_rng(10)
    n = 200
    a = rng.uniform(-1, 1, (n, 3))
    b = a + rng.normal(size=(n, 3))
    c = b + 1e-12 * rng.normal(size=(n, 3))
    needles = np.stack([a, b, c], axis=1)
    normal_tri = rng.uniform(-1, 1, (50, 1, 3)) + rng.uniform(-0.2, 0.2, (50, 3, 3))
    tri = np.concatenate([needles, normal_tri])
    targets = np.concatenate([needles.mean(axis=1), rng.uniform(-1, 1, (300, 3))])
    o = targets + rng.normal(size=targets.shape)
    d = targets - o
    for levels in (0, None):
        h = closest_hit(build_accel(tri, levels=levels), o, d)
        no_nan_hits(h)
        hit = np.flatnonzero((h.triangle >= 0) & (h.triangle < n))
        assert np.all(np.isfinite(h.t[hit]) & (h.t[hit] > 0))
        k = h.triangle[hit]
        p = o[hit] + h.t[hit, None] * d[hit]
        sa, sb = needles[k, 0], needles[k, 1]
        s = np.clip(np.sum((p - sa) * (sb - sa), axis=1) / np.sum((sb - sa) ** 2, axis=1), 0.0, 1.0)
        dist = np.linalg.norm(sa + s[:, None] * (sb - sa) - p, axis=1) / np.linalg.norm(sb - sa, axis=1)
        assert np.all(dist < 1e-2), dist.max()
    t, _, u, v = brute_force(o, d, tri)
    assert not (np.isnan(t).any() or np.isnan(u).any() or np.isnan(v).any())


# ---------------------------------------------------------------- tree depth changes nothing


def cornell_rays(tri: np.ndarray, n: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Eye-like rays from in front of the Cornell box and rays between random inner points."""
    rng = np.random.default_rng(seed)
    lo, hi = tri.reshape(-1, 3).min(axis=0), tri.reshape(-1, 3).max(axis=0)
    eye = np.array([278.0, 273.0, -800.0])
    target = rng.uniform(lo, hi, size=(n, 3))
    inner = rng.uniform(lo + 1, hi - 1, size=(n, 3))
    o = np.concatenate([np.broadcast_to(eye, (n, 3)), inner])
    d = np.concatenate([target - eye, rng.normal(size=(n, 3))])
    d[::7, 1] = 0.0  # axis-parallel components
    d[1::7, 0] = -0.0
    return o, d


@pytest.fixture(scope="module")
def cornell_tri():
    return cornell().triangles


@pytest.mark.parametrize("levels", [1, 3, None, 11])
def test_one_leaf_and_deep_trees_give_the_same_hits(cornell_tri, levels):
    """All 2604 Cornell triangles in one leaf (levels=0) and trees of 1 to 11 levels
    (2048 leaves, with heavy expansion copies) find the same hits: the same t (the
    float64 value of the same or a tied triangle), the same triangle on >= 99.9% of the
    rays (ties between triangles meeting at an edge may go either way), the same misses,
    and the same any-hit answers."""
    o, d = cornell_rays(cornell_tri, 1500, 11)
    flat = closest_hit(build_accel(cornell_tri, levels=0), o, d)
    accel = build_accel(cornell_tri, levels=levels)
    h = closest_hit(accel, o, d)
    no_nan_hits(h)
    np.testing.assert_array_equal(h.triangle >= 0, flat.triangle >= 0)
    hit = h.triangle >= 0
    np.testing.assert_allclose(h.t[hit], flat.t[hit], rtol=1e-7)
    same = h.triangle == flat.triangle
    assert same.mean() >= 0.999, same.mean()
    np.testing.assert_array_equal(h.t[same], flat.t[same])
    np.testing.assert_array_equal(any_hit(accel, o, d).occluded, hit)


# ---------------------------------------------------------------- packet invariance at silhouettes


def silhouette_rays() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rays from outside a rotated UV sphere aimed at its vertices and edge points: many
    graze the silhouette, where the float32 answer depends on rounding."""
    rot = rotation([1.0, 2.0, 3.0], 37.0)
    tri = uv_sphere((0.0, 0.0, 0.0), 1.0, 16, 8) @ rot.T
    targets = np.concatenate([unique_vertices(tri), edge_points(tri, (0.5, 0.1))])
    rng = np.random.default_rng(2)
    outside = rng.normal(size=targets.shape)
    outside *= 3.0 / np.linalg.norm(outside, axis=1, keepdims=True)
    return tri, outside, targets - outside


@pytest.mark.slow
@pytest.mark.parametrize("levels", [0, None])
def test_silhouette_rays_are_packet_invariant(levels):
    """A ray's closest hit and any-hit answer are the same alone as inside a packet, even
    for rays that graze a silhouette edge (where float32 rounding decides hit or miss):
    the kernels promise bit-for-bit packet invariance."""
    tri, o, d = silhouette_rays()
    o, d = o[:400], d[:400]
    accel = build_accel(tri, levels=levels)
    whole = closest_hit(accel, o, d)
    occ = any_hit(accel, o, d).occluded
    alone = [closest_hit(accel, o[i : i + 1], d[i : i + 1]) for i in range(o.shape[0])]
    np.testing.assert_array_equal(np.concatenate([h.triangle for h in alone]), whole.triangle)
    np.testing.assert_array_equal(np.concatenate([h.t for h in alone]), whole.t)
    occ_alone = np.concatenate([any_hit(accel, o[i : i + 1], d[i : i + 1]).occluded for i in range(o.shape[0])])
    np.testing.assert_array_equal(occ_alone, occ)
