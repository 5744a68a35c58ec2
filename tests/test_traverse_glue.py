"""The compiled glue around the traversal (``tlm.kernels._jit_glue``) and the per-accel
constants the compiled traversal keeps: each gives exactly what the numpy code it
replaces gives, and a cache never answers for another accel or page size."""

from __future__ import annotations

import numpy as np
import pytest

from tlm.kernels import memory, traverse
from tlm.kernels.memory import PAGE_WORDS, Accesses
from tlm.kernels.recording import traversal_accesses
from tlm.kernels.traverse import Touched, any_hit, build_accel, closest_hit
from tlm.scenes.loader import load_scene

pytestmark = pytest.mark.skipif(not traverse._numba_available(), reason="numba is not installed")


def glue():
    """The compiled glue module (imported here: it imports numba)."""
    from tlm.kernels import _jit_glue

    return _jit_glue


def reference_accesses(touched, lf_all, ll_all, page_words):
    """traversal_accesses as the numpy engine computed it before the compiled glue."""
    r = touched.leaf_ptr.shape[0] - 1
    nodes = Accesses.of_csr(touched.node_ids, touched.node_ptr, page_words)
    leaves = touched.leaf_ids
    lf = lf_all[leaves].astype(np.int64)
    ll = ll_all[leaves].astype(np.int64)
    owner = np.repeat(np.arange(r, dtype=np.int64), np.diff(touched.leaf_ptr))
    full = ll > lf
    lf, ll, owner = lf[full], ll[full], owner[full]
    return {
        "nodes": nodes,
        "indices": Accesses.of_ranges(lf // 4, (ll - 1) // 4 + 1, owner, page_words),
        "vertices": Accesses.of_ranges(lf * 3, ll * 3, owner, page_words),
    }


def random_touched(rng, r, n_leaves, id_type):
    """Per ray 0 to 5 nodes and 0 to 5 leaves (some rays none), nodes of a heap of 4000."""
    nv = rng.integers(0, 6, r)
    lv = rng.integers(0, 6, r)
    nv[rng.random(r) < 0.2] = 0
    lv[rng.random(r) < 0.2] = 0
    node_ptr = np.concatenate([[0], np.cumsum(nv)]).astype(np.int64)
    leaf_ptr = np.concatenate([[0], np.cumsum(lv)]).astype(np.int64)
    # near ids, so that runs on one page continue across a ray's nodes
    node_ids = (rng.integers(0, 4000, int(node_ptr[-1])) // rng.integers(1, 50)).astype(id_type)
    leaf_ids = rng.integers(0, n_leaves, int(leaf_ptr[-1])).astype(np.int64)
    return Touched(node_ptr, node_ids, leaf_ptr, leaf_ids)


def leaf_ranges(rng, n_leaves):
    """Leaf slot ranges with empty leaves (first == last) at every residue mod 4, and big ones."""
    size = rng.integers(0, 9, n_leaves)
    size[rng.random(n_leaves) < 0.3] = 0
    size[rng.random(n_leaves) < 0.05] = 3000  # (spans several pages of vertices)
    first = np.concatenate([[0], np.cumsum(size)[:-1]]).astype(np.int64)
    return first, first + size


def same(a: Accesses, b: Accesses):
    assert a.page_words == b.page_words
    assert a.words.dtype == b.words.dtype == np.int64 and a.owner.dtype == b.owner.dtype == np.int64
    assert np.array_equal(a.words, b.words) and np.array_equal(a.owner, b.owner)


@pytest.mark.parametrize("page_words", [PAGE_WORDS, 16, 6, 1, 3])
@pytest.mark.parametrize("id_type", [np.int32, np.int64])
def test_traversal_accesses_compiled_equal_numpy(monkeypatch, page_words, id_type):
    """The compiled streams equal the numpy engine's and the code they replace, on random
    lists with empty leaves, rays without nodes or leaves, and pages of 1 word up."""
    rng = np.random.default_rng(page_words)
    lf, ll = leaf_ranges(rng, 300)
    for r in (0, 1, 7, 400):
        t = random_touched(rng, r, 300, id_type)
        monkeypatch.setenv("TLM_KERNELS", "numpy")
        want = traversal_accesses(t, lf, ll, page_words)
        ref = reference_accesses(t, lf, ll, page_words)
        monkeypatch.setenv("TLM_KERNELS", "numba")
        got = traversal_accesses(t, lf, ll, page_words)
        assert list(got) == ["nodes", "indices", "vertices"]
        for name in got:
            same(got[name], want[name])
            same(got[name], ref[name])
        if r == 400:  # (the lists are not trivially empty)
            assert all(got[name].words.shape[0] > 10 for name in got)
        # the kernel itself (what the numba engine runs above)
        ok, *runs = glue().traversal_runs(t.node_ids, t.node_ptr, t.leaf_ids, t.leaf_ptr, lf, ll, 4, 3,
                                             np.int64(page_words), memory._shift(page_words))
        assert ok
        for k, name in enumerate(("nodes", "indices", "vertices")):
            same(Accesses(runs[2 * k], runs[2 * k + 1], page_words), ref[name])


def test_traversal_accesses_of_a_real_traversal(monkeypatch):
    """On a traversal's own record (int32 node ids, the accel's leaf ranges) too."""
    scene = load_scene("cornell")
    accel = build_accel(scene.triangles)
    rng = np.random.default_rng(1)
    o = np.tile(scene.triangles.reshape(-1, 3).mean(axis=0), (500, 1))
    d = rng.normal(size=(500, 3))
    monkeypatch.setenv("TLM_KERNELS", "numba")
    hits = closest_hit(accel, o, d, record=True)
    assert hits.touched.node_ids.dtype == np.int32
    got = traversal_accesses(hits.touched, accel.leaf_first, accel.leaf_last)
    monkeypatch.setenv("TLM_KERNELS", "numpy")
    want = traversal_accesses(hits.touched, accel.leaf_first, accel.leaf_last)
    for name in got:
        same(got[name], want[name])


def test_traversal_accesses_bad_pointers_still_refused(monkeypatch):
    """A pointer array that does not rise from 0 to its list's length is refused as before."""
    monkeypatch.setenv("TLM_KERNELS", "numba")
    lf, ll = np.array([0, 4]), np.array([4, 9])
    bad = Touched(np.array([0, 2, 1]), np.array([1, 2], dtype=np.int32), np.array([0, 1, 1]), np.array([0]))
    with pytest.raises(ValueError, match=r"ptr must rise from 0"):
        traversal_accesses(bad, lf, ll)
    with pytest.raises(ValueError, match=r"page_words"):
        traversal_accesses(Touched(np.array([0, 1]), np.array([1]), np.array([0, 1]), np.array([1])), lf, ll, 0)


def test_touched_ptrs_equal_cumsum():
    rng = np.random.default_rng(2)
    for r in (0, 1, 5, 1000):
        a, b = rng.integers(0, 40, r), rng.integers(0, 9, r)
        node_ptr, leaf_ptr = glue().touched_ptrs(a, b)
        for got, v in ((node_ptr, a), (leaf_ptr, b)):
            want = np.zeros(r + 1, dtype=np.int64)
            np.cumsum(v, out=want[1:])
            assert got.dtype == np.int64 and np.array_equal(got, want)


def test_page_size_shift_not_stale():
    """The page's shift kept per page size: another size gets its own."""
    assert memory._shift(1024) == 10
    assert memory._shift(6) == -1
    assert memory._shift(16) == 4
    assert memory._shift(1024) == 10


def test_constants_kept_per_accel_and_learned_sizes(monkeypatch):
    """Two accels (other scenes) traced in turn: each call answers with its own accel's
    constants, as the numpy engine does; the buffer sizes learned from a recorded call
    are those of its leaf and node counts."""
    monkeypatch.setattr(traverse, "LEARN_MIN_RAYS", 1)
    rng = np.random.default_rng(3)
    accels = [build_accel(load_scene(name).triangles) for name in ("cornell", "ring")]
    for _ in range(2):
        for accel in accels:
            centre = accel.origin
            o = centre + rng.normal(size=(300, 3)) * 0.1 * accel.scale
            d = rng.normal(size=(300, 3))
            monkeypatch.setenv("TLM_KERNELS", "numba")
            got = closest_hit(accel, o, d, record=True)
            occ = any_hit(accel, o, d, tmax=0.5)
            assert accel.__dict__["_jit_constants"][2][0][6] is accel.jit_layout.soa32
            learned = accel.__dict__["_jit_per_ray"]
            c = got.counts
            need = (-(-5 * int(c.leaf_visits.sum()) // (4 * 300)), -(-5 * int(c.node_visits.sum()) // (4 * 300)))
            assert learned[0] >= need[0] and learned[1] >= need[1]
            monkeypatch.setenv("TLM_KERNELS", "numpy")
            want = closest_hit(accel, o, d, record=True)
            want_occ = any_hit(accel, o, d, tmax=0.5)
            assert got.triangle.tobytes() == want.triangle.tobytes() and got.t.tobytes() == want.t.tobytes()
            assert np.array_equal(occ.occluded, want_occ.occluded)
            for k, a in vars(got.touched).items():
                b = getattr(want.touched, k)
                assert a.dtype == b.dtype and np.array_equal(a, b), k
    # the learned sizes equal the counts' exactly on a fresh accel (one call)
    accel = build_accel(load_scene("cornell").triangles)
    o = accel.origin + rng.normal(size=(300, 3)) * 0.1 * accel.scale
    monkeypatch.setenv("TLM_KERNELS", "numba")
    c = closest_hit(accel, o, rng.normal(size=(300, 3)), record=True).counts
    need = (-(-5 * int(c.leaf_visits.sum()) // (4 * 300)), -(-5 * int(c.node_visits.sum()) // (4 * 300)))
    assert accel.__dict__["_jit_per_ray"] == need


def test_rows3():
    a = np.arange(12.0).reshape(4, 3)
    assert traverse._rows3(a) is a
    b = traverse._rows3(np.arange(12, dtype=np.int32).reshape(2, 6))
    assert b.dtype == np.float64 and b.shape == (4, 3) and np.array_equal(b, a)
    c = traverse._rows3(np.asfortranarray(a))
    assert c.flags.c_contiguous and np.array_equal(c, a)
    assert traverse._rows3([1, 2, 3]).shape == (1, 3)


def reference_owner_major(acc: Accesses) -> Accesses:
    own = acc.owner
    if own.shape[0] < 2 or bool(np.all(own[1:] >= own[:-1])):
        return acc
    order = np.argsort(own, kind="stable")
    return Accesses(*memory.compact(acc.words[order], own[order], acc.page_words), acc.page_words)


@pytest.mark.parametrize("page_words", [PAGE_WORDS, 16, 6, 1])
def test_owner_major_compiled_equal_numpy(monkeypatch, page_words):
    """The compiled owner-major order (a counting sort, then the runs) equals numpy's stable
    sort and compaction: owners out of order, already in order, negative or spread far (the
    numpy sort then), one or no access, words running over page edges."""
    rng = np.random.default_rng(page_words)
    cases = []
    for n in (0, 1, 2, 3, 50, 3000):
        words = np.cumsum(rng.integers(0, 2 * page_words + 1, n)).astype(np.int64)
        for own in (rng.integers(0, max(1, n // 3), n), np.sort(rng.integers(0, 9, n)), rng.integers(-3, 3, n),
                    rng.integers(0, 10**9, n), np.arange(n)[::-1].copy()):
            cases.append(Accesses(words, own.astype(np.int64), page_words))
    moved = 0
    for acc in cases:
        monkeypatch.setenv("TLM_KERNELS", "numpy")
        want = acc.owner_major()
        assert want.words.shape == reference_owner_major(acc).words.shape
        monkeypatch.setenv("TLM_KERNELS", "numba")
        got = acc.owner_major()
        same(got, want)
        same(got, reference_owner_major(acc))
        moved += got is not acc
        # the kernel itself: 0 (in order), 1 (sorted here), 2 (left to numpy's sort)
        status, words, owner = glue().owner_major(acc.words, acc.owner, np.int64(page_words),
                                                     memory._shift(page_words))
        own = acc.owner
        if own.shape[0] < 2 or bool(np.all(own[1:] >= own[:-1])):
            assert status == 0
        elif own.min() < 0 or own.max() > 4 * own.shape[0] + 1024:
            assert status == 2
        else:
            assert status == 1
            same(Accesses(words, owner, page_words), want)
    assert moved > 10


def test_owner_major_compiled_returns_itself_when_in_order(monkeypatch):
    monkeypatch.setenv("TLM_KERNELS", "numba")
    acc = Accesses(np.array([5, 3000, 7], dtype=np.int64), np.array([0, 0, 2], dtype=np.int64))
    assert acc.owner_major() is acc
    out = Accesses(np.array([5, 3000, 7, 9], dtype=np.int64), np.array([2, 0, 0, 2], dtype=np.int64)).owner_major()
    assert out.words.tolist() == [3000, 7, 9] and out.owner.tolist() == [0, 0, 2]
