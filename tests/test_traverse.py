"""The Traversal PM (§III.B.2): packet invariance, recorded memory traffic, near-first order.

A ray's answer and its work counts must not depend on which other rays share its
packet, on their order, or on the ``batch`` speed knob: bit for bit. The same holds for
every render pass, pixel by pixel.
"""

from __future__ import annotations

import numpy as np
import pytest

from tlm.config import config_from_dict
from tlm.kernels.camera import primary_rays
from tlm.kernels.traverse import any_hit, build_accel, closest_hit
from tlm.kernels.work import MISS_KEYS, WORK_KEYS
from tlm.render.frame import Frame, cast
from tlm.render.passes import rcast_pass, reflect_pass, refract_pass
from tlm.scenes.loader import load_scene

COUNT_FIELDS = ("node_visits", "leaves_crossed", "leaf_visits", "tri_tests")


@pytest.fixture(scope="module")
def cornell():
    scene = load_scene("cornell")
    accel = build_accel(scene.triangles)
    w, h = scene.camera.width, scene.camera.height
    o, d = primary_rays(scene.camera, np.arange(w * h))
    return scene, accel, o, d


@pytest.fixture(scope="module")
def full_hits(cornell):
    _, accel, o, d = cornell
    return closest_hit(accel, o, d)


@pytest.fixture(scope="module")
def inner_rays(cornell):
    """Rays from inside the box in all directions (secondary-ray-like), some with tmin/tmax,
    ignore, and zero direction components."""
    scene, _, _, _ = cornell
    rng = np.random.default_rng(3)
    n = 6000
    lo, hi = scene.bounds()
    o = rng.uniform(lo + 1, hi - 1, size=(n, 3))
    d = rng.normal(size=(n, 3))
    d[::17, 0] = 0.0
    d[1::17, 1] = -0.0
    d[2::17, :2] = 0.0
    tmin = np.where(np.arange(n) % 3 == 0, rng.uniform(0, 50, n), 0.0)
    tmax = np.where(np.arange(n) % 4 == 0, tmin + rng.uniform(1, 300, n), np.inf)
    ignore = np.where(np.arange(n) % 5 == 0, rng.integers(0, scene.n_triangles, n), -1)
    return o, d, tmin, tmax, ignore


def assert_same_hits(a, b, idx=None):
    """b (a sub-packet) equals a at the rays ``idx``, bit for bit."""
    sel = slice(None) if idx is None else idx
    for f in ("t", "triangle", "u", "v"):
        assert np.array_equal(getattr(a, f)[sel], getattr(b, f)), f
    for f in COUNT_FIELDS:
        assert np.array_equal(getattr(a.counts, f)[sel], getattr(b.counts, f)), f


def assert_same_occlusion(a, b, idx=None):
    sel = slice(None) if idx is None else idx
    assert np.array_equal(a.occluded[sel], b.occluded)
    for f in COUNT_FIELDS:
        assert np.array_equal(getattr(a.counts, f)[sel], getattr(b.counts, f)), f


# ---------------------------------------------------------------- packet invariance


SUBSETS = [1, 7, 64, 1000, 20000]


@pytest.mark.parametrize("size", SUBSETS)
def test_closest_hit_subset_invariance(cornell, full_hits, size):
    _, accel, o, d = cornell
    rng = np.random.default_rng(size)
    idx = rng.choice(o.shape[0], size=size, replace=False)  # random order too
    assert_same_hits(full_hits, closest_hit(accel, o[idx], d[idx]), idx)


def test_closest_hit_permutation_and_duplicates(cornell, full_hits):
    _, accel, o, d = cornell
    rng = np.random.default_rng(1)
    perm = rng.permutation(o.shape[0])
    assert_same_hits(full_hits, closest_hit(accel, o[perm], d[perm]), perm)
    dup = rng.integers(0, o.shape[0], size=3000)  # a ray twice in one packet
    assert_same_hits(full_hits, closest_hit(accel, o[dup], d[dup]), dup)


@pytest.mark.parametrize("batch", [1, 2, 3, 16, 64])
def test_closest_hit_batch_invariance(cornell, full_hits, batch):
    _, accel, o, d = cornell
    assert_same_hits(full_hits, closest_hit(accel, o, d, batch=batch))


@pytest.fixture(scope="module")
def full_hits_shared(cornell):
    _, accel, o, d = cornell
    return closest_hit(accel, o, d, shared_origin=True)


