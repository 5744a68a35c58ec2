"""The compiled traversal (numba) against the numpy reference: bit for bit, on hard rays.

``TLM_KERNELS`` selects the engine; both must return the same hits (``t``, ``u``, ``v``
and the triangle, compared as bytes), the same work counts and the same memory
touched, for closest and any hits, with and without recording. The rays are chosen to
reach every branch of the kernels: eye rays with a shared origin, rays through edges
and vertices, axis-aligned rays and zero or subnormal direction components, rays
starting on split planes and inside the box, ``tmax`` exactly at a hit (the float64
check fails and the float64 fallback runs), origins float32 cannot hold, directions
far from unit length, ignored triangles, empty packets, and trees deep enough that
the kernel's buffers overflow and it reruns.
"""

from __future__ import annotations

import numpy as np
import pytest

from tests.helpers_gather import random_gather
from tlm.kernels import traverse
from tlm.kernels.camera import primary_rays
from tlm.kernels.traverse import any_hit, build_accel, closest_hit
from tlm.scenes.loader import load_scene

pytestmark = pytest.mark.skipif(not traverse._numba_available(), reason="numba is not installed")


@pytest.fixture(scope="module", params=["cornell", "ring", "room"])
def scene_accel(request):
    scene = load_scene(request.param)
    return scene, build_accel(scene.triangles)


def run(monkeypatch, engine, fn, *args, **kw):
    monkeypatch.setenv("TLM_KERNELS", engine)
    assert traverse.engine() == engine
    return fn(*args, **kw)


def as_bytes(res) -> dict:
    out = {}
    for name in ("t", "triangle", "u", "v", "occluded"):
        if hasattr(res, name):
            a = np.asarray(getattr(res, name))
            out[name] = (a.dtype.str, a.shape, a.tobytes())
    for group in ("counts", "touched"):
        part = getattr(res, group)
        if part is not None:
            for k, a in vars(part).items():
                out[f"{group}.{k}"] = (a.dtype.str, a.shape, a.tobytes())
    return out


def assert_same(monkeypatch, fn, *args, **kw):
    a = run(monkeypatch, "numpy", fn, *args, **kw)
    b = run(monkeypatch, "numba", fn, *args, **kw)
    ba, bb = as_bytes(a), as_bytes(b)
    assert list(ba) == list(bb)
    for k in ba:
        assert ba[k] == bb[k], f"{k} differs between the engines"
    return a


