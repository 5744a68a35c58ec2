"""The any-hit filter (:func:`tlm.kernels._jit_leaf._scan`) never skips a leaf that the full
float32 test (:func:`tlm.kernels._jit_leaf._leaf32`) accepts, on adversarial rays: aimed at
vertices and edges (barycentrics at the edge tolerance, a few ulps either side), grazing
and near-parallel to the triangle's plane, with ``tmin`` and ``tmax`` a few ulps around the
hit. The filter may pass extra leaves (the full test decides), never fewer.

The rays are checked to be adversarial: a filter without the edge tolerance (``eps = 0``)
or with ``tmax`` one ulp shorter skips some accepted leaf of this set, so a filter whose
margin loses to float32 rounding in either way fails here.
"""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from tlm.kernels import _jit_leaf as L
from tlm.kernels.intersect import EDGE_EPS

EPS = np.float32(EDGE_EPS[np.dtype(np.float32)])
F = np.float32


def _stack(tris: np.ndarray, leaves: list[list[int]]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The (16, m') float32 stack of ``tris`` (n, 3, 3) float64 as ``tlm.kernels._jit.layout``
    builds it (v0, -E1, E2, N, -N, id bits; each leaf padded to PAD with NaN slots of id -2),
    and each leaf's first and past-last padded slot."""
    e1 = tris[:, 1] - tris[:, 0]
    e2 = tris[:, 2] - tris[:, 0]
    n = np.cross(e1, e2)
    rows = np.concatenate([tris[:, 0].T, -e1.T, e2.T, n.T, -n.T])
    cols, first, last = [], [], []
    for leaf in leaves:
        first.append(len(cols))
        cols += leaf + [-1] * (-len(leaf) % L.PAD)
        last.append(len(cols))
    soa = np.full((16, len(cols)), np.nan, dtype=np.float32)
    ids = np.full(len(cols), -2, dtype=np.int32)
    for c, t in enumerate(cols):
        if t >= 0:
            soa[:15, c] = rows[:, t]
            ids[c] = t
    soa[15] = ids.view(np.float32)
    return soa, np.array(first, dtype=np.int64), np.array(last, dtype=np.int64)


def _rays(tris: np.ndarray, rng: np.random.Generator, per: int):
    """Per triangle ``per`` rays ``(tri, o, d, tmin, tmax)`` (float64) at its vertices and
    edges, just inside and just outside them, grazing or not, with the segment's ends a
    few ulps around the hit."""
    out = []
    for k, (a, b, c) in enumerate(tris):
        e1, e2 = b - a, c - a
        nrm = np.cross(e1, e2)
        nrm /= np.linalg.norm(nrm)
        for _ in range(per):
            kind = rng.integers(4)
            if kind == 0:  # a vertex
                u, v = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)][rng.integers(3)]
            else:  # an edge, at the tolerance: a few float32 ulps of eps either side
                s = rng.random() if rng.random() < 0.8 else float(rng.integers(2))
                off = -float(EPS) * (1.0 + rng.integers(-4, 5) * 2.0**-23) if rng.random() < 0.7 else 0.0
                if kind == 1:
                    u, v = s, off
                elif kind == 2:
                    u, v = off, s
                else:
                    u, v = s - off / 2, 1.0 - s - off / 2  # (u + v = 1 - off)
            p = a + u * e1 + v * e2
            tang = rng.normal(size=3)
            tang -= tang.dot(nrm) * nrm
            tang /= np.linalg.norm(tang)
            cosine = [1.0, 0.3, 1e-2, 1e-4, 1e-6][rng.integers(5)] * rng.choice([-1.0, 1.0])
            d = cosine * nrm + np.sqrt(1.0 - cosine * cosine) * tang
            d *= 10.0 ** rng.uniform(-1, 1)
            t_hit = 10.0 ** rng.uniform(-1, 1)
            o = p - t_hit * d
            ulp = float(np.spacing(F(t_hit)))
            if rng.random() < 0.5:  # tmax a few ulps around the hit
                tmin, tmax = 1e-3 * t_hit, t_hit + rng.integers(-3, 4) * ulp
            else:  # tmin a few ulps around it
                tmin, tmax = t_hit + rng.integers(-3, 4) * ulp, 4.0 * t_hit
            out.append((k, o, d, tmin, tmax))
    return out


def _leaf32(ray, soa, s0, s1, eps, ign=-1):
    o32, d32, t0, t1 = ray
    args = [*o32, *d32, t0, t1, ign, soa, s0, s1, eps]
    if "keys" in inspect.signature(L._leaf32.py_func).parameters:  # (the scratch of the keys, where it takes one)
        args.append(np.empty(max(L.PAD, s1 - s0), dtype=np.uint32))
    return L._leaf32(*args)[0]


def _skips(ray, soa, first, last, leaf, eps, tmax=None):
    """True where the filter skips ``leaf`` (tested alone: the leaves ``leaf:leaf + 1``)."""
    o32, d32, t0, t1 = ray
    k = L._scan(*o32, *d32, t0, t1 if tmax is None else tmax, soa, first, last, leaf, leaf + 1, eps)
    return int(k) != leaf


@pytest.fixture(scope="module")
def cases():
    rng = np.random.default_rng(25)
    n_tri = 60
    centre = rng.uniform(-1, 1, size=(n_tri, 1, 3))
    tris = centre + rng.normal(scale=10.0 ** rng.uniform(-2, 0, size=(n_tri, 1, 1)), size=(n_tri, 3, 3))
    # each triangle alone in a leaf, and again among others (leaves of 2 - 19 triangles)
    leaves = [[k] for k in range(n_tri)]
    home = list(range(n_tri))  # the leaf that holds triangle k alone
    mixed = {}
    for k in range(n_tri):
        others = [int(x) for x in rng.choice(n_tri, size=rng.integers(1, 19), replace=False) if x != k]
        leaf = others[: len(others) // 2] + [k] + others[len(others) // 2:]
        mixed[k] = len(leaves)
        leaves.append(leaf)
    soa, first, last = _stack(tris, leaves)
    rays = []
    for k, o, d, tmin, tmax in _rays(tris, rng, per=60):
        ray = (tuple(F(x) for x in o), tuple(F(x) for x in d), F(tmin), F(tmax))
        rays.append((k, ray))
    return soa, first, last, rays, home, mixed


def test_the_filter_never_skips_a_leaf_the_full_test_accepts(cases):
    soa, first, last, rays, home, mixed = cases
    accepted = missed = 0
    for k, ray in rays:
        for leaf in (home[k], mixed[k]):
            if _leaf32(ray, soa, first[leaf], last[leaf], EPS) < 0:
                continue
            accepted += 1
            missed += _skips(ray, soa, first, last, leaf, EPS)
    assert accepted > 1000  # (most of these rays hit: the edge ones on either side of the tolerance)
    assert missed == 0


def test_the_rays_are_adversarial_enough_to_catch_a_filter_without_its_margins(cases):
    """Each kind of margin matters on these rays: without the edge tolerance, or with
    ``tmax`` one ulp short, the filter skips leaves the full test accepts."""
    soa, first, last, rays, home, _ = cases
    no_eps = short_t = 0
    for k, ray in rays:
        leaf = home[k]
        if _leaf32(ray, soa, first[leaf], last[leaf], EPS) < 0:
            continue
        no_eps += _skips(ray, soa, first, last, leaf, F(0.0))
        short_t += _skips(ray, soa, first, last, leaf, EPS, tmax=np.nextafter(ray[3], F(-np.inf)))
    assert no_eps > 0 and short_t > 0