@pytest.mark.parametrize("size", [1, 7, 1000, None])
@pytest.mark.parametrize("batch", [1, 4, 11])
def test_shared_origin_invariance(cornell, full_hits_shared, size, batch):
    """The eye-ray path (one shared origin) is packet- and batch-invariant too."""
    _, accel, o, d = cornell
    rng = np.random.default_rng(100 + batch)
    idx = rng.permutation(o.shape[0]) if size is None else rng.choice(o.shape[0], size=size, replace=False)
    sub = closest_hit(accel, o[idx], d[idx], shared_origin=True, batch=batch)
    assert_same_hits(full_hits_shared, sub, idx)


def test_shared_origin_close_to_general(cornell, full_hits, full_hits_shared):
    """The two paths round differently, but pick the same triangle except at ties."""
    a, b = full_hits, full_hits_shared
    differ = a.triangle != b.triangle
    assert differ.mean() < 1e-3
    assert np.all((a.triangle[differ] >= 0) & (b.triangle[differ] >= 0))
    np.testing.assert_allclose(a.t[differ], b.t[differ], rtol=1e-4)
    same = ~differ
    np.testing.assert_array_equal(a.t[same], b.t[same])  # t, u, v are float64 from the triangle


def test_shared_origin_requires_one_origin(cornell):
    _, accel, o, d = cornell
    o2 = o[:10].copy()
    o2[3, 0] += 1.0
    with pytest.raises(ValueError):
        closest_hit(accel, o2, d[:10], shared_origin=True)


@pytest.mark.parametrize("batch", [1, 4, 9])
def test_inner_rays_invariance(cornell, inner_rays, batch):
    """With tmin, tmax, ignore and zero components, per ray; any_hit too."""
    _, accel, _, _ = cornell
    o, d, tmin, tmax, ignore = inner_rays
    full = closest_hit(accel, o, d, tmin=tmin, tmax=tmax, ignore=ignore)
    full_occ = any_hit(accel, o, d, tmin=tmin, tmax=tmax, ignore=ignore)
    assert (full.triangle >= 0).mean() > 0.5
    np.testing.assert_array_equal(full_occ.occluded, full.triangle >= 0)
    rng = np.random.default_rng(batch)
    for size in (1, 7, 500):
        idx = rng.choice(o.shape[0], size=size, replace=False)
        sub = closest_hit(accel, o[idx], d[idx], tmin=tmin[idx], tmax=tmax[idx], ignore=ignore[idx],
                          batch=batch)
        assert_same_hits(full, sub, idx)
        occ = any_hit(accel, o[idx], d[idx], tmin=tmin[idx], tmax=tmax[idx], ignore=ignore[idx],
                      batch=batch)
        assert_same_occlusion(full_occ, occ, idx)
    # one ray at a time for a few rays
    for i in rng.choice(o.shape[0], size=5, replace=False):
        one = closest_hit(accel, o[i : i + 1], d[i : i + 1], tmin=tmin[i], tmax=tmax[i],
                          ignore=ignore[i : i + 1], batch=batch)
        assert_same_hits(full, one, [i])


@pytest.mark.slow
@pytest.mark.parametrize("size", [1, 7, 5000, None])
@pytest.mark.parametrize("batch", [1, 2, 5])
def test_any_hit_invariance(cornell, size, batch):
    _scene, accel, o, d = cornell
    # shadow-like rays: from the eye hits toward a point under the ceiling
    pick = np.random.default_rng(0).choice(o.shape[0], size=12000, replace=False)
    hits = closest_hit(accel, o[pick], d[pick])
    ok = np.flatnonzero(hits.triangle >= 0)
    p = o[pick][ok] + hits.t[ok, None] * d[pick][ok]
    to = np.array([278.0, 400.0, 280.0]) - p
    full = any_hit(accel, p, to, tmin=1e-4, tmax=1 - 1e-4, ignore=hits.triangle[ok])
    assert 0.01 < full.occluded.mean() < 0.99
    ref = any_hit(accel, p, to, tmin=1e-4, tmax=1 - 1e-4, ignore=hits.triangle[ok], batch=batch)
    assert_same_occlusion(full, ref)
    rng = np.random.default_rng(10 * batch + (size or 0))
    idx = rng.permutation(p.shape[0]) if size is None else rng.choice(p.shape[0], size=size, replace=False)
    sub = any_hit(accel, p[idx], to[idx], tmin=1e-4, tmax=1 - 1e-4, ignore=hits.triangle[ok][idx], batch=batch)
    assert_same_occlusion(full, sub, idx)


# ---------------------------------------------------------------- render passes


