"""The photon-map glue compiled without the interpreter lock (tlm/kernels/_jit_pmap.py) gives
exactly what the numpy code it replaced gave: a gather's per-query counts and leaf word ranges,
the per-pixel sums, and the final-gather rays' point and ray indices."""

from __future__ import annotations

import numpy as np
import pytest

from tests.helpers_gather import random_gather
from tlm.kernels import _jit_pmap, estimate, threads
from tlm.kernels.estimate import Estimate
from tlm.kernels.memory import PHOTON_WORDS, Streams
from tlm.render import pmap


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



@pytest.mark.parametrize("bad", [-1, 5])
def test_add_per_owner_refuses_an_owner_outside_the_counts(bad):
    """As numpy's bincount-and-add does: no count lands on another pixel or past the end."""
    into = np.zeros(5, dtype=np.int64)
    with pytest.raises(IndexError, match="owner outside"):
        _jit_pmap.add_per_owner(into, np.array([0, bad, 1], dtype=np.int64), np.array([1, 2, 3], dtype=np.int64))
    assert not into.any()


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
    pos, power, inc, tree, pts, nrm = random_gather(7, 2500, 1500, 7)
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