def hard_rays(scene, n: int, seed: int):
    """Origins, directions, tmin, tmax, ignore: a mix of the cases in the module doc."""
    rng = np.random.default_rng(seed)
    tri = scene.triangles.reshape(-1, 3, 3)
    lo, hi = tri.reshape(-1, 3).min(axis=0), tri.reshape(-1, 3).max(axis=0)
    size = hi - lo
    k = n // 8
    o = lo - 0.2 * size + rng.random((n, 3)) * 1.4 * size
    pick = rng.integers(0, tri.shape[0], n)
    target = np.einsum("nk,nkj->nj", rng.dirichlet([1, 1, 1], n), tri[pick])
    d = target - o
    # through vertices and edge midpoints (shared by neighbours: ties and edge tolerance)
    d[:k] = tri[pick[:k], 0] - o[:k]
    d[k:2 * k] = 0.5 * (tri[pick[k:2 * k], 0] + tri[pick[k:2 * k], 1]) - o[k:2 * k]
    # axis-aligned, signed zeros and subnormal components
    axis = rng.integers(0, 3, k)
    d[2 * k:3 * k] = 0.0
    d[2 * k + np.arange(k), axis] = rng.choice([-1.0, 1.0], k)
    d[2 * k:3 * k:2, (axis[::2] + 1) % 3] = -0.0
    d[3 * k:3 * k + k // 2, 0] = 1e-310
    # origins on the root box's faces and the centre's planes
    o[4 * k:5 * k, 0] = lo[0]
    o[4 * k:5 * k:2, 1] = 0.5 * (lo[1] + hi[1])
    # lengths far from one (rescaled by powers of two)
    d[5 * k:5 * k + k // 2] *= 1e-20
    d[5 * k + k // 2:6 * k] *= 1e20
    tmin = np.where(rng.random(n) < 0.3, 1e-4 * np.linalg.norm(size), 0.0)
    tmax = np.where(rng.random(n) < 0.3, rng.random(n) * 2.0, np.inf)
    ignore = np.where(rng.random(n) < 0.4, pick, -1)
    return o, d, tmin, tmax, ignore


@pytest.mark.slow
@pytest.mark.parametrize("record", [False, True])
def test_hard_rays(scene_accel, monkeypatch, record):
    scene, accel = scene_accel
    o, d, tmin, tmax, ignore = hard_rays(scene, 4000, seed=7)
    h = assert_same(monkeypatch, closest_hit, accel, o, d, tmin=tmin, tmax=tmax, ignore=ignore, record=record)
    assert (h.triangle >= 0).mean() > 0.3  # the rays do reach the scene
    s = assert_same(monkeypatch, any_hit, accel, o, d, tmin=tmin, tmax=tmax, ignore=ignore, record=record)
    assert s.occluded.mean() > 0.3


@pytest.mark.slow
def test_eye_rays_with_a_shared_origin(scene_accel, monkeypatch):
    scene, accel = scene_accel
    w, h = scene.camera.width, scene.camera.height
    o, d = primary_rays(scene.camera, np.arange(0, w * h, 7))
    hits = assert_same(monkeypatch, closest_hit, accel, o, d, shared_origin=True, record=True)
    assert (hits.triangle >= 0).mean() > 0.5
    o2 = o.copy()
    o2[3] += 1.0
    for engine in ("numpy", "numba"):
        with pytest.raises(ValueError, match="shared_origin"):
            run(monkeypatch, engine, closest_hit, accel, o2, d, shared_origin=True)


@pytest.mark.slow
def test_tmax_at_the_hit_runs_the_float64_fallback(scene_accel, monkeypatch):
    """tmax equal to the float64 hit distance: float32 accepts what the check refuses,
    so the float64 fallback decides (checked to run under numpy, then compared)."""
    scene, accel = scene_accel
    o, d, _, _, _ = hard_rays(scene, 3000, seed=11)
    first = closest_hit(accel, o, d)
    hit = first.triangle >= 0
    o, d, tmax = o[hit], d[hit], first.t[hit]
    calls = []
    real = traverse._traverse

    def spy(*args, **kw):
        if kw.get("exact64"):
            calls.append(args[1].shape[0])
        return real(*args, **kw)

    monkeypatch.setattr(traverse, "_traverse", spy)
    res = assert_same(monkeypatch, closest_hit, accel, o, d, tmax=tmax, record=True)
    assert calls and sum(calls) > 10, "the float64 fallback did not run"
    assert (res.triangle != first.triangle[hit]).any()  # the hit at tmax itself is excluded
    assert_same(monkeypatch, any_hit, accel, o, d, tmax=tmax, record=True)


@pytest.mark.slow
def test_origins_float32_cannot_hold(scene_accel, monkeypatch):
    _, accel = scene_accel
    centre = 0.5 * (accel.tree.lo[0] + accel.tree.hi[0])
    rng = np.random.default_rng(5)
    d = rng.normal(size=(200, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    o = centre - 1e39 * d  # far beyond float32's range, aimed at the scene
    o[::2] = centre - 1e6 * d[::2] + rng.normal(size=(100, 3)) * 1e-3
    res = assert_same(monkeypatch, closest_hit, accel, o, d, record=True)
    assert (res.triangle >= 0).any()
    assert_same(monkeypatch, any_hit, accel, o, d)


def test_empty_and_missing_packets(scene_accel, monkeypatch):
    _, accel = scene_accel
    z = np.zeros((0, 3))
    assert_same(monkeypatch, closest_hit, accel, z, z, record=True)
    assert_same(monkeypatch, any_hit, accel, z, z, record=True)
    far = np.full((50, 3), 1e5) + np.arange(50)[:, None]
    res = assert_same(monkeypatch, closest_hit, accel, far, np.ones((50, 3)), record=True)
    assert (res.triangle == -1).all()
    inverted = assert_same(monkeypatch, closest_hit, accel, far * 0, np.ones((50, 3)), tmin=5.0, tmax=1.0)
    assert (inverted.triangle == -1).all()


@pytest.fixture
def statuses(monkeypatch) -> list[int]:
    """The status of every call of the compiled kernel (0: done; else the buffer that overflowed)."""
    seen: list[int] = []
    real = traverse._jit_trace

    def spy(*args):
        out = real(*args)
        seen.append(out[0])
        return out

    monkeypatch.setattr(traverse, "_jit_trace", spy)
    return seen


@pytest.mark.slow
@pytest.mark.parametrize("record", [True, False])
@pytest.mark.parametrize("fn", [closest_hit, any_hit])
def test_deep_trees_and_small_buffers_rerun(monkeypatch, statuses, record, fn):
    """A deep tree and tiny starting buffers: every buffer overflows, the kernel reruns
    with larger ones, and the answers still equal numpy's (without record, the leaf list
    of the depth-first walk is the buffer that overflows)."""
    scene = load_scene("room")
    accel = build_accel(scene.triangles, levels=13)
    o, d, tmin, tmax, ignore = hard_rays(scene, 1500, seed=3)
    monkeypatch.setattr(traverse, "JIT_BUFFERS", (2, 1, 1))
    seen = statuses
    assert_same(monkeypatch, fn, accel, o, d, tmin=tmin, tmax=tmax, ignore=ignore, record=record)
    assert ({1, 2, 3} if record else {1}) <= set(seen) and seen[-1] == 0  # each buffer overflowed once at least


def test_buffers_learned_on_the_accel_spare_the_reruns(monkeypatch, statuses):
    """After a call whose buffers overflowed, the accel keeps what a ray needed, and the
    next calls start with buffers that hold it: one call each, the same answers."""
    monkeypatch.setenv("TLM_KERNELS", "numba")
    scene = load_scene("room")
    accel = build_accel(scene.triangles)
    o, d, tmin, tmax, ignore = hard_rays(scene, 600, seed=5)
    monkeypatch.setattr(traverse, "JIT_BUFFERS", (1 << 12, 1, 1))
    seen = statuses
    closest_hit(accel, o, d, tmin=tmin, tmax=tmax, ignore=ignore)  # (not recorded: nothing to learn)
    assert "_jit_per_ray" not in accel.__dict__ and seen == [0]
    first = closest_hit(accel, o, d, tmin=tmin, tmax=tmax, ignore=ignore, record=True)
    assert len(seen) > 2 and set(seen[1:-1]) <= {2, 3} and seen[-1] == 0  # overflowed, then held
    leaves, nodes = accel.__dict__["_jit_per_ray"]
    assert leaves * 600 >= first.counts.leaf_visits.sum() and nodes * 600 >= first.counts.node_visits.sum()
    seen.clear()
    again = closest_hit(accel, o, d, tmin=tmin, tmax=tmax, ignore=ignore, record=True)
    assert seen == [0]
    assert as_bytes(again) == as_bytes(first)


@pytest.mark.parametrize("engine", ["numba", "numpy"])
def test_prepare_builds_what_the_engine_reads(monkeypatch, engine):
    monkeypatch.setenv("TLM_KERNELS", engine)
    accel = build_accel(load_scene("cornell").triangles)
    assert not {"jit_layout", "soa", "soa64"} & set(accel.__dict__)  # (built on first use)
    assert accel.prepare() is accel
    built = {"jit_layout"} if engine == "numba" else {"soa", "soa64"}
    assert {"jit_layout", "soa", "soa64"} & set(accel.__dict__) == built


@pytest.mark.parametrize("memory_factor", [20.0, 1.3])
def test_the_compiled_layout_holds_the_numpy_constants(scene_accel, memory_factor):
    """Every padded slot of the compiled kernel's copy holds the float32 and float64
    constants the numpy engine tests (``soa``, ``soa64``) of the slot it maps back to,
    leaves start on a multiple of PAD slots, and padding is NaN with no triangle's id."""
    from tlm.kernels import _jit_leaf

    scene, _ = scene_accel
    accel = build_accel(scene.triangles, memory_factor=memory_factor)  # (slots shared by leaves at 20)
    lay, s32, s64 = accel.jit_layout, accel.soa, accel.soa64
    real = lay.back >= 0
    pad = _jit_leaf.PAD
    assert (lay.first % pad == 0).all() and (lay.last - lay.first == -(-lay.size // pad) * pad).all()
    assert (lay.size == accel.leaf_last - accel.leaf_first).all() and lay.back.shape == (lay.soa32.shape[1],)
    want32 = np.concatenate([s32.v0, s32.e1n, s32.e2, s32.n, s32.nn])[:, lay.back[real]]
    assert lay.soa32[:15, real].tobytes() == want32.tobytes()
    assert lay.soa32[15, real].view(np.int32).tolist() == s32.ids[lay.back[real]].tolist()
    assert np.isnan(lay.soa32[:15, ~real]).all() and (lay.soa32[15, ~real].view(np.int32) == -2).all()
    assert lay.soa64.tobytes() == np.concatenate([s64.v0, s64.e1n, s64.e2]).tobytes()
    assert lay.ids.tolist() == s64.ids.tolist()
    for leaf in range(lay.size.shape[0]):  # a leaf's slots in order, then its padding
        got = lay.back[lay.first[leaf]:lay.last[leaf]]
        n = int(lay.size[leaf])
        assert got[:n].tolist() == list(range(accel.leaf_first[leaf], accel.leaf_last[leaf]))
        assert (got[n:] == -1).all()


def test_the_compiled_ray_checks_are_numpys():
    """``_prepare``'s one-pass checks of the directions and the shared-origin test, against
    the numpy expressions they replace, on zeros of both signs, subnormals, the limits
    2**32 and 2**-30, infinities and NaN."""
    from tlm.kernels import _jit_rays

    specials = np.array([0.0, -0.0, 5e-324, -2.2e-308, np.finfo(float).tiny, 1.0, -3.5, 2.0**32, -(2.0**32),
                         np.nextafter(2.0**32, 0), 2.0**-30, np.nextafter(2.0**-30, 0), 2.0**-31, 1e300,
                         np.inf, -np.inf, np.nan])
    rng = np.random.default_rng(5)
    for _ in range(3000):
        n = int(rng.integers(1, 5))
        d = specials[rng.integers(0, specials.shape[0], size=(n, 3))]
        mix = rng.random((n, 3)) < 0.5  # and ordinary values of every scale
        d[mix] = rng.normal(size=int(mix.sum())) * 10.0 ** rng.integers(-12, 12, size=int(mix.sum()))
        mag = np.abs(d)
        with np.errstate(invalid="ignore", over="ignore"):
            plain = bool(mag.max() < 2.0**32 and (mag[:, 0] + mag[:, 1] + mag[:, 2]).min() >= 2.0**-30)
        assert _jit_rays.direction_checks(d) == (plain, bool((mag < np.finfo(float).tiny).any())), d
        o = np.repeat(d[:1], n, axis=0)
        if rng.random() < 0.5:
            o[rng.integers(0, n)] = d[-1]
        assert _jit_rays.same_rows(o) == bool((o == o[:1]).all()), o
    assert _jit_rays.same_rows(np.zeros((0, 3))) and not _jit_rays.same_rows(np.full((1, 3), np.nan))


def test_the_compiled_id_passes_are_numpys():
    """``_traverse_jit``'s one-pass flags of the ignored ids and its triangle ids of the
    hit slots, against the numpy expressions they replace: ids at int32's limits, -1 and
    below, none, and slots of an accel with no triangles."""
    from tlm.kernels import _jit_rays

    top = np.iinfo(np.int32).max
    specials = np.array([-(2**40), -2, -1, 0, 1, 7, top - 1, top, top + 1, 2**40], dtype=np.int64)
    rng = np.random.default_rng(6)
    for n in [0, *rng.integers(1, 9, size=3000)]:
        ig = specials[rng.integers(0, specials.shape[0], size=n)]
        outside = (ig < 0) | (ig > top)
        has, remap = _jit_rays.ignore_flags(ig)
        assert has == bool((np.where(outside, -1, ig) >= 0).any()), ig
        assert remap == bool((np.where(outside, -1, ig) != ig).any()), ig
    ids = rng.integers(0, 1000, size=50)
    slot = rng.integers(-1, 50, size=2000)
    assert np.array_equal(_jit_rays.triangles_of(slot, ids), np.where(slot >= 0, ids[np.maximum(slot, 0)], -1))
    none = np.full(5, -1, dtype=np.int64)
    assert np.array_equal(_jit_rays.triangles_of(none, np.zeros(0, dtype=np.int64)), none)


@pytest.mark.parametrize("engine", ["numba", "numpy"])
def test_the_rays_limits_and_ids_in_every_form(monkeypatch, engine):
    """``_prepare``'s per-ray ``tmin``, ``tmax`` and ``ignore``, from a value, a 0-d
    array, a list, a float32 array, a strided view, a (1,) array and one per ray: the
    values the broadcast and copy gave (bit for bit: NaN, -0.0, an id below -1 or past
    int32), the same answers from both queries in both forms, and the caller's arrays
    left as they were (a per-ray array is now passed on, no longer copied)."""
    monkeypatch.setenv("TLM_KERNELS", engine)
    scene = load_scene("cornell")
    accel = build_accel(scene.triangles)
    o, d = primary_rays(scene.camera, np.arange(0, scene.camera.width * scene.camera.height, 97))
    r = o.shape[0]
    rng = np.random.default_rng(7)
    limits = [0.0, -0.0, 3, np.nan, np.inf, np.array(0.25), np.float32(0.5), np.array([0.0]) if r == 1 else None,
              rng.random(r) * 0.1, list(rng.random(r)), rng.random(2 * r)[::2], rng.random(r).astype(np.float32)]
    ids = [None, -1, np.array(5), rng.integers(-3, 3000, size=r), rng.integers(-(2**40), 2**40, size=r),
           list(rng.integers(-1, 3000, size=r)), rng.integers(0, 3000, size=2 * r)[::2]]
    bits = np.ndarray.tobytes
    for k in range(len(limits) * 2):
        tmin = limits[k % len(limits)]
        tmax = limits[(k * 5 + 3) % len(limits)]
        ignore = ids[k % len(ids)]
        if tmin is None or tmax is None:
            continue
        tmax = np.inf if isinstance(tmax, float) and tmax == 0.0 else tmax
        kept = [np.array(a, copy=True) for a in (tmin, tmax, 0 if ignore is None else ignore)]
        _, _, t0, t1, ig, _ = traverse._prepare(o, d, tmin, tmax, ignore)
        assert bits(t0) == bits(np.maximum(np.broadcast_to(np.asarray(tmin, dtype=np.float64), (r,)), 0.0))
        assert bits(t1) == bits(np.ascontiguousarray(np.broadcast_to(np.asarray(tmax, dtype=np.float64), (r,))))
        want = np.full(r, -1) if ignore is None else np.broadcast_to(np.asarray(ignore, dtype=np.int64), (r,))
        assert bits(ig) == bits(np.ascontiguousarray(want))
        if isinstance(tmin, np.ndarray) and tmin.ndim == 1:
            tmin_copy = np.array(tmin)
        else:
            tmin_copy = tmin
        hits = closest_hit(accel, o, d, tmin, tmax, ignore)
        again = closest_hit(accel, o, d, tmin_copy, np.array(tmax, dtype=np.float64),
                            None if ignore is None else np.array(ignore, dtype=np.int64))
        assert bits(hits.t) == bits(again.t) and (hits.triangle == again.triangle).all()
        occ = any_hit(accel, o, d, tmin, tmax, ignore)
        assert (occ.occluded == (hits.triangle >= 0)).all()
        for was, now in zip(kept, (tmin, tmax, 0 if ignore is None else ignore), strict=True):
            assert bits(np.asarray(was)) == bits(np.asarray(now))


def test_unknown_engine_is_refused(monkeypatch):
    monkeypatch.setenv("TLM_KERNELS", "cuda")
    with pytest.raises(ValueError, match="TLM_KERNELS"):
        traverse.engine()


def tree_bytes(tree) -> dict:
    out = {k: (v.dtype.str, v.shape, v.tobytes()) for k, v in vars(tree).items() if isinstance(v, np.ndarray)}
    out.update({k: v for k, v in vars(tree).items() if not isinstance(v, np.ndarray)})
    return out


@pytest.mark.parametrize("case", ["cube", "faces", "coincident", "one", "empty", "deep"])
def test_point_trees(monkeypatch, case):
    from tlm.kernels.bsp import build_point_tree

    rng = np.random.default_rng(1)
    pts = {
        "cube": rng.random((30000, 3)),
        "faces": np.where(rng.random((20000, 3)) < 0.3, 0.0, rng.random((20000, 3))),
        "coincident": np.repeat(rng.random((40, 3)), 50, axis=0),
        "one": rng.random((1, 3)),
        "empty": np.zeros((0, 3)),
        "deep": rng.normal(size=(5000, 3)) * np.array([1e-3, 1.0, 1e3]),
    }[case]
    levels = 16 if case == "deep" else None
    a = run(monkeypatch, "numpy", build_point_tree, pts, levels=levels)
    b = run(monkeypatch, "numba", build_point_tree, pts, levels=levels)
    assert tree_bytes(a) == tree_bytes(b)


@pytest.mark.parametrize("memory_factor", [20.0, 1.3])
def test_triangle_trees(scene_accel, monkeypatch, memory_factor):
    """The geometry BSP with its expansion pass, and truncated where the reserved
    memory runs out."""
    from tlm.kernels.bsp import build_triangle_tree

    scene, _ = scene_accel
    levels = None if memory_factor > 2 else 12
    a = run(monkeypatch, "numpy", build_triangle_tree, scene.triangles, levels=levels, memory_factor=memory_factor)
    b = run(monkeypatch, "numba", build_triangle_tree, scene.triangles, levels=levels, memory_factor=memory_factor)
    assert tree_bytes(a) == tree_bytes(b)
    assert a.truncated == (memory_factor < 2)


def test_ignore_outside_the_id_range(monkeypatch):
    """An ignore id no triangle has (beyond int32, or negative) ignores nothing, in both
    engines (the compiled test compares ids as int32)."""
    tri = np.array([[[0, 0, 1], [1, 0, 1], [0, 1, 1]], [[0, 0, 2], [1, 0, 2], [0, 1, 2]]], float)
    accel = build_accel(tri, levels=0)
    o, d = np.array([[0.25, 0.25, 0.0]] * 4), np.array([[0.0, 0.0, 1.0]] * 4)
    ignore = np.array([2**32, 2**31, -2, 0])  # 2**32 would be triangle 0 cut to 32 bits
    h = assert_same(monkeypatch, closest_hit, accel, o, d, ignore=ignore)
    assert h.triangle.tolist() == [0, 0, 0, 1]
    s = assert_same(monkeypatch, any_hit, accel, o, d, tmax=1.5, ignore=ignore)
    assert s.occluded.tolist() == [True, True, True, False]


def test_shared_origins_equal_but_for_a_zero_sign(monkeypatch):
    """Eye rays whose origins differ only in a zero's sign count as one origin; both
    engines then test with the first ray's float32 origin (here it decides a hit at
    t = 0 on the plane through the origin)."""
    dl = 5e-7  # inside float32's edge tolerance, outside float64's
    tri = np.array([
        [[0, 0, 0], [1, 1, 0], [1, 0, 1]],
        [[dl, -1, 1], [dl + 1, -1, 1], [dl, 1, 1]],
        [[-dl, -1, -1], [-dl - 1, -1, -1], [-dl, 1, -1]],  # a mirror: the box's centre x is 0.0
    ], float)
    accel = build_accel(tri, levels=0)
    d = np.array([[0.0, 0.0, 1.0]] * 2)
    for x in (0.0, -0.0):
        o = np.array([[0.0, 0.0, 0.0], [x, 0.0, 0.0]])
        for shared in (False, True):
            assert_same(monkeypatch, closest_hit, accel, o, d, shared_origin=shared, record=True)


def test_no_triangles(monkeypatch):
    accel = build_accel(np.zeros((0, 3, 3)))
    o, d = np.zeros((2, 3)), np.array([[1.0, 0, 0], [0, 1.0, 0]])
    h = assert_same(monkeypatch, closest_hit, accel, o, d, record=True)
    assert h.triangle.tolist() == [-1, -1] and np.isinf(h.t).all()
    s = assert_same(monkeypatch, any_hit, accel, o, d)
    assert not s.occluded.any()


@pytest.mark.parametrize("filt", ["disk", "mvoxel"])
def test_fixed_radius_gather_is_the_same_compiled(monkeypatch, filt):
    """The compiled fixed-radius gather (tlm.kernels._jit_gather) returns the numpy path's
    densities, work and leaf-read misses bit for bit: a realistic radius, one so small it
    finds nothing, one holding most of the map, photons exactly on a query point, a
    degenerate (one-leaf) tree, and pair buffers that overflow (the block is run again)."""
    from tlm.kernels import _jit_gather, estimate
    from tlm.kernels.bsp import build_point_tree
    from tlm.kernels.memory import Streams

    rng = np.random.default_rng(5)
    pos = rng.uniform(-1.0, 1.0, (3000, 3))
    pos[:50] = pos[50:100]  # coincident photons
    power = rng.uniform(0.0, 1.0, (3000, 3))
    inc = rng.normal(size=(3000, 3))
    inc /= np.linalg.norm(inc, axis=1, keepdims=True)
    pts = np.r_[rng.uniform(-1.1, 1.1, (700, 3)), pos[:20]]
    nrm = rng.normal(size=(720, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    fn = estimate.disk_estimate if filt == "disk" else estimate.mvoxel_estimate
    monkeypatch.setattr(estimate, "QUERY_BLOCK", 256)  # several blocks: misses carried in order
    monkeypatch.setattr(estimate, "JIT_PAIRS", 8)  # the pair buffer overflows: blocks run again
    for levels in (8, 0):
        tree = build_point_tree(pos, levels)
        for radius in (0.12, 1e-9, 1.5):
            out = {}
            for engine in ("numpy", "numba"):
                monkeypatch.setenv("TLM_KERNELS", engine)
                out[engine] = fn(pos, power, inc, tree, pts, nrm, radius, streams=Streams(64, 4))
            for f in ("density", "node_visits", "leaves_visited", "photons_tested", "photons_accepted",
                      "gather_misses"):
                assert np.array_equal(getattr(out["numpy"], f), getattr(out["numba"], f)), (levels, radius, f)
            assert out["numba"].photons_accepted.sum() > 0 or radius < 1e-6
    assert _jit_gather.fixed_radius is not None


@pytest.mark.parametrize("n_threads", [1, 2])
def test_gather_buffers_learned_on_the_map_spare_the_reruns(monkeypatch, n_threads):
    """After a gather whose pair buffers overflowed, the map in leaf order keeps the pairs a
    query needed at that radius, and the next gathers at that radius (a render's next
    batches) start with buffers that hold them: each chunk runs once, the same answers as a
    map that learned nothing. A chunk of a few queries teaches nothing (a dense spot would
    size every later buffer), and another radius starts from the default again."""
    from tlm.kernels import _jit_gather, estimate, threads

    monkeypatch.setenv("TLM_KERNELS", "numba")
    pos, power, inc, tree, pts, nrm = random_gather(9, 4000, 1800, 9)
    monkeypatch.setattr(estimate, "QUERY_BLOCK", 600)  # three blocks a call, of GATHER_MIN_CHUNK queries or more
    monkeypatch.setattr(estimate, "JIT_PAIRS", 600)  # one pair a query to start with: too few
    calls = []
    kernel = _jit_gather.fixed_radius

    def spy(*args):
        need = kernel(*args)
        calls.append(need > args[16].shape[0])  # (the pair buffer overflowed: the chunk runs again)
        return need

    monkeypatch.setattr(_jit_gather, "fixed_radius", spy)
    lp = estimate.leaf_photons(pos, power, inc, tree)

    def gather(prepared, radius, at=pts, normals=nrm):
        calls.clear()
        return estimate.disk_estimate(pos, power, inc, tree, at, normals, radius, prepared=prepared)

    with threads.using(n_threads):
        first = gather(lp, 0.3)
        assert any(calls) and 0.3 in lp.pairs  # the default buffer was too small: learned
        again = gather(lp, 0.3)
        assert calls and not any(calls)  # each chunk once
        fresh = gather(estimate.leaf_photons(pos, power, inc, tree), 0.3)
        for f in ("density", "node_visits", "leaves_visited", "photons_tested", "photons_accepted",
                  "gather_misses"):
            assert np.array_equal(getattr(again, f), getattr(first, f)) and np.array_equal(
                getattr(again, f), getattr(fresh, f)), f
        learned = lp.pairs[0.3][0]
        gather(lp, 0.3, np.zeros((3, 3)), nrm[:3])  # three queries at the centre: overflows, learns nothing
        assert any(calls) and lp.pairs[0.3][0] == learned
        gather(lp, 0.6)
        assert any(calls)  # (a radius not seen yet: from the default)


@pytest.mark.parametrize("page_words", [1, 4, 6, 1024])
def test_stream_compaction_is_the_same_compiled(monkeypatch, page_words):
    """Accesses.of_csr, of_ranges and compact (tlm/kernels/_jit_memory.py against the numpy
    code): the same words and owners, element for element, on streams with empty owners and
    ranges, ranges over several pages, owners that repeat and come back, int32 and int64 words."""
    from tlm.kernels.memory import Accesses, compact

    rng = np.random.default_rng(page_words)
    for trial in range(40):
        n = int(rng.integers(0, 60))
        words = rng.integers(0, 8 * page_words + 3, n).astype(np.int32 if trial % 2 else np.int64)
        if trial % 3 == 0:
            words = np.sort(words)
        cuts = np.sort(rng.integers(0, n + 1, int(rng.integers(0, 12))))
        ptr = np.concatenate([[0], cuts, [n]])
        owner = np.sort(rng.integers(0, 5, n)) if trial % 4 else rng.integers(0, 3, n)
        first = rng.integers(0, 6 * page_words, n)
        last = first + rng.integers(-2, 3 * page_words + 2, n)
        got = {}
        for engine in ("numpy", "numba"):
            monkeypatch.setenv("TLM_KERNELS", engine)
            csr = Accesses.of_csr(words, ptr, page_words)
            ranges = Accesses.of_ranges(first, last, owner, page_words)
            plain = Accesses.of_ranges(first, last, None, page_words)
            got[engine] = [(a.dtype.str, a.tobytes()) for a in
                           (*compact(words, owner, page_words), csr.words, csr.owner, ranges.words, ranges.owner,
                            plain.words, plain.owner)]
        assert got["numpy"] == got["numba"], (trial, page_words)


@pytest.mark.parametrize("page_words", [1, 2, 6, 1024])
def test_page_misses_are_the_same_compiled(monkeypatch, page_words):
    """page_misses (tlm/kernels/_jit_memory.py against the numpy code): the same misses and
    state after, from every kind of state before (empty, on the stream's first page, armed or
    not, on the page before it), on streams that walk pages forward, skip and come back."""
    from tlm.kernels.memory import PairState, page_misses

    rng = np.random.default_rng(page_words)
    for trial in range(60):
        n = int(rng.integers(0, 50))
        steps = rng.integers(-2, 3 * page_words, n) if trial % 2 else rng.integers(0, page_words, n)
        words = np.abs(np.cumsum(steps) + int(rng.integers(0, 4 * page_words))).astype(np.int64)
        first = int(words[0]) // page_words if n else 0
        state = [None, PairState(), PairState(first, bool(trial % 3)), PairState(first - 1, True),
                 PairState(first + 1, False)][trial % 5]
        got = {}
        for engine in ("numpy", "numba"):
            monkeypatch.setenv("TLM_KERNELS", engine)
            miss, after = page_misses(words, state, page_words)
            got[engine] = (miss.dtype.str, miss.tobytes(), after)
        assert got["numpy"] == got["numba"], (trial, page_words)


def test_stream_compaction_refuses_what_numpy_would(monkeypatch):
    """The compiled compaction reads no bounds it is not given: owners of another length, a
    ``ptr`` that does not rise from 0 to the words, a page of no words are errors on both
    engines; a numpy integer page size works on both."""
    from tlm.kernels.memory import Accesses, PairState, compact, page_misses

    words = np.array([3, 4, 9, 1], dtype=np.int64)
    for engine in ("numpy", "numba"):
        monkeypatch.setenv("TLM_KERNELS", engine)
        with pytest.raises(ValueError):
            compact(words, np.array([0, 1]), 4)
        for ptr in ([0, 2, 5], [1, 4], [0, 3, 2, 4]):
            with pytest.raises(ValueError, match="ptr"):
                Accesses.of_csr(words, np.array(ptr), 4)
        with pytest.raises(ValueError, match="page_words"):
            Accesses.of_ranges(words, words + 2, None, 0)
        miss, after = page_misses(words, PairState(), np.int64(4))
        assert miss.tolist() == [True, False, True, True] and after == PairState(0, False)  # (4: armed next page)


def test_hash_uniform_is_the_same_compiled(monkeypatch):
    """The random numbers (tlm/kernels/_jit_hash.py against the numpy code): the same bits for
    negative and huge keys, seeds near 2**64, scalar keys broadcast, two-dimensional keys, and
    below the size where the numpy code runs anyway."""
    from tlm.kernels import shade

    rng = np.random.default_rng(4)
    a = rng.integers(-(2**62), 2**62, 5000)
    b = rng.integers(0, 1000, 5000)
    cases = [(12345, a, 3, 0), (2**64 - 5, a, b), (-7, a.reshape(50, 100), b.reshape(50, 100), -1),
             (0, np.zeros(300, np.int64) + 5, 2), (1, a[:10], 4)]
    for case in cases:
        got = {}
        for engine in ("numpy", "numba"):
            monkeypatch.setenv("TLM_KERNELS", engine)
            got[engine] = shade.hash_uniform(*case)
        assert got["numpy"].shape == got["numba"].shape and got["numpy"].tobytes() == got["numba"].tobytes()
        assert ((got["numba"] >= 0) & (got["numba"] < 1)).all()


def _cone_cases():
    """(origins, boxes, three uniforms) reaching every branch of the cones: origins on a
    box's corners, at its centres, inside it and far out, one shared origin (a point
    light), one box, flat boxes, boxes of one point (cones of no solid angle, cosines
    rounded past 1), no photon, picks at 0, just below 1 and at 1, cones so narrow that
    the picked one need not hold its own draw (it counts all the same), coordinates so
    small or so large that corners' lengths underflow or overflow, and NaN boxes."""
    rng = np.random.default_rng(11)
    lo = rng.uniform(-1, 1, (37, 3))
    boxes = np.stack([lo, lo + rng.uniform(0, 0.5, (37, 3))], axis=1)
    m = 3000
    o = rng.uniform(-2, 2, (m, 3))
    o[:10], o[10:20], o[20:30] = boxes[:10, 0], boxes[:10].mean(axis=1), boxes[:10, 1]
    o[30:40] = boxes[:10, 0] + 0.25 * (boxes[:10, 1] - boxes[:10, 0])  # inside
    u = [rng.uniform(size=m) for _ in range(3)]
    u[0][:5], u[0][5:10], u[0][10:15] = 0.0, np.nextafter(1.0, 0.0), 1.0
    flat = boxes.copy()
    flat[:, 1, 2] = flat[:, 0, 2]
    tiny = boxes.copy()  # cones so narrow that a draw's rounding can leave its own cone
    tiny[:, 1] = tiny[:, 0] + 1e-7
    point = boxes.copy()
    point[:, 1] = point[:, 0]
    nan = boxes.copy()  # (no scene gives one: numpy's NaN rule in the corners' minimum)
    nan[3, 1, 0] = nan[7, 0, 2] = np.nan
    return [(o, boxes, *u), (o[:1], boxes, *u), (np.array([[5.0, 5.0, 5.0]]), boxes[:1], *u), (o, flat, *u),
            (o[:0], boxes, *(x[:0] for x in u)), (o[100:], tiny, *(x[100:] for x in u)), (o, point, *u),
            (o * 1e-300, boxes * 1e-300, *u), (o * 1e300, boxes * 1e300, *u), (o, nan, *u)]


@pytest.mark.parametrize("case", range(10))
def test_cone_mixture_is_the_same_compiled(monkeypatch, case):
    """The caustic group's cone mixture (tlm/kernels/_jit_cones.py against the numpy
    code): the same directions and densities, as bytes, at one thread and at three."""
    from tlm.kernels import threads
    from tlm.kernels.emission import cone_mixture

    args = _cone_cases()[case]
    got = {}
    for engine, n in (("numpy", 1), ("numba", 1), ("numba", 3)):
        monkeypatch.setenv("TLM_KERNELS", engine)
        with threads.using(n), np.errstate(all="ignore"):  # (the huge coordinates overflow)
            got[engine, n] = [x.tobytes() for x in cone_mixture(*args)]
    assert got["numba", 1] == got["numpy", 1] and got["numba", 3] == got["numpy", 1]


def test_emission_aimed_at_parts_is_the_same_compiled(monkeypatch):
    """Photons of a quad light and of a point light aimed at the Cornell box's specular parts
    (``photons.aim: parts``) emitted with either engine: the same bytes."""
    from tlm.kernels.emission import aim_boxes, emit, photon_key
    from tlm.scenes.model import Light

    scene = load_scene("cornell")
    boxes = aim_boxes(scene.triangles, scene.material_table()["kind"], scene.part, 8)
    assert len(boxes) > 4
    point = Light(kind="point", position=(0.0, 1.5, 0.0), power=(10.0, 10.0, 10.0))
    lights = (*scene.lights, point)
    got = {}
    for engine in ("numpy", "numba"):
        monkeypatch.setenv("TLM_KERNELS", engine)
        got[engine] = [x.tobytes() for x in emit(lights, 4000, photon_key(3), None, None, 0.5, with_source=True,
                                                 caustic_boxes=boxes)]
    assert got["numba"] == got["numpy"]


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_cone_mixture_refuses_origins_that_are_not_one_or_one_a_photon(monkeypatch, engine):
    """Two origins for five photons (or boxes not (K, 2, 3)) is a ValueError with either
    engine, before anything is computed (the compiled code does not check its indices)."""
    from tlm.kernels.emission import cone_mixture

    monkeypatch.setenv("TLM_KERNELS", engine)
    u = np.full(5, 0.5)
    boxes = np.array([[[0.0, 0, 0], [1, 1, 1]]])
    with pytest.raises(ValueError, match="origins"):
        cone_mixture(np.zeros((2, 3)), boxes, u, u, u)
    with pytest.raises(ValueError, match="boxes"):
        cone_mixture(np.zeros((1, 3)), boxes[0], u, u, u)


def _photon_scenes():
    """Scenes for the compiled photon bounce, each with what some of its branches need:
    the Cornell box as it is (a mirror, glass, three Lambertian colours); the same with a
    black wall (Russian roulette's zero albedo), a mirror that reflects no green, glass
    of index 2.4 (total internal reflection) and shading normals reversed, zero (the
    geometric normal's fallback) or random on the specular triangles; with index-matched
    glass (photons cross it and stay direct light) and a black mirror (paths that end with
    no power); with the mirror and the glass made white Lambertian (diffuse bounces about
    normals of every direction: both tangent frames); and the refined water of cornell-water."""
    import dataclasses

    from tlm.scenes.normals import crease_normals

    box = load_scene("cornell")
    mats = {m.name: m for m in box.materials}
    hard_mats = {**mats, "red": dataclasses.replace(mats["red"], albedo=(0.0, 0.0, 0.0)),
                 "chrome": dataclasses.replace(mats["chrome"], reflectance=(0.9, 0.0, 0.5)),
                 "glass": dataclasses.replace(mats["glass"], ior=2.4)}
    normals = crease_normals(box.triangles, box.part)
    spec = np.flatnonzero(box.material_table()["kind"] != 0)
    rng = np.random.default_rng(5)
    normals[spec[0::5]] *= -1.0
    normals[spec[1::5]] = 0.0
    odd = rng.standard_normal((spec[2::5].shape[0], 3, 3))
    normals[spec[2::5]] = odd / np.linalg.norm(odd, axis=2, keepdims=True)
    hard = dataclasses.replace(box, materials=tuple(hard_mats[m.name] for m in box.materials), normals=normals)
    matched = dataclasses.replace(box, materials=tuple(
        dataclasses.replace(m, ior=1.0) if m.kind == "dielectric" else
        dataclasses.replace(m, reflectance=(0.0, 0.0, 0.0)) if m.kind == "mirror" else m for m in box.materials))
    matte = dataclasses.replace(box, materials=tuple(
        m if m.kind == "lambertian" else dataclasses.replace(mats["white"], name=m.name) for m in box.materials))
    return {"cornell": box, "hard": hard, "matched": matched, "matte": matte, "water": load_scene("cornell-water")}


@pytest.mark.parametrize(("name", "options"), [
    ("cornell", {"global_map": True, "aim": "parts"}),
    ("hard", {}),
    ("hard", {"russian_roulette": False, "fresnel": False, "global_map": True}),
    ("matched", {"caustic_fraction": 0.0, "max_bounces": 12}),
    ("matte", {"global_map": True}),
    ("water", {"caustic_fraction": 0.3}),
])
def test_photon_trace_is_the_same_compiled(monkeypatch, name, options):
    """The photon trace with the compiled bounce (tlm/kernels/_jit_photons.py) against the
    numpy code: the same maps (every stored photon's position, normal, incoming direction,
    power and caustic flag, the global map's too) and the same work per photon, as bytes,
    at one thread and at three; and at one thread, every bounce's rays as traced (origins,
    directions, the spawn offsets and the triangles they leave, which seldom change a hit)."""
    from tlm.kernels import photons, threads
    from tlm.kernels.photons import trace_photons

    scene = _photon_scenes()[name]
    accel = build_accel(scene.triangles)
    got, rays = {}, {}

    def recording(accel, o, d, tmin, ignore, **kw):
        rays[key].append(b"".join(np.ascontiguousarray(a).tobytes() for a in (o, d, tmin, ignore)))
        return closest_hit(accel, o, d, tmin=tmin, ignore=ignore, **kw)

    monkeypatch.setattr(photons, "closest_hit", recording)
    for key in (("numpy", 1), ("numba", 1), ("numba", 3)):
        engine, n = key
        rays[key] = []
        monkeypatch.setenv("TLM_KERNELS", engine)
        with threads.using(n), np.errstate(all="ignore"):
            trace = trace_photons(scene, accel, 6000, seed=11, batch_rays=12000, **options)
        maps = [m for m in (*trace.photons.maps, trace.photons.global_map) if m is not None]
        got[key] = ([getattr(m, k).tobytes() for m in maps for k in ("position", "normal", "incoming", "power",
                                                                       "caustic")],
                    {k: v.tobytes() for k, v in trace.work.items()})
        assert trace.photons.n > 0
    assert got["numba", 1] == got["numpy", 1]
    assert got["numba", 3] == got["numpy", 1]
    assert len(rays["numpy", 1]) > 2 and rays["numba", 1] == rays["numpy", 1]


def test_photon_bounce_optics_are_numpys():
    """The compiled bounce's Fresnel term, Snell direction and clip (tlm/kernels/_jit_photons.py)
    against the numpy code, one ray at a time, where the scenes seldom go: incidence at exactly
    0 and 90 degrees, total internal reflection at its bound (sin^2 t = 1), signed zeros (a dot
    product of three -0.0 products is +0.0, as np.sum's), a zero direction, infinities and NaNs
    (np.nan_to_num's and np.clip's rules)."""
    from tlm.kernels import _jit_photons
    from tlm.kernels.shade import _snell, fresnel_dielectric

    special = [0.0, -0.0, 1.0, 0.5, 1e-300, np.nextafter(1.0, 0.0), 2.0, -1.0, np.inf, -np.inf, np.nan]
    etas = [1.0, 1.5, 1 / 1.5, 0.5, 2.0, 0.0, 1e300, np.inf, np.nan]
    for eta in etas:
        bound = float(np.sqrt(1.0 - 1.0 / (eta * eta))) if 1 < eta < np.inf else 0.25  # sin^2 t = 1
        for cos_i in [*special, bound]:
            with np.errstate(all="ignore"):
                f, cos_t = fresnel_dielectric(np.array([cos_i]), np.array([eta]))
                got = _jit_photons._fresnel(cos_i, eta)
            assert np.array(got).tobytes() == np.concatenate([f, cos_t]).tobytes(), (cos_i, eta)
    rng = np.random.default_rng(2)
    n = np.array([0.0, 0.0, 1.0])
    dirs = [np.array(x) for x in ([0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.6, 0.0, -0.8],
                                  [0.0, -0.0, 1.0], [np.inf, 0.0, -1.0], [np.nan, 0.0, -1.0],
                                  [-1.0, -0.0, -0.0], [-0.0, -1.0, -0.0])]  # (d . n: three -0.0 products)
    dirs += list(rng.standard_normal((40, 3)) / np.linalg.norm(rng.standard_normal((40, 3)), axis=1, keepdims=True))
    for d in dirs:
        for eta in etas:
            with np.errstate(all="ignore"):
                t, f = _snell(d[None], n[None], np.array([eta]))
                got = _jit_photons._snell(*d, *n, eta)
            assert np.array(got).tobytes() == np.concatenate([t[0], f]).tobytes(), (d, eta)
    for x in special:
        assert np.array([_jit_photons._clip(x, 0.0, 1.0)]).tobytes() == np.clip(np.array([x]), 0.0, 1.0).tobytes(), x


def test_photon_bounce_scatter_is_numpys():
    """The compiled bounces' specular scatter and shading normal (tlm/kernels/_jit_photons.py)
    against shade.scatter_specular and normals.interpolate, one ray at a time: directions
    along and against the normals and grazing them, with signed zeros (three products of
    -0.0 sum to +0.0 in np.sum), shading normals reversed, zero and random, mirrors and
    glass of several indices."""
    from tlm.kernels import _jit_photons
    from tlm.kernels.shade import scatter_specular
    from tlm.scenes.normals import interpolate

    rng = np.random.default_rng(8)
    unit = rng.standard_normal((300, 3))
    unit /= np.linalg.norm(unit, axis=1, keepdims=True)
    axes = [np.array(x) for x in ([1.0, 0, 0], [-1.0, -0.0, -0.0], [0, 0, 1.0], [0.0, -0.0, -1.0], [-0.0, 1.0, 0.0])]
    dirs = axes + list(unit[:60])
    geo = axes + list(unit[60:80])
    for k, d in enumerate(dirs):
        for g in geo:
            for s in (g, -g, np.zeros(3), unit[80 + k % 200]):
                for index in (1.0, 1.5, 1 / 1.33, 2.4):
                    refl, refr, f = scatter_specular(d[None], s[None], g[None], np.array([index]))
                    got = _jit_photons._scatter_specular(*d, *s, *g, index)
                    want = np.concatenate([refl[0], refr[0], f, [np.sum(d * g) < 0.0]])
                    assert np.array(got, dtype=np.float64).tobytes() == want.tobytes(), (d, s, g, index)
    shading = rng.standard_normal((4, 3, 3))
    shading[1] = 0.0
    shading[2, :, 2] = -0.0
    shading[3] *= np.array([[1.0], [-1.0], [1.0]])
    for tri in range(4):
        for u, v in ((0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (0.5, 0.5), (0.2, 0.3), (-0.0, 1.0)):
            for g in geo:
                want = interpolate(shading, np.array([tri]), np.array([u]), np.array([v]), g[None])
                got = _jit_photons._shading_normal(shading, tri, u, v, *g)
                assert np.array(got).tobytes() == want[0].tobytes(), (tri, u, v, g)


@pytest.mark.parametrize(("scene", "over"), [
    ("tinted", []),  # the Cornell box's mirror (tinted: each channel its own) and glass sphere
    ("cornell-water", ["render.fresnel=false"]),  # rays into and out of water: the medium's index
])
def test_final_gathering_is_the_same_compiled(monkeypatch, tmp_path, scene, over):
    """The photon-map frame with final gathering, its rays' bounces compiled
    (tlm/kernels/_jit_fgather.py) against the numpy code: the same radiance and work of
    every pass, as bytes, at one thread and at three; and some rays went through a
    mirror or glass before their gather."""
    from pathlib import Path

    from tlm.config import load_config
    from tlm.experiments.run import render

    if scene == "tinted":
        text = (Path(__file__).parents[1] / "scenes" / "cornell.yaml").read_text()
        assert "reflectance: [0.9, 0.9, 0.9]" in text
        scene = tmp_path / "tinted.yaml"
        scene.write_text(text.replace("reflectance: [0.9, 0.9, 0.9]", "reflectance: [0.9, 0.2, 0.5]"))
    got = {}
    for engine, n in (("numpy", 1), ("numba", 1), ("numba", 3)):
        monkeypatch.setenv("TLM_KERNELS", engine)
        cfg, base = load_config(Path(__file__).parents[1] / "configs" / "cornell_pmap.yaml",
                                [f"scene={scene}", "resolution=[24,24]", "estimate.final_gather=4",
                                 "photons.count=20000", f"render.threads={n}", *over])
        res = render(cfg, base)
        got[engine, n] = ({k: v.tobytes() for k, v in res.radiance.items()},
                          {f"{p}.{k}": v.tobytes() for p, wk in res.work.items() for k, v in wk.items()})
        assert res.work["fgather"]["specular_bounces"].sum() > 0
    assert got["numba", 1] == got["numpy", 1]
    assert got["numba", 3] == got["numpy", 1]


def test_directions_about_axes_are_the_same_compiled(monkeypatch):
    """Directions about axes (tlm.kernels.emission._around: emission, diffuse bounces, final
    gathering) compiled against the numpy code, as bytes: random axes and cosines, axes at and
    about |x| = 0.9 (where the tangent frame changes), along +-x, y and z, cosines of -1, 0, 1 and
    just over 1 (no sine left), and a NaN."""
    from tlm.kernels.emission import _around

    rng = np.random.default_rng(4)
    axis = rng.standard_normal((500, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    edge = np.array([[0.9, np.sqrt(1 - 0.81), 0.0], [np.nextafter(0.9, 1), 0.0, np.sqrt(1 - 0.81)],
                     [-0.9, 0.0, np.sqrt(1 - 0.81)], [1.0, 0, 0], [-1.0, 0, 0], [0, 1.0, 0], [0, 0, -1.0],
                     [np.nan, 0, 1.0]])
    axis = np.concatenate([axis, edge])
    cos_t = rng.uniform(-1, 1, axis.shape[0])
    cos_t[:6] = [-1.0, 0.0, 1.0, np.nextafter(1.0, 2.0), -0.0, 1e-300]
    phi = rng.uniform(0, 2 * np.pi, axis.shape[0])
    got = {}
    for engine in ("numpy", "numba"):
        monkeypatch.setenv("TLM_KERNELS", engine)
        with np.errstate(all="ignore"):
            got[engine] = _around(axis, cos_t, phi).tobytes()
    assert got["numba"] == got["numpy"]


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_photon_trace_refuses_tables_not_of_the_scene(monkeypatch, engine):
    """Normals, shading normals or a material table of another length than the scene's
    triangles are a ValueError naming them, with either engine (the compiled bounce reads
    them by triangle id without a bounds check)."""
    from tlm.kernels.photons import trace_photons
    from tlm.kernels.shade import face_normals

    monkeypatch.setenv("TLM_KERNELS", engine)
    scene = load_scene("cornell")
    accel = build_accel(scene.triangles)
    short = face_normals(scene.triangles)[:-1]
    with pytest.raises(ValueError, match="normals has 2603 rows; the scene has 2604 triangles"):
        trace_photons(scene, accel, 100, normals=short)
    table = {k: v[:10] for k, v in scene.material_table().items()}
    with pytest.raises(ValueError, match=r"table\['kind'\] has 10 rows"):
        trace_photons(scene, accel, 100, table=table)


@pytest.mark.parametrize(("last", "fresnel"), [(False, True), (False, False), (True, True)])
def test_final_gather_bounce_is_the_same_compiled(monkeypatch, last, fresnel):
    """One bounce of final-gather rays (tlm.kernels.shade.final_gather_bounce) with either
    engine, every output as bytes: the gathers (point, facing normal, weight through a change
    of medium, triangle), the rays that go on (their medium, weight through a tinted mirror
    or glass, origin, direction and the triangle they leave) and the per-pixel counts; rays
    from random points in the Cornell box, some of them seeing a light first."""
    from tlm.kernels.shade import face_normals, final_gather_bounce
    from tlm.scenes.normals import crease_normals

    scene = load_scene("cornell")
    accel = build_accel(scene.triangles)
    mats = scene.material_table()
    table = {"kind": mats["kind"], "normals": face_normals(scene.triangles), "ior": mats["ior"],
             "shading": crease_normals(scene.triangles, scene.part),
             "reflectance": mats["reflectance"] * np.array([1.0, 0.3, 0.6]), "transmittance": mats["transmittance"]}
    rng = np.random.default_rng(6)
    n, points, pixels = 6000, 900, 300
    lo, hi = scene.bounds()
    origin = lo + rng.random((n, 3)) * (hi - lo)
    d = rng.standard_normal((n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    hits = closest_hit(accel, origin, d)
    j, r = rng.integers(0, points, n), rng.integers(0, 16, n)
    owner, pkeys = rng.integers(0, pixels, points), rng.integers(0, 1 << 40, points)
    medium = rng.choice([1.0, 1.33, 1.5], points)
    med, w, seen = rng.choice([1.0, 1.33, 1.5], n), rng.random((n, 3)), rng.random(n) < 0.2
    got = {}
    for engine in ("numpy", "numba"):
        monkeypatch.setenv("TLM_KERNELS", engine)
        counts = (np.zeros(pixels, dtype=np.int64), np.zeros(pixels, dtype=np.int64))
        found, going = final_gather_bounce(12345, 1, last, j, r, owner, pkeys, medium, med, w, origin, d, hits,
                                           seen, table, fresnel, *counts)
        got[engine] = [np.ascontiguousarray(a).tobytes() for a in (*found, *going, *counts)]
        assert found[0].shape[0] > 100 and (going[0].shape[0] == 0) == last
    assert got["numba"] == got["numpy"]


def test_gather_order_is_a_morton_curve():
    """The compiled gather takes its queries along a Morton curve over their box: a
    permutation of the queries whose interleaved cell codes never decrease (ties in
    index order), whatever NaN or flat extents the points have."""
    from tlm.kernels._jit_gather import MORTON_BITS, morton_order

    rng = np.random.default_rng(3)
    pts = rng.uniform(-5.0, 5.0, (3, 3000))
    pts[2, :] = 1.0  # a flat axis: every z in cell 0
    pts[0, 207] = np.nan  # (the 8th query)
    order = morton_order(pts, 200, 2200)
    assert np.array_equal(np.sort(order), np.arange(2000))
    p = pts[:, 200:2200]
    lo = np.nanmin(p, axis=1, keepdims=True)
    ext = np.nanmax(p, axis=1, keepdims=True) - lo
    cells = (1 << MORTON_BITS) - 1
    with np.errstate(invalid="ignore", divide="ignore"):
        g = np.nan_to_num((p - lo) * np.where(ext > 0, cells / ext, 0.0)).astype(np.int64)
    code = sum(((g[axis] >> b) & 1) << (3 * b + axis) for axis in range(3) for b in range(MORTON_BITS))
    assert np.array_equal(order, np.argsort(code, kind="stable"))
    assert np.all(np.diff(code[order]) >= 0)
    assert morton_order(pts, 5, 5).shape == (0,) and np.array_equal(morton_order(pts, 5, 6), [0])
    # ties (many points share a cell) in index order; an infinite coordinate: its axis all in cell 0
    grid = np.ascontiguousarray(rng.integers(0, 4, (3, 500)).astype(np.float64))
    codes = sum(((grid[axis].astype(np.int64) * 341 >> b) & 1) << (3 * b + axis)
                for axis in range(3) for b in range(MORTON_BITS))
    assert np.array_equal(morton_order(grid, 0, 500), np.argsort(codes, kind="stable"))
    grid[1, 9] = np.inf
    codes = sum(((grid[axis].astype(np.int64) * 341 >> b) & 1) << (3 * b + axis)
                for axis in (0, 2) for b in range(MORTON_BITS))
    assert np.array_equal(morton_order(grid, 0, 500), np.argsort(codes, kind="stable"))