@pytest.fixture(scope="module")
def frame64():
    cfg = config_from_dict({"resolution": [64, 64]})
    scene = load_scene("cornell", resolution=[64, 64])
    accel = build_accel(scene.triangles)
    frame = Frame.create(scene, accel, cfg)
    pixels = np.arange(64 * 64)
    g = cast(frame, pixels)
    full = {f.__name__: f(frame, g) for f in (rcast_pass, reflect_pass, refract_pass)}
    return frame, g, full


def test_passes_do_work(frame64):
    _, g, full = frame64
    assert (g.triangle >= 0).mean() > 0.8
    rad, work = full["rcast_pass"]
    assert rad.max() > 0 and work["shadow_rays"].sum() > 0
    assert full["reflect_pass"][1]["secondary_rays"].sum() > 0
    assert full["refract_pass"][1]["secondary_rays"].sum() > 0
    for _, (rad, work) in full.items():
        assert set(work) == set(WORK_KEYS)
        assert np.isfinite(rad).all() and (rad >= 0).all()


def samples_of(idx: np.ndarray, spp: int) -> np.ndarray:
    """The sample rows of pixels ``idx`` (a pixel's ``spp`` samples are consecutive)."""
    return (np.asarray(idx)[:, None] * spp + np.arange(spp)).ravel()


