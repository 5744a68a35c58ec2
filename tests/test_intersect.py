"""Ray-triangle intersection (eq. 3.6) through the BSP and by brute force, against an
independent float64 Möller–Trumbore written here.

The library decides *which* triangle is hit in float32 and then computes t, u, v in
float64; the reference does everything in float64. They may legitimately disagree only
on near-ties: two hits at almost the same distance, or a hit within a hair of an edge.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from tlm.kernels.intersect import brute_force
from tlm.kernels.traverse import any_hit, build_accel, closest_hit

TIE_REL = 1e-5  # best and second-best t closer than this (relative): a tie
EDGE_TOL = 1e-5  # barycentric distance to an edge below this: an edge case


# ---------------------------------------------------------------- the reference


@dataclass
class Ref:
    t: np.ndarray  # (r,) nearest accepted t (inf: none)
    tri: np.ndarray  # (r,) its triangle (-1: none)
    u: np.ndarray
    v: np.ndarray
    t2: np.ndarray  # (r,) second-nearest accepted t (inf: none)
    edge: np.ndarray  # (r,) min(u, v, 1-u-v) of the nearest hit (inf: none)
    all_t: np.ndarray  # (r, n) every triangle's t (NaN where det == 0)
    all_b: np.ndarray  # (r, n) every triangle's min(u, v, 1-u-v) (NaN where det == 0)


def mt_reference(o, d, tri, tmin=0.0, tmax=np.inf, ignore=None) -> Ref:
    """Eq. 3.6 literally, float64: a loop over triangles, vectorized over rays."""
    o = np.asarray(o, dtype=np.float64).reshape(-1, 3)
    d = np.asarray(d, dtype=np.float64).reshape(-1, 3)
    tri = np.asarray(tri, dtype=np.float64).reshape(-1, 3, 3)
    r, n = o.shape[0], tri.shape[0]
    tmin = np.broadcast_to(np.asarray(tmin, dtype=np.float64), (r,))
    tmax = np.broadcast_to(np.asarray(tmax, dtype=np.float64), (r,))
    all_t = np.full((r, n), np.nan)
    all_b = np.full((r, n), np.nan)
    all_u = np.full((r, n), np.nan)
    all_v = np.full((r, n), np.nan)
    for k in range(n):
        v0, v1, v2 = tri[k]
        e1 = v1 - v0
        e2 = v2 - v0
        tt = o - v0
        p = np.cross(d, e2)
        q = np.cross(tt, e1)
        det = p @ e1
        # det == 0: the ray is parallel to the plane; a zero-area triangle has det == 0 in
        # exact arithmetic for every ray (rounding could make it a tiny nonzero here)
        ok = (det != 0.0) & np.any(np.cross(e1, e2) != 0.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.einsum("ij,ij->i", p, tt) / det
            v = np.einsum("ij,ij->i", q, d) / det
            t = (q @ e2) / det
            b = np.minimum(np.minimum(u, v), 1.0 - u - v)
        all_t[ok, k] = t[ok]
        all_u[ok, k] = u[ok]
        all_v[ok, k] = v[ok]
        all_b[ok, k] = b[ok]
    with np.errstate(invalid="ignore"):
        accept = (all_b >= 0.0) & (all_t >= tmin[:, None]) & (all_t < tmax[:, None])
    if ignore is not None:
        ign = np.broadcast_to(np.asarray(ignore), (r,))
        accept &= np.arange(n)[None, :] != ign[:, None]
    tt = np.where(accept, all_t, np.inf)
    if n == 0:
        inf = np.full(r, np.inf)
        return Ref(inf, np.full(r, -1), np.zeros(r), np.zeros(r), inf, inf, all_t, all_b)
    order = np.argsort(tt, axis=1, kind="stable")
    best = order[:, 0]
    rows = np.arange(r)
    t1 = tt[rows, best]
    t2 = tt[rows, order[:, 1]] if n > 1 else np.full(r, np.inf)
    hit = np.isfinite(t1)
    return Ref(
        t=t1,
        tri=np.where(hit, best, -1),
        u=np.where(hit, all_u[rows, best], 0.0),
        v=np.where(hit, all_v[rows, best], 0.0),
        t2=t2,
        edge=np.where(hit, all_b[rows, best], np.inf),
        all_t=all_t,
        all_b=all_b,
    )


def explained(ref: Ref, got_tri: np.ndarray, tmin=0.0, tmax=np.inf) -> np.ndarray:
    """Rays where a disagreement with the reference is a legitimate near-tie."""
    r = got_tri.shape[0]
    tmin = np.broadcast_to(np.asarray(tmin, dtype=np.float64), (r,))
    tmax = np.broadcast_to(np.asarray(tmax, dtype=np.float64), (r,))
    rows = np.arange(r)
    scale = np.maximum(np.abs(ref.t), 1.0)
    scale = np.where(np.isfinite(scale), scale, 1.0)
    with np.errstate(invalid="ignore"):
        tie = np.abs(ref.t2 - ref.t) < TIE_REL * scale
        at_edge = ref.edge < EDGE_TOL
        # what the library picked, seen by the reference: just outside an edge, or at a
        # distance tied with the reference's best, or at the ends of the (tmin, tmax) window
        g = np.maximum(got_tri, 0)
        gb = ref.all_b[rows, g]
        gt = ref.all_t[rows, g]
        got_edge = (got_tri >= 0) & (gb > -EDGE_TOL) & (gb < EDGE_TOL)
        got_tie = (got_tri >= 0) & (np.abs(gt - ref.t) < TIE_REL * scale)
        window = (np.abs(ref.t - tmin) < TIE_REL * scale) | (np.abs(ref.t - tmax) < TIE_REL * scale)
        window |= (got_tri >= 0) & (
            (np.abs(gt - tmin) < TIE_REL * np.maximum(np.abs(gt), 1))
            | (np.abs(gt - tmax) < TIE_REL * np.maximum(np.abs(gt), 1))
        )
    return tie | at_edge | got_edge | got_tie | window


def check_against_reference(ref: Ref, t, tri, u, v, tmin=0.0, tmax=np.inf, max_bad=0.002):
    """Same triangle except explained near-ties; t, u, v match where the triangle does."""
    assert not np.isnan(t).any() and not np.isnan(u).any() and not np.isnan(v).any()
    differ = tri != ref.tri
    ok = explained(ref, tri, tmin, tmax)
    unexplained = np.flatnonzero(differ & ~ok)
    assert unexplained.size == 0, (
        f"{unexplained.size} unexplained disagreements, e.g. ray {unexplained[:5]}: "
        f"got {tri[unexplained[:5]]} ref {ref.tri[unexplained[:5]]} "
        f"t {t[unexplained[:5]]} ref t {ref.t[unexplained[:5]]}"
    )
    assert differ.mean() <= max_bad, f"{differ.sum()} of {differ.size} rays disagree"
    same = ~differ & (tri >= 0)
    np.testing.assert_allclose(t[same], ref.t[same], rtol=1e-9, atol=0)
    np.testing.assert_allclose(u[same], ref.u[same], rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(v[same], ref.v[same], rtol=1e-7, atol=1e-9)
    miss = tri < 0
    assert np.all(np.isinf(t[miss])) and np.all(t[miss] > 0)
    assert np.all(np.isfinite(t[~miss]))
    return differ.sum()


# ---------------------------------------------------------------- data


def soup(seed: int, n: int = 150, size: float = 0.12) -> np.ndarray:
    rng = np.random.default_rng(seed)
    c = rng.uniform(0.0, 1.0, size=(n, 1, 3))
    return c + rng.uniform(-size, size, size=(n, 3, 3))


def rays(seed: int, tri: np.ndarray, r: int = 1500) -> tuple[np.ndarray, np.ndarray]:
    """A mix: random rays, rays aimed at random points of random triangles, rays from inside."""
    rng = np.random.default_rng(seed + 1000)
    k = r // 3
    o1 = rng.uniform(-0.5, 1.5, size=(k, 3))
    d1 = rng.normal(size=(k, 3))
    o2 = rng.uniform(-1.0, 2.0, size=(k, 3))
    w = rng.dirichlet([1, 1, 1], size=k)
    target = np.einsum("ij,ijk->ik", w, tri[rng.integers(0, tri.shape[0], size=k)])
    d2 = (target - o2) * rng.uniform(0.2, 3.0, size=(k, 1))  # not unit: t in units of |d|
    o3 = rng.uniform(0.2, 0.8, size=(r - 2 * k, 3))
    d3 = rng.normal(size=(r - 2 * k, 3))
    return np.concatenate([o1, o2, o3]), np.concatenate([d1, d2, d3])


LEVELS = [0, 1, 3, None, 9]


@pytest.fixture(scope="module", params=[0, 1, 2, 3])
def case(request):
    seed = request.param
    tri = soup(seed)
    o, d = rays(seed, tri)
    return seed, tri, o, d, mt_reference(o, d, tri)


# ---------------------------------------------------------------- agreement


def test_reference_sanity():
    """The reference itself: a unit triangle, a ray through a known point."""
    tri = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    o = np.array([[0.25, 0.5, 2.0], [2.0, 2.0, 1.0]])
    d = np.array([[0.0, 0.0, -2.0], [0.0, 0.0, -1.0]])
    ref = mt_reference(o, d, tri)
    np.testing.assert_allclose(ref.t[:1], [1.0])
    np.testing.assert_allclose(ref.u[:1], [0.25])
    np.testing.assert_allclose(ref.v[:1], [0.5])
    assert ref.tri.tolist() == [0, -1]


@pytest.mark.slow
def test_brute_force_matches_reference(case):
    seed, tri, o, d, ref = case
    t, k, u, v = brute_force(o, d, tri)
    n_bad = check_against_reference(ref, t, k, u, v)
    assert (ref.tri >= 0).mean() > 0.3  # the rays do hit things
    print(f"seed {seed}: brute force disagrees (explained) on {n_bad} rays")


@pytest.mark.slow
@pytest.mark.parametrize("levels", LEVELS)
def test_closest_hit_matches_reference(case, levels):
    seed, tri, o, d, ref = case
    accel = build_accel(tri, levels=levels)
    h = closest_hit(accel, o, d)
    n_bad = check_against_reference(ref, h.t, h.triangle, h.u, h.v)
    print(f"seed {seed} levels {levels}: {n_bad} explained disagreements")
    # the BSP and brute force decide with the same float32 test: identical triangles
    _t, k, _, _ = brute_force(o, d, tri)
    agree = k == h.triangle
    assert agree.mean() >= 0.999
    assert np.all(explained(ref, h.triangle)[~agree])


@pytest.mark.parametrize("levels", [0, 1, None])
def test_any_hit_matches_reference(case, levels):
    _, tri, o, d, ref = case
    accel = build_accel(tri, levels=levels)
    occ = any_hit(accel, o, d)
    want = ref.tri >= 0
    differ = occ.occluded != want
    # a miss/hit disagreement can only come from a grazing edge hit
    with np.errstate(invalid="ignore"):
        near_edge = np.any(np.abs(ref.all_b) < EDGE_TOL, axis=1)
    assert np.all(near_edge[differ])
    assert differ.mean() <= 0.002


@pytest.mark.slow
@pytest.mark.parametrize("levels", [0, 1, 4, None])
def test_tmin_tmax_window(case, levels):
    seed, tri, o, d, _ = case
    rng = np.random.default_rng(seed + 7)
    r = o.shape[0]
    tmin = rng.uniform(0.0, 1.0, size=r) * rng.integers(0, 2, size=r)  # half the rays: 0
    tmax = tmin + rng.exponential(1.0, size=r)
    tmax[::5] = np.inf
    ref = mt_reference(o, d, tri, tmin=tmin, tmax=tmax)
    accel = build_accel(tri, levels=levels)
    h = closest_hit(accel, o, d, tmin=tmin, tmax=tmax)
    check_against_reference(ref, h.t, h.triangle, h.u, h.v, tmin, tmax)
    hit = h.triangle >= 0
    # returned distances inside the window (float32 decision: a hair of slack)
    assert np.all(h.t[hit] >= tmin[hit] * (1 - 1e-6) - 1e-7)
    assert np.all(h.t[hit] <= tmax[hit] * (1 + 1e-6) + 1e-7)
    occ = any_hit(accel, o, d, tmin=tmin, tmax=tmax)
    differ = occ.occluded != (ref.tri >= 0)
    assert np.all(explained(ref, h.triangle, tmin, tmax)[differ] | (hit != (ref.tri >= 0))[differ])
    assert differ.mean() <= 0.002
    # a window that ends just before the first hit finds nothing nearer
    h0 = closest_hit(accel, o, d)
    hit0 = h0.triangle >= 0
    h1 = closest_hit(accel, o[hit0], d[hit0], tmax=h0.t[hit0] * (1 - 1e-3))
    assert np.all((h1.triangle < 0) | (h1.t < h0.t[hit0]))
    assert (h1.triangle < 0).mean() > 0.99
    # and a window that starts just after it never returns something before tmin
    h2 = closest_hit(accel, o[hit0], d[hit0], tmin=h0.t[hit0] * (1 + 1e-3))
    assert np.all(h2.t > h0.t[hit0])


@pytest.mark.slow
@pytest.mark.parametrize("levels", [0, 2, None])
def test_ignore_never_returns_the_ignored_triangle(case, levels):
    _, tri, o, d, _ref = case
    accel = build_accel(tri, levels=levels)
    h = closest_hit(accel, o, d)
    hit = np.flatnonzero(h.triangle >= 0)
    ign = h.triangle[hit]
    h2 = closest_hit(accel, o[hit], d[hit], ignore=ign)
    assert not np.any(h2.triangle == ign)
    ref2 = mt_reference(o[hit], d[hit], tri, ignore=ign)
    check_against_reference(ref2, h2.t, h2.triangle, h2.u, h2.v)
    # the ignored triangle was the closest: the next hit is at least as far
    assert np.all(h2.t >= h.t[hit] * (1 - 1e-6))
    # brute force and any_hit honour ignore too
    _, k, _, _ = brute_force(o[hit], d[hit], tri, ignore=ign)
    assert not np.any(k == ign)
    occ = any_hit(accel, o[hit], d[hit], ignore=ign)
    np.testing.assert_array_equal(occ.occluded, h2.triangle >= 0)
    # ignoring some other triangle changes nothing when it is not the one hit
    other = np.where(ign == 0, 1, 0)
    h3 = closest_hit(accel, o[hit], d[hit], ignore=other)
    keep = h.triangle[hit] != other
    np.testing.assert_array_equal(h3.triangle[keep], h.triangle[hit][keep])


def test_ignore_single_triangle_scene():
    tri = np.array([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]])
    accel = build_accel(tri)
    o = np.array([[0.2, 0.2, 1.0]] * 3)
    d = np.array([[0.0, 0.0, -1.0]] * 3)
    h = closest_hit(accel, o, d, ignore=np.array([0, -1, 5]))
    assert h.triangle.tolist() == [-1, 0, 0]
    assert h.t[0] == np.inf
    np.testing.assert_allclose(h.t[1:], 1.0)
    occ = any_hit(accel, o, d, ignore=np.array([0, -1, 5]))
    assert occ.occluded.tolist() == [False, True, True]
    _, k, _, _ = brute_force(o, d, tri, ignore=np.array([0, -1, 5]))
    assert k.tolist() == [-1, 0, 0]


# ---------------------------------------------------------------- awkward rays


def _no_nan(h):
    for a in (h.t, h.u, h.v):
        assert not np.isnan(a).any()
    for f in ("node_visits", "leaves_crossed", "leaf_visits", "tri_tests"):
        c = getattr(h.counts, f)
        assert c.dtype == np.int64 and np.all(c >= 0)


@pytest.mark.parametrize("levels", [0, 1, 4, None])
def test_rays_parallel_to_triangles(levels):
    """Triangles in z = 0.5 planes: rays in the plane and parallel to it never hit."""
    rng = np.random.default_rng(11)
    n = 80
    xy = rng.uniform(0, 1, size=(n, 1, 2)) + rng.uniform(-0.1, 0.1, size=(n, 3, 2))
    tri = np.concatenate([xy, np.full((n, 3, 1), 0.5)], axis=2)
    r = 500
    o = np.c_[rng.uniform(-0.5, 1.5, size=(r, 2)), np.zeros(r)]
    o[:, 2] = np.where(np.arange(r) % 2 == 0, 0.5, 0.5 + rng.uniform(-0.3, 0.3, size=r))
    ang = rng.uniform(0, 2 * np.pi, size=r)
    d = np.c_[np.cos(ang), np.sin(ang), np.zeros(r)]
    accel = build_accel(tri, levels=levels)
    h = closest_hit(accel, o, d)
    _no_nan(h)
    assert np.all(h.triangle == -1)
    assert np.all(np.isinf(h.t))
    assert not any_hit(accel, o, d).occluded.any()
    t, k, _u, _v = brute_force(o, d, tri)
    assert np.all(k == -1) and not np.isnan(t).any()
    # tilted soups: rays parallel to one random triangle's plane (det == 0 up to rounding)
    tri2 = soup(12, 60)
    e1 = tri2[:, 1] - tri2[:, 0]
    e2 = tri2[:, 2] - tri2[:, 0]
    nrm = np.cross(e1, e2)
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    inside = tri2[:, 0] + 0.3 * e1 + 0.3 * e2  # a point inside each triangle
    dd = e1 - e2  # in the plane
    accel2 = build_accel(tri2, levels=levels)
    # in the plane: ill-conditioned, any answer is fine but no NaN and no crash
    _no_nan(closest_hit(accel2, inside, dd))
    any_hit(accel2, inside, dd)
    # off the plane: never the own triangle, and the rest as the reference says
    off = inside + 0.05 * nrm
    h2 = closest_hit(accel2, off, dd)
    _no_nan(h2)
    assert not np.any(h2.triangle == np.arange(60))
    ref = mt_reference(off, dd, tri2)
    check_against_reference(ref, h2.t, h2.triangle, h2.u, h2.v, max_bad=0.05)


@pytest.mark.slow
@pytest.mark.parametrize("levels", [0, 1, 2, 5, None])
def test_zero_direction_components(levels):
    """Axis-parallel rays with +0.0 and -0.0 components agree with the reference, and
    the sign of zero changes nothing."""
    tri = soup(21, 200)
    accel = build_accel(tri, levels=levels)
    rng = np.random.default_rng(22)
    r = 600
    o = rng.uniform(-0.2, 1.2, size=(r, 3))
    axis = rng.integers(0, 3, size=r)
    d = np.zeros((r, 3))
    d[np.arange(r), axis] = rng.choice([-1.0, 1.0], size=r) * rng.uniform(0.5, 2, size=r)
    # two nonzero components on a third of the rays
    two = np.arange(r) % 3 == 0
    d[two, (axis[two] + 1) % 3] = rng.normal(size=two.sum())
    ref = mt_reference(o, d, tri)
    variants = []
    for sign in (1.0, -1.0):
        dz = np.where(d == 0.0, sign * 0.0, d)
        assert np.all(np.signbit(dz[d == 0.0]) == (sign < 0))
        h = closest_hit(accel, o, dz)
        _no_nan(h)
        check_against_reference(ref, h.t, h.triangle, h.u, h.v)
        variants.append(h)
    np.testing.assert_array_equal(variants[0].triangle, variants[1].triangle)
    np.testing.assert_array_equal(variants[0].t, variants[1].t)
    # origins exactly on split planes of the tree, with a zero component on that axis
    tree = accel.tree
    if tree.levels:
        o_on = o.copy()
        d_on = d.copy()
        for i in range(r):
            node = i % tree.leaf_offset if tree.leaf_offset else 0
            ax = ((node + 1).bit_length() - 1) % 3
            o_on[i, ax] = tree.split[node]
            d_on[i, ax] = -0.0 if i % 2 else 0.0
            if not d_on[i].any():
                d_on[i, (ax + 1) % 3] = 1.0
        ref_on = mt_reference(o_on, d_on, tri)
        h = closest_hit(accel, o_on, d_on)
        _no_nan(h)
        check_against_reference(ref_on, h.t, h.triangle, h.u, h.v)


@pytest.mark.parametrize("levels", [0, 3, None])
def test_zero_direction(levels):
    tri = soup(31, 100)
    accel = build_accel(tri, levels=levels)
    o = np.array([[0.5, 0.5, 0.5], [5.0, 5.0, 5.0], [0.1, 0.9, 0.4], tri[0, 0], tri[3].mean(axis=0)])
    for zero in (0.0, -0.0):
        d = np.full(o.shape, zero)
        h = closest_hit(accel, o, d)
        _no_nan(h)
        assert np.all(h.triangle == -1) and np.all(np.isinf(h.t))
        occ = any_hit(accel, o, d)
        assert not occ.occluded.any()
        t, k, u, v = brute_force(o, d, tri)
        assert np.all(k == -1)
        assert not (np.isnan(t).any() or np.isnan(u).any() or np.isnan(v).any())
    # mixed with ordinary rays in one packet: the others are unaffected
    o2, d2 = rays(31, tri, 90)
    d_mix = np.concatenate([d2, np.zeros((5, 3))])
    o_mix = np.concatenate([o2, o])
    h_mix = closest_hit(accel, o_mix, d_mix)
    h_alone = closest_hit(accel, o2, d2)
    np.testing.assert_array_equal(h_mix.triangle[:90], h_alone.triangle)
    np.testing.assert_array_equal(h_mix.t[:90], h_alone.t)
    assert np.all(h_mix.triangle[90:] == -1)


def test_empty_packet_and_empty_scene():
    tri = soup(41, 20)
    accel = build_accel(tri)
    h = closest_hit(accel, np.zeros((0, 3)), np.zeros((0, 3)))
    assert h.t.shape == h.triangle.shape == (0,)
    assert any_hit(accel, np.zeros((0, 3)), np.zeros((0, 3))).occluded.shape == (0,)
    t, k, _, _ = brute_force(np.zeros((0, 3)), np.zeros((0, 3)), tri)
    assert t.shape == k.shape == (0,)


@pytest.mark.parametrize("levels", [0, 2, None])
def test_degenerate_triangles_never_hit(levels):
    """Zero-area triangles (repeated vertices, collinear, a point) are never hit, even by
    rays aimed exactly at them; ordinary triangles around them still are."""
    rng = np.random.default_rng(51)
    good = soup(52, 60)
    a = rng.integers(-4, 5, size=(40, 3)).astype(np.float64) / 4
    b = rng.integers(-4, 5, size=(40, 3)).astype(np.float64) / 4
    degenerate = np.concatenate(
        [
            np.stack([a, a, b], axis=1)[:10],  # two coincident vertices
            np.stack([a, b, b], axis=1)[10:20],
            np.stack([a, a + (b - a), a + 2 * (b - a)], axis=1)[20:30],  # collinear
            np.stack([a, a, a], axis=1)[30:],  # a point
        ]
    )
    cross = np.cross(degenerate[:, 1] - degenerate[:, 0], degenerate[:, 2] - degenerate[:, 0])
    assert np.all(cross == 0.0)  # exactly zero area, as the library will compute it
    tri = np.concatenate([good, degenerate])
    bad_ids = set(range(good.shape[0], tri.shape[0]))
    # rays aimed at the vertices and edge midpoints of the degenerate triangles
    targets = np.concatenate([degenerate[:, 0], degenerate[:, 1], degenerate.mean(axis=1),
                              0.5 * (degenerate[:, 0] + degenerate[:, 2])])
    o = targets + rng.normal(size=targets.shape)
    d = targets - o
    o_rand, d_rand = rays(53, tri, 600)
    o = np.concatenate([o, o_rand])
    d = np.concatenate([d, d_rand])
    accel = build_accel(tri, levels=levels)
    h = closest_hit(accel, o, d)
    _no_nan(h)
    assert not (set(h.triangle.tolist()) & bad_ids)
    _, k, _, _ = brute_force(o, d, tri)
    assert not (set(k.tolist()) & bad_ids)
    # any_hit on the degenerate triangles alone: never occluded
    only = build_accel(degenerate, levels=levels)
    assert not any_hit(only, o, d).occluded.any()
    h_only = closest_hit(only, o, d)
    assert np.all(h_only.triangle == -1)
    # and against the reference on the good ones
    ref = mt_reference(o, d, tri)
    assert not (set(ref.tri.tolist()) & bad_ids)
    check_against_reference(ref, h.t, h.triangle, h.u, h.v)


def test_shared_edge_no_leak():
    """A ray through the shared edge of two triangles of a quad hits one of them."""
    quad = np.array([[[0.0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0.0, 0, 0], [1, 1, 0], [0, 1, 0]]])
    s = np.linspace(0.0, 1.0, 101)
    o = np.c_[s, s, np.ones_like(s)]  # over the diagonal x == y
    d = np.tile([0.0, 0.0, -1.0], (s.shape[0], 1))
    for levels in (0, 1, 3):
        h = closest_hit(build_accel(quad, levels=levels), o, d)
        assert np.all(h.triangle >= 0)
        np.testing.assert_allclose(h.t, 1.0)
        assert np.all(h.triangle == 0)  # equal t: the lower id wins
    _, k, _, _ = brute_force(o, d, quad)
    assert np.all(k == 0)


def test_far_from_origin_scene():
    """Geometry 1e6 away from the world origin loses no precision (relative storage)."""
    tri = soup(61, 100)
    o, d = rays(61, tri, 600)
    shift = np.array([1e6, -2e6, 3e6])
    ref = mt_reference(o, d, tri)
    h = closest_hit(build_accel(tri + shift), o + shift, d)
    differ = h.triangle != ref.tri
    assert differ.mean() <= 0.005
    assert np.all(explained(ref, h.triangle)[differ])
    same = ~differ & (h.triangle >= 0)
    np.testing.assert_allclose(h.t[same], ref.t[same], rtol=1e-6)


def test_grazing_hits_stay_inside_the_window():
    """Shadow-ray geometry of the Cornell box: rays from points just below a plane 548.8
    units from the origin end ON that plane (the light is coplanar with the ceiling) and
    stop ``SPAWN_EPS * scale`` short of it. No hit may lie beyond ``tmax``."""
    y = 548.8
    tri = np.array([
        [[-500, y, -500], [500, y, -500], [500, y, 500]],
        [[-500, y, -500], [500, y, 500], [-500, y, 500]],
        [[-500, 0, -500], [500, 0, -500], [500, 0, 500]],
    ], dtype=np.float64)
    accel = build_accel(tri)
    rng = np.random.default_rng(0)
    n = 4000
    target = np.c_[rng.uniform(-100, 100, n), np.full(n, y), rng.uniform(-100, 100, n)]
    along = rng.normal(size=(n, 2))
    along /= np.linalg.norm(along, axis=1, keepdims=True)
    length = rng.uniform(100, 400, n)
    o = target + np.c_[along[:, 0] * length, -rng.uniform(0.1, 3.0, n), along[:, 1] * length]
    to = target - o
    dist = np.linalg.norm(to, axis=1)
    d = to / dist[:, None]
    eps = 1e-5 * accel.scale
    tmax = dist - eps  # the plane is met at t == dist only
    h = closest_hit(accel, o, d, tmin=eps, tmax=tmax)
    hit = h.triangle >= 0
    assert np.all(h.t[hit] <= tmax[hit]), f"{hit.sum()} hits beyond tmax"
    assert not any_hit(accel, o, d, tmin=eps, tmax=tmax).occluded.any()


# ---------------------------------------------------------------- property-based


coord = st.floats(min_value=-10.0, max_value=10.0, allow_nan=False, allow_infinity=False, width=64)
vec3 = st.tuples(coord, coord, coord)


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:overflow encountered:RuntimeWarning")  # subnormal d: see below
@settings(max_examples=150, deadline=None, derandomize=True)
@given(
    tris=st.lists(st.tuples(vec3, vec3, vec3), min_size=1, max_size=6),
    o=vec3,
    d=vec3,
    levels=st.sampled_from([0, 1, 2]),
)
# found by CI: a direction that float32 flushes to zero hits at t ~ 1e276 in float64
@example(tris=[((0.0, 0.0, 0.0), (0.0, 0.0, -2.0), (2.0, 0.0, 1.0))], o=(1.0, -1.0, 0.0),
         d=(0.0, 8.85230326406259e-277, 0.0), levels=0)
@example(tris=[((0.0, 0.0, 0.0), (0.0, 0.0, -2.0), (2.0, 0.0, 1.0))], o=(1.0, -1.0, 0.0),
         d=(1e-300, 1e-290, 0.0), levels=1)
def test_single_ray_property(tris, o, d, levels):
    """Any small soup, any ray (zero components included): the BSP, brute force and
    the reference agree up to explained near-ties; nothing is NaN."""
    tri = np.asarray(tris, dtype=np.float64)
    o = np.asarray([o])
    d = np.asarray([d])
    h = closest_hit(build_accel(tri, levels=levels), o, d)
    _no_nan(h)
    t, k, u, v = brute_force(o, d, tri)
    assert not (np.isnan(t).any() or np.isnan(u).any() or np.isnan(v).any())
    ref = mt_reference(o, d, tri)
    for got in (h.triangle, k):
        if got[0] != ref.tri[0]:
            assert explained(ref, got)[0], (got, ref.tri, ref.t, ref.t2, ref.edge)
    if h.triangle[0] >= 0 and h.triangle[0] == ref.tri[0]:
        # a hit computed with a near-zero determinant carries its conditioning
        assert h.t[0] == pytest.approx(ref.t[0], rel=1e-6, abs=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("levels", [0, 1, 3, None])
def test_shared_origin_path(levels):
    """Eye-ray path (one origin for all rays) against the reference."""
    tri = soup(71, 200)
    rng = np.random.default_rng(72)
    for origin in ([0.5, 0.5, -1.0], [0.4, 0.6, 0.5], [2.0, -1.0, 0.3]):
        o = np.tile(origin, (1200, 1))
        w = rng.dirichlet([1, 1, 1], size=800)
        target = np.einsum("ij,ijk->ik", w, tri[rng.integers(0, tri.shape[0], size=800)])
        d = np.concatenate([target - o[:800], rng.normal(size=(400, 3))])
        d[::50, 0] = 0.0
        ref = mt_reference(o, d, tri)
        accel = build_accel(tri, levels=levels)
        h = closest_hit(accel, o, d, shared_origin=True)
        _no_nan(h)
        check_against_reference(ref, h.t, h.triangle, h.u, h.v)
        # and the per-ray path: same triangles except explained ties
        g = closest_hit(accel, o, d)
        differ = g.triangle != h.triangle
        assert np.all(explained(ref, g.triangle)[differ] | explained(ref, h.triangle)[differ])


def test_subnormal_direction_components():
    # a floor (y = 0, the root box's low face) and a wall at x = 10
    tri = np.array([
        [[0, 0, 0], [10, 0, 0], [10, 0, 10]], [[0, 0, 0], [10, 0, 10], [0, 0, 10]],
        [[10, 0, 0], [10, 5, 0], [10, 5, 10]], [[10, 0, 0], [10, 5, 10], [10, 0, 10]],
    ], dtype=np.float64)
    accel = build_accel(tri, levels=3)
    s0 = accel.tree.split[0]  # an x split
    o = np.array([[2.0, 0.0, 5.0], [2.0, 0.0, 5.0], [s0, 1.0, 5.0], [s0, 1.0, 5.0]])
    d = np.array([[1.0, 0.0, 0.0], [1.0, 1e-310, 0.0], [0.0, -1.0, 0.0], [1e-320, -1.0, 0.0]])
    with np.errstate(over="ignore"):
        _, k, _, _ = brute_force(o, d, tri, tmin=1e-6)
        h = closest_hit(accel, o, d, tmin=1e-6)
    assert k.tolist() == [3, 3, 0, 0]
    np.testing.assert_array_equal(h.triangle, k)


@pytest.mark.parametrize("levels", [0, 2])
def test_rays_float32_cannot_carry_fall_back_to_float64(levels):
    """A direction float32 flushes to zero, or one it rounds to inf, is still traced:
    the float32 datapath only finds candidates, and such rays are traced in float64."""
    tri = np.array([[(0.0, 0.0, 0.0), (0.0, 0.0, -2.0), (2.0, 0.0, 1.0)]])
    accel = build_accel(tri, levels=levels)
    o = np.tile([1.0, -1.0, 0.0], (5, 1))
    # float32 flushes the first to zero and rounds the second to inf; the fourth is
    # subnormal in float64; the last meets the plane beyond float64's range (a miss)
    d = np.array([[0.0, 1e-300, 0.0], [0.0, 1e300, 0.0], [0.0, 1.0, 0.0], [1e-320, 2e-308, 0.0], [0.0, 1e-310, 0.0]])
    with np.errstate(over="ignore"):
        h = closest_hit(accel, o, d)
        occ = any_hit(accel, o, d).occluded
        t, k, _, _ = brute_force(o, d, tri)
    assert h.triangle.tolist() == [0, 0, 0, 0, -1]
    np.testing.assert_allclose(h.t, [1e300, 1e-300, 1.0, 5e307, np.inf], rtol=1e-12)
    assert k.tolist() == h.triangle.tolist()
    np.testing.assert_array_equal(t, h.t)
    assert occ.tolist() == [True, True, True, True, False]
