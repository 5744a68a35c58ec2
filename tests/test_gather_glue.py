"""The photon-map glue compiled without the interpreter lock (tlm/kernels/_jit_pmap.py) gives
exactly what the numpy code it replaced gave: the density rule's k-th neighbour distances
(ties, duplicates, planes, lattices), a gather's per-query counts and leaf word ranges, the
per-pixel sums, and the final-gather rays' point and ray indices."""

from __future__ import annotations

import numpy as np
import pytest

from tlm.kernels import _jit_pmap, estimate, threads
from tlm.kernels.bsp import build_point_tree
from tlm.kernels.estimate import Estimate, density_radius
from tlm.kernels.memory import PHOTON_WORDS, Streams
from tlm.render import pmap


def _kth_reference(pos: np.ndarray, at: np.ndarray, kk: int) -> np.ndarray:
    """The numpy engine's k-th distances: scipy's cKDTree, the distances recomputed in numpy."""
    from scipy.spatial import cKDTree

    s = at.shape[0]
    _, idx = cKDTree(pos, balanced_tree=False, compact_nodes=False).query(pos[at], k=kk + 1, workers=1)
    idx = np.asarray(idx, dtype=np.int64).reshape(s, kk + 1)
    d2 = ((pos[idx] - pos[at][:, None, :]) ** 2).sum(axis=2)
    d2 = np.where(idx == at[:, None], np.inf, d2)
    d2.sort(axis=1)
    return d2[:, kk - 1]