@pytest.mark.parametrize("size", [1, 7, 333, 2048])
def test_pass_subset_invariance(frame64, size):
    frame, g_full, full = frame64
    assert frame.spp == 4  # the default: four jittered samples per pixel
    rng = np.random.default_rng(size)
    # bias toward pixels that see the mirror and glass spheres so every pass has work
    spec = np.unique(np.flatnonzero(
        (g_full.triangle >= 0) & (frame.kind[np.maximum(g_full.triangle, 0)] > 0)
    ) // frame.spp)
    if size <= 7:
        idx = rng.choice(spec, size=size, replace=False)
    else:
        idx = rng.choice(64 * 64, size=size, replace=False)  # random order too
    g = cast(frame, idx)
    rows = samples_of(idx, frame.spp)
    assert_same_hits(g_full.hits, g.hits, rows)
    np.testing.assert_array_equal(g.light, g_full.light[rows])
    np.testing.assert_array_equal(g.sees_light, g_full.sees_light[rows])
    for f in (rcast_pass, reflect_pass, refract_pass):
        rad, work = f(frame, g)
        rad_full, work_full = full[f.__name__]
        assert np.array_equal(rad, rad_full[idx]), f.__name__
        for k in set(WORK_KEYS) - set(MISS_KEYS):  # misses need the pixels before (tests/test_misses.py)
            assert np.array_equal(work[k], work_full[k][idx]), (f.__name__, k)


def test_pass_single_pixels(frame64):
    """Pixel by pixel for a handful of pixels of every kind."""
    frame, g_full, full = frame64
    kinds = frame.kind[np.maximum(g_full.triangle, 0)]
    picks = []
    for k in (0, 1, 2):
        picks += (np.flatnonzero((g_full.triangle >= 0) & (kinds == k))[:3] // frame.spp).tolist()
    picks += (np.flatnonzero(g_full.triangle < 0)[:2] // frame.spp).tolist()
    picks += (np.flatnonzero(g_full.sees_light)[:2] // frame.spp).tolist()
    assert len(picks) >= 9
    for p in picks:
        g = cast(frame, np.array([p]))
        for f in (rcast_pass, reflect_pass, refract_pass):
            rad, work = f(frame, g)
            rad_full, work_full = full[f.__name__]
            assert np.array_equal(rad[0], rad_full[p]), (p, f.__name__)
            for k in set(WORK_KEYS) - set(MISS_KEYS):
                assert work[k][0] == work_full[k][p], (p, f.__name__, k)


def test_pass_batch_invariance(frame64):
    frame, _, full = frame64
    cfg = config_from_dict({"resolution": [64, 64], "render": {"batch": 1}})
    frame1 = Frame.create(frame.scene, frame.accel, cfg)
    g = cast(frame1, np.arange(64 * 64))
    for f in (rcast_pass, reflect_pass, refract_pass):
        rad, work = f(frame1, g)
        assert np.array_equal(rad, full[f.__name__][0])
        for k in WORK_KEYS:
            assert np.array_equal(work[k], full[f.__name__][1][k])


# ---------------------------------------------------------------- recorded traffic


def slab_entry_exit(lo, hi, o, d, tmin, tmax):
    """Entry and exit distances of the segment [tmin, tmax] of one ray through closed boxes.

    lo, hi : (3,) or (k, 3). Returns scalars or (k,) arrays; crossed where entry <= exit.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d
        t0 = (lo - o) * inv
        t1 = (hi - o) * inv
    zero = d == 0.0
    inside = (o >= lo) & (o <= hi)
    near = np.where(zero, np.where(inside, -np.inf, np.inf), np.minimum(t0, t1))
    far = np.where(zero, np.where(inside, np.inf, -np.inf), np.maximum(t0, t1))
    return np.maximum(near.max(axis=-1), tmin), np.minimum(far.min(axis=-1), tmax)


def check_touched(accel, res, o, d, tmin, tmax):
    tree = accel.tree
    tc = res.touched
    c = res.counts
    r = o.shape[0]
    assert tc.node_ptr.shape == tc.leaf_ptr.shape == (r + 1,)
    assert tc.node_ptr[0] == 0 and tc.leaf_ptr[0] == 0
    np.testing.assert_array_equal(np.diff(tc.node_ptr), c.node_visits)
    np.testing.assert_array_equal(np.diff(tc.leaf_ptr), c.leaf_visits)
    assert tc.node_ptr[-1] == tc.node_ids.shape[0]
    assert tc.leaf_ptr[-1] == tc.leaf_ids.shape[0]
    assert np.all(c.leaf_visits <= c.leaves_crossed)
    assert np.all((tc.node_ids >= 0) & (tc.node_ids < tree.leaf_offset))
    assert np.all((tc.leaf_ids >= 0) & (tc.leaf_ids < tree.n_leaves))
    size = accel.leaf_size
    owner = np.repeat(np.arange(r), np.diff(tc.leaf_ptr))
    tests = np.bincount(owner, weights=size[tc.leaf_ids], minlength=r).astype(np.int64)
    np.testing.assert_array_equal(tests, c.tri_tests)
    tmin = np.broadcast_to(np.asarray(tmin, float), (r,))
    tmax = np.broadcast_to(np.asarray(tmax, float), (r,))
    for i in range(r):
        leaves = tc.leaf_ids[tc.leaf_ptr[i] : tc.leaf_ptr[i + 1]]
        nodes = tc.node_ids[tc.node_ptr[i] : tc.node_ptr[i + 1]]
        assert len(set(leaves.tolist())) == leaves.shape[0]  # no leaf twice
        assert len(set(nodes.tolist())) == nodes.shape[0]
        # nodes level by level: heap indices never go back to a shallower level
        levels = np.floor(np.log2(nodes + 1)).astype(int)
        assert np.all(np.diff(levels) >= 0)
        if tree.levels and (c.leaves_crossed[i] > 0):
            assert nodes[0] == 0  # the root first
        entries = []
        for leaf in leaves:
            k = leaf + tree.leaf_offset
            a, b = slab_entry_exit(tree.lo[k], tree.hi[k], o[i], d[i], tmin[i], tmax[i])
            assert a <= b, (i, leaf)  # the segment does cross the leaf
            entries.append(a)
        assert np.all(np.diff(entries) >= 0), (i, entries)  # near to far
        # every node on the list is crossed, and is an ancestor of a crossed leaf
        for node in nodes:
            a, b = slab_entry_exit(tree.lo[node], tree.hi[node], o[i], d[i], tmin[i], tmax[i])
            assert a <= b


@pytest.mark.slow
@pytest.mark.parametrize("batch", [1, 4])
def test_record_primary(cornell, full_hits, batch):
    _, accel, o, d = cornell
    idx = np.random.default_rng(5).choice(o.shape[0], size=400, replace=False)
    res = closest_hit(accel, o[idx], d[idx], record=True, batch=batch)
    assert_same_hits(full_hits, res, idx)  # recording changes nothing
    check_touched(accel, res, o[idx], d[idx], 0.0, np.inf)
    occ = any_hit(accel, o[idx], d[idx], record=True, batch=batch)
    check_touched(accel, occ, o[idx], d[idx], 0.0, np.inf)


@pytest.mark.slow
def test_record_inner_rays(cornell, inner_rays):
    _, accel, _, _ = cornell
    o, d, tmin, tmax, ignore = (a[:500] for a in inner_rays)
    res = closest_hit(accel, o, d, tmin=tmin, tmax=tmax, ignore=ignore, record=True)
    check_touched(accel, res, o, d, tmin, tmax)
    # the recorded leaves, in order, are a prefix of every crossed leaf
    occ = any_hit(accel, o, d, tmin=tmin, tmax=tmax, ignore=ignore, record=True)
    check_touched(accel, occ, o, d, tmin, tmax)
    for i in range(o.shape[0]):
        a = occ.touched.leaf_ids[occ.touched.leaf_ptr[i] : occ.touched.leaf_ptr[i + 1]]
        b = res.touched.leaf_ids[res.touched.leaf_ptr[i] : res.touched.leaf_ptr[i + 1]]
        m = min(a.shape[0], b.shape[0])
        np.testing.assert_array_equal(a[:m], b[:m])
        assert occ.counts.leaf_visits[i] <= res.counts.leaf_visits[i]


def test_missing_rays_visit_every_crossed_leaf_near_to_far():
    """Rays that hit nothing test every leaf their segment crosses: the full list, which
    must be exactly the leaves whose box the segment meets, ordered by entry distance."""
    rng = np.random.default_rng(8)
    n = 300
    c = rng.uniform(0, 1, size=(n, 1, 3))
    tri = c + rng.uniform(-0.01, 0.01, size=(n, 3, 3))  # tiny: most rays miss
    accel = build_accel(tri, levels=7)
    tree = accel.tree
    r = 400
    o = rng.uniform(-0.5, 1.5, size=(r, 3))
    d = rng.normal(size=(r, 3))
    tmin = np.where(np.arange(r) % 2 == 0, 0.0, rng.uniform(0, 0.5, r))
    tmax = np.where(np.arange(r) % 3 == 0, rng.uniform(0.5, 2.0, r), np.inf)
    res = closest_hit(accel, o, d, tmin=tmin, tmax=tmax, record=True)
    check_touched(accel, res, o, d, tmin, tmax)
    miss = np.flatnonzero(res.triangle < 0)
    assert miss.shape[0] > r // 2
    for i in miss:
        leaves = res.touched.leaf_ids[res.touched.leaf_ptr[i] : res.touched.leaf_ptr[i + 1]]
        assert res.counts.leaf_visits[i] == res.counts.leaves_crossed[i] == leaves.shape[0]
        off = tree.leaf_offset
        a, b = slab_entry_exit(tree.lo[off:], tree.hi[off:], o[i], d[i], tmin[i], tmax[i])
        assert set(leaves.tolist()) == set(np.flatnonzero(a <= b).tolist()), i
        assert np.all(np.diff(a[leaves]) >= 0), i
        # inner nodes visited = every inner node whose box the segment meets
        nodes = res.touched.node_ids[res.touched.node_ptr[i] : res.touched.node_ptr[i + 1]]
        a, b = slab_entry_exit(tree.lo[:off], tree.hi[:off], o[i], d[i], tmin[i], tmax[i])
        assert set(nodes.tolist()) == set(np.flatnonzero(a <= b).tolist()), i


def test_counts_relations(cornell, full_hits):
    _scene, accel, _, _ = cornell
    c = full_hits.counts
    hit = full_hits.triangle >= 0
    assert np.all(c.leaf_visits[hit] >= 1)
    assert np.all(c.leaf_visits <= c.leaves_crossed)
    assert np.all(c.tri_tests <= c.leaf_visits * int(accel.leaf_size.max()))
    assert np.all(c.node_visits <= 2 ** accel.tree.levels - 1)
    assert np.all(c.node_visits[c.leaves_crossed > 0] >= accel.tree.levels)
    # a ray that misses the root box does no work at all
    o = np.array([[1e4, 1e4, 1e4]])
    d = np.array([[1.0, 0.0, 0.0]])
    far = closest_hit(accel, o, d, record=True)
    assert far.triangle[0] == -1
    for f in COUNT_FIELDS:
        assert getattr(far.counts, f)[0] == 0
    assert far.touched.node_ids.shape == far.touched.leaf_ids.shape == (0,)


def test_shadow_ray_work_is_kept_apart():
    """A pass's node_visits ... tri_tests are its eye and secondary rays' alone; the
    shadow rays' traversal is counted under shadow_* (the thesis traces them in passes
    of their own)."""
    from tlm.config import config_from_dict
    from tlm.render.frame import Frame, cast
    from tlm.render.passes import rcast_pass

    scene = load_scene("cornell", resolution=[32, 32])
    accel = build_accel(scene.triangles)
    frame = Frame.create(scene, accel, config_from_dict({}))
    g = cast(frame, np.arange(32 * 32))
    _, work = rcast_pass(frame, g)
    for name in COUNT_FIELDS:  # a pixel's count is its samples' sum
        np.testing.assert_array_equal(work[name], getattr(g.hits.counts, name).reshape(-1, g.spp).sum(axis=1))
    lit = work["shadow_rays"] > 0
    assert lit.any()
    assert np.all(work["shadow_node_visits"][lit] > 0) and np.all(work["shadow_node_visits"][~lit] == 0)
    assert np.all(work["shadow_tri_tests"] >= 0)