def _cloud(rng, kind: int, n: int) -> np.ndarray:
    if kind == 0:  # spread
        return rng.standard_normal((n, 3)) * rng.uniform(0.1, 10.0, 3)
    if kind == 1:  # a small integer lattice: many ties at every distance
        return rng.integers(0, 3, (n, 3)).astype(np.float64)
    if kind == 2:  # points stacked five on one spot
        return np.repeat(rng.standard_normal((n // 5 + 1, 3)), 5, axis=0)[:n]
    return np.column_stack([rng.standard_normal(n), np.zeros(n), rng.integers(0, 4, n) * 0.1])  # a plane, rows


@pytest.mark.parametrize("kind", [0, 1, 2, 3])
def test_kth_neighbour_is_the_kdtree_reference(kind):
    rng = np.random.default_rng(11 + kind)
    for _ in range(40):
        n = int(rng.integers(2, 300))
        kk = int(rng.integers(1, n))
        s = min(int(rng.integers(1, 300)), n)
        at = np.arange(s, dtype=np.int64) * n // s
        pos = _cloud(rng, kind, n)
        for leaf in (1, 3, _jit_pmap.KNN_LEAF):
            got = _jit_pmap.kth_neighbour_d2(np.ascontiguousarray(pos), at, kk, leaf)
            assert np.array_equal(got, _kth_reference(pos, at, kk)), (n, kk, s, leaf)
    # the edges: the farthest other point (kk = n - 1), two points, all on one spot
    pos = _cloud(rng, 0, 50)
    at = np.arange(50, dtype=np.int64)
    assert np.array_equal(_jit_pmap.kth_neighbour_d2(pos, at, 49, 4), _kth_reference(pos, at, 49))
    two = np.array([[0.0, 0.0, 0.0], [3.0, 4.0, 0.0]])
    assert _jit_pmap.kth_neighbour_d2(two, np.array([0, 1]), 1, 8).tolist() == [25.0, 25.0]
    assert _jit_pmap.kth_neighbour_d2(np.zeros((9, 3)), np.array([0, 4]), 8, 2).tolist() == [0.0, 0.0]


def test_kth_neighbour_is_not_the_one_before_or_after():
    """The k-th, not the (k-1)-th or (k+1)-th: distinct distances 1, 4, 9, ... from the origin."""
    pos = np.column_stack([np.arange(6.0), np.zeros(6), np.zeros(6)])
    assert _jit_pmap.kth_neighbour_d2(pos, np.array([0]), 3, 1).tolist() == [9.0]
    assert _jit_pmap.kth_neighbour_d2(pos, np.array([0, 5]), 1, 2).tolist() == [1.0, 1.0]


@pytest.mark.parametrize("k", [1, 8, 100])
def test_density_radius_is_the_same_on_both_engines(monkeypatch, k):
    rng = np.random.default_rng(k)
    pos = np.r_[rng.uniform(0.0, 5.0, (3000, 3)), np.repeat(rng.uniform(0, 5, (40, 3)), 4, axis=0)]
    pos[::7, 2] = 0.0  # a share of them on a plane
    got = {}
    for name in ("numpy", "numba"):
        monkeypatch.setenv("TLM_KERNELS", name)
        got[name] = (density_radius(pos, k), density_radius(pos[:2], k), density_radius(np.zeros((4, 3)), k))
    assert got["numpy"] == got["numba"]
    assert got["numba"][0] > 0.0 and got["numba"][1] == pytest.approx(np.linalg.norm(pos[1] - pos[0]))


def test_pair_words_are_the_bincounts():
    rng = np.random.default_rng(2)
    first = rng.integers(0, 10_000, 64)
    size = rng.integers(0, 9, 64)  # empty leaves too
    size[:5] = 0
    for p, m in ((0, 0), (0, 5), (1, 1), (500, 40)):
        pq = np.sort(rng.integers(0, max(m, 1), p))
        leaf = rng.integers(0, 64, p)
        leaves, tested, lo, hi = _jit_pmap.pair_words(pq, leaf, first, size, m, PHOTON_WORDS)
        assert np.array_equal(leaves, np.bincount(pq, minlength=m))
        assert np.array_equal(tested, np.bincount(pq, weights=size[leaf], minlength=m).astype(np.int64))
        assert np.array_equal(lo, first[leaf] * PHOTON_WORDS)
        assert np.array_equal(hi, first[leaf] * PHOTON_WORDS + size[leaf] * PHOTON_WORDS)
        assert leaves.dtype == tested.dtype == lo.dtype == hi.dtype == np.int64


def test_add_per_owner_is_the_bincount():
    rng = np.random.default_rng(4)
    for n, p in ((0, 3), (1, 1), (1000, 17)):
        owner = rng.integers(0, p, n)
        values = rng.integers(0, 1 << 40, n)
        start = rng.integers(0, 100, p)
        into = start.copy()
        _jit_pmap.add_per_owner(into, owner, values)
        assert np.array_equal(into, start + np.bincount(owner, weights=values, minlength=p).astype(np.int64))


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_add_per_pixel_adds_the_counts(monkeypatch, engine):
    monkeypatch.setenv("TLM_KERNELS", engine)
    owner = np.array([2, 0, 2, 2, 1])
    z = np.zeros(5, dtype=np.int64)
    e = Estimate(np.zeros((5, 3)), z, z, np.array([3, 1, 4, 1, 5]), z, z, z)
    work = {"photons_tested": np.array([10, 20, 30, 40], dtype=np.int64)}
    pmap._add_per_pixel(work, "photons_tested", owner, e, Streams())
    assert work["photons_tested"].tolist() == [11, 25, 38, 40]


@pytest.mark.parametrize("m, rays", [(0, 4), (1, 1), (3, 4), (5, 6)])
def test_final_gather_ray_indices_are_point_major(m, rays):
    rng = np.random.default_rng(m + rays)
    n = rng.normal(size=(m, 3))
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    j, r, d = pmap.final_gather_directions(n, rng.integers(0, 1000, m), rays, seed=1)
    assert np.array_equal(j, np.repeat(np.arange(m), rays)) and np.array_equal(r, np.tile(np.arange(rays), m))
    assert j.dtype == r.dtype == np.int64 and d.shape == (m * rays, 3)


@pytest.mark.parametrize("n_threads", [1, 3])
def test_chunked_gathers_are_the_numpy_gathers(monkeypatch, n_threads):
    """Blocks cut into chunks on several threads (the chunks' pairs joined, their counts and word
    ranges made by each chunk): the numpy path's densities, work and misses, bit for bit."""
    rng = np.random.default_rng(7)
    pos = rng.uniform(-1.0, 1.0, (2500, 3))
    power = rng.uniform(0.0, 1.0, (2500, 3))
    inc = rng.normal(size=(2500, 3))
    inc /= np.linalg.norm(inc, axis=1, keepdims=True)
    pts = rng.uniform(-1.0, 1.0, (1500, 3))
    nrm = rng.normal(size=(1500, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    tree = build_point_tree(pos, 7)
    monkeypatch.setattr(estimate, "QUERY_BLOCK", 700)  # three blocks, the first two in chunks on 3 threads
    monkeypatch.setattr(estimate, "GATHER_MIN_CHUNK", 200)
    out = {}
    for name in ("numpy", "numba"):
        monkeypatch.setenv("TLM_KERNELS", name)
        with threads.using(n_threads):
            out[name] = estimate.mvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.2, streams=Streams(64, 4))
    for f in Estimate.__dataclass_fields__:
        assert np.array_equal(getattr(out["numpy"], f), getattr(out["numba"], f)), f
    assert out["numba"].gather_misses.sum() > 0 and out["numba"].photons_accepted.sum() > 0


@pytest.mark.parametrize("n", [0, 1, 7, 200])
def test_walk_branches_in_sample_order(n):
    """The specular walk's branches (tlm.render.walk._branches): each sample's reflection
    before its refraction, as the stable sort of the two lists gave them."""
    from tlm.render.walk import _interleave

    rng = np.random.default_rng(n)
    for p in (0.0, 0.5, 1.0):
        take_l, take_r = rng.random(n) < p, rng.random(n) < 1.0 - p / 2
        take = np.column_stack([take_l, take_r])
        at = np.flatnonzero(take.ravel())
        order = np.argsort(np.r_[np.flatnonzero(take_l) * 2, np.flatnonzero(take_r) * 2 + 1], kind="stable")
        assert np.array_equal(at >> 1, np.r_[np.flatnonzero(take_l), np.flatnonzero(take_r)][order])
        for shape in ((n,), (n, 3)):
            a, b = rng.normal(size=shape), rng.normal(size=shape)
            got = _interleave(a, b)[at]
            assert got.shape == (at.shape[0], *shape[1:]) and got.dtype == np.float64
            assert np.array_equal(got, np.r_[a[take_l], b[take_r]][order])


def test_final_gather_key_is_made_once_a_seed():
    """The final-gather key, kept per seed: each seed's own, SeedSequence's value."""
    pmap._fg_key.cache_clear()
    for seed in (0, 1, 0, 12345, 1):
        want = int(np.random.SeedSequence([seed, 0xF16A7]).generate_state(1, dtype=np.uint64)[0] >> 1)
        assert pmap._fg_key(seed) == want
    assert pmap._fg_key.cache_info().hits == 2 and pmap._fg_key(0) != pmap._fg_key(1)
