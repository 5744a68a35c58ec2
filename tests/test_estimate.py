"""The radiance filters of §III.A.2–3 (eqs. 3.2–3.5, Fig. 8): brute force, consistency, edge cases.

Every estimator is checked against an independent reference written here: all photons
against all queries for the fixed-radius filters, an argsort k-NN for the exact
reference, a query-by-query re-implementation of the k-voxel sampling, and a
recursive Fig. 8 for the m-voxel node lists and work counts.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from tlm.kernels import estimate as est
from tlm.kernels import kvoxel
from tlm.kernels.bsp import build_point_tree
from tlm.kernels.memory import Streams, page_misses, span_addresses
from tlm.kernels.shade import hash_uniform

CONE = 1.1
SLACK = 2.0**-40  # the documented widening of Fig. 8's search cube
COPLANAR_TOL = 2.0**-32  # the documented tolerance of the k-voxel filter's flat splits

# ---------------------------------------------------------------- maps and queries


def unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def cube_map(n: int, seed: int):
    rng = np.random.default_rng(seed)
    return rng.uniform(0, 1, (n, 3)), rng.uniform(0, 2, (n, 3)), unit(rng.normal(size=(n, 3)))


def plane_map(n: int, seed: int, total: float = 3.0):
    """Photons uniform on the unit square of z = 0, total power ``total`` W, arriving from above."""
    rng = np.random.default_rng(seed)
    pos = np.zeros((n, 3))
    pos[:, :2] = rng.uniform(0, 1, (n, 2))
    inc = unit(np.column_stack([rng.uniform(-0.5, 0.5, (n, 2)), -np.ones(n)]))
    return pos, np.full((n, 3), total / n), inc


def cube_queries(q: int, seed: int, lo: float = 0.0, hi: float = 1.0):
    rng = np.random.default_rng(seed)
    return rng.uniform(lo, hi, (q, 3)), unit(rng.normal(size=(q, 3)))


def plane_queries(q: int, seed: int):
    rng = np.random.default_rng(seed)
    pts = np.zeros((q, 3))
    pts[:, :2] = rng.uniform(0.2, 0.8, (q, 2))
    return pts, np.tile([0.0, 0.0, 1.0], (q, 1))


# ---------------------------------------------------------------- references


def sq_dist(pos: np.ndarray, x: np.ndarray) -> np.ndarray:
    """(q, n) squared distances, in the estimators' documented order."""
    d = [pos[None, :, c] - x[:, None, c] for c in range(3)]
    return (d[0] * d[0] + d[1] * d[1]) + d[2] * d[2]


def front(inc: np.ndarray, nrm: np.ndarray) -> np.ndarray:
    return (inc[None, :, 0] * nrm[:, None, 0] + inc[None, :, 1] * nrm[:, None, 1]
            + inc[None, :, 2] * nrm[:, None, 2]) < 0.0


def brute_fixed(pos, power, inc, pts, nrm, r, cone_k=None):
    """All photons against all queries: (density (q, 3), photons accepted (q,))."""
    d2 = sq_dist(pos, pts)
    acc = (d2 <= r * r) & front(inc, nrm)
    if r == 0.0:
        return np.zeros((pts.shape[0], 3)), acc.sum(axis=1)
    w = acc * (1.0 if cone_k is None else 1.0 - np.sqrt(d2) / (cone_k * r))
    norm = math.pi * r * r * (1.0 if cone_k is None else 1.0 - 2.0 / (3.0 * cone_k))
    return (w @ power) / norm, acc.sum(axis=1)


def brute_knn(pos, power, inc, pts, nrm, k, cone_k=CONE):
    """Argsort k-NN, summed in (distance, id) order like the estimator: exact.

    Returns (density, accepted, unique): ``unique`` is False where photons tie at the
    k-th distance (any of them may be taken; cKDTree decides).
    """
    q, n = pts.shape[0], pos.shape[0]
    kk = min(k, n)
    dens, acc = np.zeros((q, 3)), np.zeros(q, dtype=np.int64)
    unique = np.ones(q, dtype=bool)
    if kk == 0:
        return dens, acc, unique
    d2 = sq_dist(pos, pts)
    fr = front(inc, nrm)
    for i in range(q):
        order = np.lexsort((np.arange(n), d2[i]))
        unique[i] = kk == n or d2[i, order[kk]] > d2[i, order[kk - 1]]
        order = order[:kk]
        d = np.sqrt(d2[i, order])
        rk = d[-1]
        acc[i] = fr[i, order].sum()
        if rk == 0.0:
            continue
        w = np.where(fr[i, order], 1.0 - d / (cone_k * rk), 0.0)
        norm = (1.0 - 2.0 / (3.0 * cone_k)) * math.pi * rk**2
        for c in range(3):
            s = 0.0
            for j in range(kk):
                s += w[j] * power[order[j], c]
            dens[i, c] = s / norm
    return dens, acc, unique


def fig8(tree, x: np.ndarray, r: float) -> tuple[list[int], int]:
    """Recursive Fig. 8 for one query: (leaves listed, inner nodes visited)."""
    pad = r + SLACK * (np.abs(x) + r)
    leaves: list[int] = []
    inner = 0

    def visit(i: int, j: int) -> None:
        nonlocal inner
        if j == tree.levels:
            leaves.append(i - tree.leaf_offset)
            return
        inner += 1
        a, d = j % 3, tree.split[i]
        if d > x[a] - pad[a]:
            visit(2 * i + 1, j + 1)
        if d <= x[a] + pad[a]:
            visit(2 * i + 2, j + 1)

    visit(0, 0)
    return leaves, inner


def layered_splits(tree, pos):
    """Brute force, node by node: (delta, moved splits, flat) as the module docstring defines them."""
    delta = min(COPLANAR_TOL * np.abs(np.concatenate([tree.lo[0], tree.hi[0]])).max(),
                2.0**-20 * np.max(tree.hi[0] - tree.lo[0]))
    split = tree.split.copy()
    flat = np.zeros(tree.leaf_offset, dtype=bool)
    for i in range(tree.leaf_offset):
        a, d = ((i + 1).bit_length() - 1) % 3, tree.split[i]
        n_left = tree.last[2 * i + 1] - tree.first[2 * i + 1]
        n_right = tree.last[2 * i + 2] - tree.first[2 * i + 2]
        if n_left and n_right:
            flat[i] = np.all(np.abs(pos[tree.items[tree.first[i] : tree.last[i]], a] - d) <= delta)
        elif n_left:
            split[i] = d + 2.0 * delta
        elif n_right:
            split[i] = d - 2.0 * delta
    return delta, split, flat


def descend(tree, layered, p: np.ndarray, x: np.ndarray, lim: np.ndarray) -> tuple[list[int], int]:
    """Leaves reached by point ``p`` of the disk at ``x``, and the inner nodes visited."""
    _, split, flat = layered
    leaves: list[int] = []
    inner = 0

    def visit(i: int, j: int) -> None:
        nonlocal inner
        if j == tree.levels:
            leaves.append(i - tree.leaf_offset)
            return
        inner += 1
        a = j % 3
        if flat[i] and abs(x[a] - tree.split[i]) <= lim[a]:  # the disk lies on the split: both layers
            visit(2 * i + 1, j + 1)
            visit(2 * i + 2, j + 1)
        else:
            visit(2 * i + (2 if p[a] >= split[i] else 1), j + 1)

    visit(0, 0)
    return leaves, inner


def kvoxel_reference(pos, power, inc, tree, pts, nrm, r, k, cone_k, seed, keys):
    """Query by query: sample, locate, search each distinct voxel by brute force (eqs. 3.4/3.5).

    A sample reaching several leaves (layers under flat splits) sums their estimates.
    """
    m = np.arange(64)
    rho = np.sqrt((m + 0.5) / 64)
    phi = m * math.pi * (3.0 - math.sqrt(5.0))
    pu, pv = rho * np.cos(phi), rho * np.sin(phi)
    cw = np.round((1.0 - rho / cone_k) * 2.0**20) * 2.0**-20
    norm = (1.0 - 2.0 / (3.0 * cone_k)) * math.pi * r * r
    first, last = tree.leaf_ranges()
    layered = layered_splits(tree, pos)
    q = pts.shape[0]
    dens = np.zeros((q, 3))
    names = ("leaves", "tested", "accepted", "nodes", "probes")
    counts = {name: np.zeros(q, dtype=np.int64) for name in names}
    for i in range(q):
        x, (nx, ny, nz) = pts[i], nrm[i]
        sign = math.copysign(1.0, nz)
        a = -1.0 / (sign + nz)
        b = nx * ny * a
        t1 = np.array([1.0 + sign * nx * nx * a, sign * b, -sign * nx])
        t2 = np.array([b, sign + ny * ny * a, -ny])
        lim = layered[0] - r * np.sqrt(t1 * t1 + t2 * t2)
        s = np.arange(1, k)
        rs = r * np.sqrt(hash_uniform(seed, keys[i], 7, s, 0))
        ph = 2.0 * math.pi * hash_uniform(seed, keys[i], 7, s, 1)
        samples = [x] + [x + (u * t1 + v * t2) for u, v in zip(rs * np.cos(ph), rs * np.sin(ph))]
        reached = [descend(tree, layered, p, x, lim) for p in samples]
        probes = [descend(tree, layered, x + ((r * a_) * t1 + (r * b_) * t2), x, lim)[0] for a_, b_ in zip(pu, pv)]
        counts["nodes"][i] = sum(v for _, v in reached)
        counts["probes"][i] = sum(len(pl) for pl in probes)
        for leaf in sorted({leaf for ls, _ in reached for leaf in ls}):
            ids = tree.items[first[leaf] : last[leaf]]
            d2 = sq_dist(pos[ids], x[None])[0]
            ok = (d2 <= r * r) & front(inc[ids], nrm[i : i + 1])[0]
            counts["leaves"][i] += 1
            counts["tested"][i] += ids.shape[0]
            counts["accepted"][i] += ok.sum()
            frac = sum(c for c, pl in zip(cw, probes) if leaf in pl) / cw.sum()
            mult = sum(leaf in ls for ls, _ in reached)
            if r > 0 and frac > 0:
                w = np.where(ok, 1.0 - np.sqrt(d2) / (cone_k * r), 0.0)
                dens[i] += (w @ power[ids]) / (norm * frac) * mult / k
    return dens, counts


def close(a: np.ndarray, b: np.ndarray, rtol: float = 1e-12) -> None:
    scale = max(float(np.abs(b).max(initial=0.0)), 1e-300)
    np.testing.assert_allclose(a, b, rtol=rtol, atol=rtol * scale)


def finite_nonneg(e: est.Estimate) -> None:
    assert np.all(np.isfinite(e.density)) and np.all(e.density >= 0.0)
    for name in ("node_visits", "leaves_visited", "photons_tested", "photons_accepted", "probe_tests"):
        v = getattr(e, name)
        assert v.dtype == np.int64 and v.shape == (e.density.shape[0],) and np.all(v >= 0)


FIXED = [("disk", None), ("mvoxel", CONE)]


def fixed(kind: str, *args, **kw) -> est.Estimate:
    return est.disk_estimate(*args, **kw) if kind == "disk" else est.mvoxel_estimate(*args, cone_k=CONE, **kw)


# ---------------------------------------------------------------- brute force


@pytest.mark.slow
@pytest.mark.parametrize("kind,cone", FIXED)
@pytest.mark.parametrize("levels", [None, 0, 3])
def test_fixed_radius_equals_brute_force(kind, cone, levels):
    pos, power, inc = cube_map(3000, 1)
    pts, nrm = cube_queries(300, 2, -0.1, 1.1)
    tree = build_point_tree(pos, levels)
    for r in (0.03, 0.12, 0.7):
        e = fixed(kind, pos, power, inc, tree, pts, nrm, r)
        ref, acc = brute_fixed(pos, power, inc, pts, nrm, r, cone)
        np.testing.assert_array_equal(e.photons_accepted, acc)
        close(e.density, ref)
        finite_nonneg(e)


@pytest.mark.slow
def test_knn_equals_brute_force():
    pos, power, inc = cube_map(2000, 3)
    pts, nrm = cube_queries(150, 4)
    for k in (1, 7, 50):
        e = est.knn_estimate(pos, power, inc, pts, nrm, k_nearest=k, cone_k=CONE)
        ref, acc, unique = brute_knn(pos, power, inc, pts, nrm, k)
        assert unique.all()
        np.testing.assert_array_equal(e.density, ref)
        np.testing.assert_array_equal(e.photons_accepted, acc)
        assert np.all(e.photons_tested == k) and np.all(e.node_visits == 0) and np.all(e.leaves_visited == 0)
    e2 = est.knn_estimate(pos, power, inc, pts, nrm, k_nearest=7, cone_k=CONE, kdtree=cKDTree(pos))
    np.testing.assert_array_equal(e2.density, brute_knn(pos, power, inc, pts, nrm, 7)[0])


@pytest.mark.slow
@pytest.mark.parametrize("k", [1, 3, 8])
def test_kvoxel_equals_reference(k):
    pos, power, inc = cube_map(4000, 5)
    pts, nrm = cube_queries(80, 6, 0.05, 0.95)
    tree = build_point_tree(pos)
    keys = np.arange(80, dtype=np.int64) * 7919 + 11
    e = kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, k=k, cone_k=CONE, seed=42, keys=keys)
    ref, counts = kvoxel_reference(pos, power, inc, tree, pts, nrm, 0.1, k, CONE, 42, keys)
    close(e.density, ref)
    np.testing.assert_array_equal(e.leaves_visited, counts["leaves"])
    np.testing.assert_array_equal(e.photons_tested, counts["tested"])
    np.testing.assert_array_equal(e.photons_accepted, counts["accepted"])
    assert np.all(e.node_visits == k * tree.levels) and np.all(e.probe_tests == kvoxel.PROBES)
    np.testing.assert_array_equal(e.node_visits, counts["nodes"])
    np.testing.assert_array_equal(e.probe_tests, counts["probes"])
    assert np.all(e.leaves_visited <= k)
    finite_nonneg(e)


def traced_plane(n: int, seed: int, z0: float = 0.5, jitter: float = 1e-13):
    """``plane_map`` on the plane z = z0, each z off by up to ``jitter`` (rounding of traced photons)."""
    pos, power, inc = plane_map(n, seed)
    pos[:, 2] = z0 + np.random.default_rng(seed + 1).uniform(-jitter, jitter, n)
    return pos, power, inc


def scattered_z_splits(tree, pos) -> int:
    """Inner nodes splitting along z whose photons lie on both sides, all within 1e-12 of the split."""
    count = 0
    for i in range(tree.leaf_offset):
        if ((i + 1).bit_length() - 1) % 3 == 2:
            z = pos[tree.items[tree.first[i] : tree.last[i]], 2]
            d = tree.split[i]
            count += bool(np.any(z < d) and np.any(z >= d) and np.all(np.abs(z - d) < 1e-12))
    return count


@pytest.mark.slow
@pytest.mark.parametrize("k", [1, 4, 8])
def test_kvoxel_layers_equal_reference(k):
    """Photons on a plane, off it by rounding: the splits along z scatter them (layers)."""
    pos, power, inc = traced_plane(6000, 30)
    tree = build_point_tree(pos)
    assert scattered_z_splits(tree, pos) >= 7
    pts, nrm = plane_queries(60, 31)
    pts[:, 2] = 0.5 + np.random.default_rng(32).uniform(-1e-13, 1e-13, 60)
    pts[-10:] += [0.0, 0.0, 1e-3]  # off the plane: a disk that does not lie on the splits
    keys = np.arange(60, dtype=np.int64) * 131 + 3
    e = kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, k=k, cone_k=CONE, seed=5, keys=keys)
    ref, counts = kvoxel_reference(pos, power, inc, tree, pts, nrm, 0.1, k, CONE, 5, keys)
    close(e.density, ref)
    for name, key in (("leaves_visited", "leaves"), ("photons_tested", "tested"),
                      ("photons_accepted", "accepted"), ("node_visits", "nodes"), ("probe_tests", "probes")):
        np.testing.assert_array_equal(getattr(e, name), counts[key], err_msg=name)
    assert np.all(e.node_visits[:-10] > k * tree.levels) and np.all(e.probe_tests[:-10] > kvoxel.PROBES)
    np.testing.assert_array_equal(e.node_visits[-10:], k * tree.levels)
    finite_nonneg(e)


@pytest.mark.slow
@pytest.mark.parametrize("k", [1, 4, 8, 16])
def test_kvoxel_unbiased_on_traced_plane(k):
    """Regression: with every z split on the plane, one voxel held one layer's photons only.

    The voxel was credited with the whole disk, and the estimate fell to ~1/8 of the
    m-voxel one (three z levels); summing the layers' estimates removes the bias.
    """
    pos, power, inc = traced_plane(40_000, 33)
    tree = build_point_tree(pos)
    assert scattered_z_splits(tree, pos) >= 50
    pts, nrm = plane_queries(400, 34)
    pts[:, 2] = 0.5 + np.random.default_rng(35).uniform(-1e-13, 1e-13, 400)
    args = (pos, power, inc, tree, pts, nrm, 0.05)
    mv = est.mvoxel_estimate(*args, cone_k=CONE)
    kv = kvoxel.kvoxel_estimate(*args, k=k, cone_k=CONE, seed=6)
    assert abs(kv.density.mean() / mv.density.mean() - 1.0) < 0.03, kv.density.mean() / mv.density.mean()
    assert abs(mv.density.mean() / 3.0 - 1.0) < 0.03
    # the layers' leaves are searched by the m-voxel filter too
    assert np.all(kv.photons_tested <= mv.photons_tested)
    finite_nonneg(kv)


@pytest.mark.slow
@pytest.mark.parametrize("tilt", [0.0, 1e-9, 1e-6, 1e-3])
def test_kvoxel_unbiased_on_traced_box(tilt):
    """Photons and queries on the six faces of a box, rounded off them by ~1e-13, faces
    tilted by ``tilt`` (0: flat splits on every face; otherwise the splits cut the faces)."""
    rng = np.random.default_rng(36)
    n, q = 60_000, 600
    pos, normal, axis = [], [], []
    for size in (n, q):
        p = rng.uniform(0.0, 1.0, (size, 3))
        ax = rng.integers(0, 3, size)
        side = rng.integers(0, 2, size).astype(np.float64)
        rows = np.arange(size)
        other = (ax + 1) % 3
        p[rows, ax] = side + tilt * (p[rows, other] - 0.5) + rng.uniform(-1e-13, 1e-13, size)
        nv = np.zeros((size, 3))
        nv[rows, ax] = 1.0 - 2.0 * side
        nv[rows, other] = -tilt * (1.0 - 2.0 * side)
        pos.append(p)
        normal.append(unit(nv))
        axis.append(ax)
    inc = unit(-normal[0] + rng.uniform(-0.7, 0.7, (n, 3)) * (np.abs(normal[0]) < 0.5))
    power = rng.uniform(0.5, 1.5, (n, 3)) / n
    tree = build_point_tree(pos[0])
    pts, nrm = pos[1], normal[1]
    inside = np.all((pts > 0.1) & (pts < 0.9) | (np.abs(nrm) > 0.5), axis=1)  # away from edges
    args = (pos[0], power, inc, tree, pts[inside], nrm[inside], 0.06)
    mv = est.mvoxel_estimate(*args, cone_k=CONE).density.sum(axis=1)
    kv = kvoxel.kvoxel_estimate(*args, k=8, cone_k=CONE, seed=7).density.sum(axis=1)
    assert abs(kv.mean() / mv.mean() - 1.0) < 0.03, kv.mean() / mv.mean()


def test_kvoxel_one_voxel_is_mvoxel():
    """When one voxel covers the whole disk, eq. 3.5 is exactly the m-voxel estimate."""
    pos, power, inc = cube_map(2000, 7)
    pts, nrm = cube_queries(100, 8, 0.2, 0.8)
    tree = build_point_tree(pos, 0)
    kv = kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, k=5, cone_k=CONE)
    mv = est.mvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, cone_k=CONE)
    np.testing.assert_array_equal(kv.density, mv.density)


# ---------------------------------------------------------------- consistency


@pytest.fixture(scope="module")
def planes():
    """Uniform plane maps (P/A = 3 W/m^2) of 20k and 200k photons, and their estimates at r = 0.05."""
    out = {}
    pts, nrm = plane_queries(300, 9)
    for n in (20_000, 200_000):
        pos, power, inc = plane_map(n, n)
        tree = build_point_tree(pos)
        lp = est.leaf_photons(pos, power, inc, tree)
        args = (pos, power, inc, tree, pts, nrm, 0.05)
        out[n] = {
            "disk": est.disk_estimate(*args, prepared=lp),
            "mvoxel": est.mvoxel_estimate(*args, cone_k=CONE, prepared=lp),
            "kvoxel": kvoxel.kvoxel_estimate(*args, k=8, cone_k=CONE, seed=1, prepared=lp),
            "knn": est.knn_estimate(pos, power, inc, pts, nrm, k_nearest=50, cone_k=CONE),
        }
        # the same depth at both counts (the default, floor(ln n), is 9 for 20k photons)
        tree9 = build_point_tree(pos, 9)
        args9 = (pos, power, inc, tree9, pts, nrm, 0.05)
        out[n]["kvoxel9"] = kvoxel.kvoxel_estimate(*args9, k=8, cone_k=CONE, seed=1)
        out[n]["mvoxel9"] = est.mvoxel_estimate(*args9, cone_k=CONE)
    return out


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["disk", "mvoxel", "knn"])
def test_uniform_density(planes, kind):
    expect = 3.0
    err = {}
    for n, estimates in planes.items():
        d = estimates[kind].density
        assert abs(d.mean() / expect - 1.0) < 0.03, (n, d.mean())
        err[n] = np.abs(d / expect - 1.0).mean()
    if kind != "knn":  # fixed radius: more photons in the disk, less noise
        assert err[200_000] < 0.6 * err[20_000] and err[200_000] < 0.04
    else:  # k fixed: noise ~ 1/sqrt(k) at any density
        assert err[200_000] < 0.15


@pytest.mark.slow
def test_kvoxel_converges_to_mvoxel(planes):
    """At a fixed depth the k voxels fill with photons and eq. 3.5 approaches eq. 3.3.

    At the default depth ``floor(ln n)`` the leaves keep ~40-60 photons whatever ``n``,
    so the k-voxel estimate keeps its own noise (a few percent here), but stays close.
    """
    def rel(e, kv, mv):
        return np.abs(e[kv].density / e[mv].density - 1.0).mean()

    fixed_depth = {n: rel(e, "kvoxel9", "mvoxel9") for n, e in planes.items()}
    assert fixed_depth[200_000] < 0.025 and fixed_depth[200_000] < 0.8 * fixed_depth[20_000]
    assert rel(planes[200_000], "kvoxel", "mvoxel") < 0.05
    for e in planes.values():
        for kv in ("kvoxel", "kvoxel9"):
            assert abs(e[kv].density.mean() / 3.0 - 1.0) < 0.03
            finite_nonneg(e[kv])
        assert np.all(e["kvoxel"].photons_tested <= e["mvoxel"].photons_tested)


# ---------------------------------------------------------------- edge cases


def all_estimates(pos, power, inc, tree, pts, nrm, r, k=4):
    return {
        "disk": est.disk_estimate(pos, power, inc, tree, pts, nrm, r),
        "mvoxel": est.mvoxel_estimate(pos, power, inc, tree, pts, nrm, r, cone_k=CONE),
        "kvoxel": kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, r, k=k, cone_k=CONE, seed=3),
        "knn": est.knn_estimate(pos, power, inc, pts, nrm, k_nearest=5, cone_k=CONE),
    }


def check_all(pos, power, inc, tree, pts, nrm, r):
    e = all_estimates(pos, power, inc, tree, pts, nrm, r)
    for kind, cone in FIXED:
        ref, acc = brute_fixed(pos, power, inc, pts, nrm, r, cone)
        np.testing.assert_array_equal(e[kind].photons_accepted, acc)
        close(e[kind].density, ref)
    ref, acc, unique = brute_knn(pos, power, inc, pts, nrm, 5)
    np.testing.assert_array_equal(e["knn"].density[unique], ref[unique])
    np.testing.assert_array_equal(e["knn"].photons_accepted[unique], acc[unique])
    for v in e.values():
        finite_nonneg(v)
    return e


def test_behind_photons_excluded():
    pos, power, _ = plane_map(5000, 10)
    pts, nrm = plane_queries(50, 11)
    tree = build_point_tree(pos)
    from_below = np.tile([0.0, 0.0, 1.0], (5000, 1))
    for e in all_estimates(pos, power, from_below, tree, pts, nrm, 0.05).values():
        assert np.all(e.density == 0.0) and np.all(e.photons_accepted == 0)
    # half from above, half from below: only the first half counts
    inc = np.where((np.arange(5000) % 2 == 0)[:, None], [0.0, 0.0, -1.0], from_below)
    check_all(pos, power, inc, tree, pts, nrm, 0.05)
    mv = est.mvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.05)
    keep = np.arange(5000) % 2 == 0
    ref, _ = brute_fixed(pos[keep], power[keep], inc[keep], pts, nrm, 0.05, CONE)
    close(mv.density, ref)


def test_photons_on_split_planes_counted_once():
    """Integer grid: centre-of-mass splits fall exactly on photons, at distance exactly r."""
    g = np.arange(9.0)
    pos = np.stack(np.meshgrid(g, g, g, indexing="ij"), axis=-1).reshape(-1, 3)
    rng = np.random.default_rng(12)
    power, inc = rng.uniform(0, 1, pos.shape), unit(rng.normal(size=pos.shape))
    tree = build_point_tree(pos, 6)
    assert np.isin(tree.split[: tree.leaf_offset], g).mean() > 0.5  # splits lie on photon planes
    pts = np.vstack([pos[rng.choice(729, 60, replace=False)], rng.integers(0, 17, (40, 3)) / 2.0])
    nrm = unit(rng.normal(size=pts.shape))
    for r in (1.0, 2.0, 0.5):
        check_all(pos, power, inc, tree, pts, nrm, r)
        mv = est.mvoxel_estimate(pos, power, np.tile([0.0, 0.0, -1.0], (729, 1)), tree, pts,
                                 np.tile([0.0, 0.0, 1.0], (100, 1)), r)
        within = (sq_dist(pos, pts) <= r * r).sum(axis=1)
        np.testing.assert_array_equal(mv.photons_accepted, within)


def test_coincident_photons():
    rng = np.random.default_rng(13)
    pos = np.vstack([np.full((60, 3), 0.5), rng.uniform(0, 1, (40, 3))])
    power, inc = rng.uniform(0, 1, pos.shape), unit(rng.normal(size=pos.shape))
    tree = build_point_tree(pos, 5)
    pts = np.vstack([np.full((5, 3), 0.5), rng.uniform(0, 1, (20, 3))])
    nrm = unit(rng.normal(size=pts.shape))
    for r in (0.0, 0.05, 0.3):
        check_all(pos, power, inc, tree, pts, nrm, r)
    # all k nearest at distance 0: r_k = 0 gives 0, not NaN
    e = est.knn_estimate(pos, power, inc, pts[:5], nrm[:5], k_nearest=10)
    assert np.all(e.density == 0.0)


@pytest.mark.parametrize("shape", ["plane_xy", "plane_tilted", "line_x", "line_diag"])
def test_degenerate_maps(shape):
    rng = np.random.default_rng(14)
    t = rng.uniform(0, 1, (800, 2))
    pos = {
        "plane_xy": np.column_stack([t, np.full(800, 0.3)]),
        "plane_tilted": np.column_stack([t, 0.2 * t[:, 0] + 0.5 * t[:, 1]]),
        "line_x": np.column_stack([t[:, 0], np.full(800, 0.4), np.full(800, 0.6)]),
        "line_diag": np.repeat(t[:, :1], 3, axis=1),
    }[shape]
    power, inc = rng.uniform(0, 1, pos.shape), unit(rng.normal(size=pos.shape))
    tree = build_point_tree(pos, 7)
    pts = np.vstack([pos[:30], pos[30:60] + rng.normal(0, 0.02, (30, 3))])
    nrm = unit(rng.normal(size=pts.shape))
    for r in (0.02, 0.1):
        check_all(pos, power, inc, tree, pts, nrm, r)


@pytest.mark.parametrize("n", [0, 1, 2, 3])
@pytest.mark.parametrize("levels", [None, 4])
def test_tiny_maps(n, levels):
    rng = np.random.default_rng(15 + n)
    pos = rng.uniform(0, 1, (n, 3))
    power, inc = rng.uniform(0, 1, (n, 3)), unit(rng.normal(size=(n, 3))) if n else np.zeros((0, 3))
    tree = build_point_tree(pos, levels)
    pts = np.vstack([pos, rng.uniform(0, 1, (10, 3))])
    nrm = unit(rng.normal(size=pts.shape))
    e = check_all(pos, power, inc, tree, pts, nrm, 0.6)
    if n == 0:
        assert all(np.all(v.density == 0.0) for v in e.values())
    np.testing.assert_array_equal(e["knn"].photons_tested, min(n, 5))


def test_zero_power_and_radius_zero():
    pos, power, inc = cube_map(500, 16)
    power[::3] = 0.0
    tree = build_point_tree(pos)
    pts, nrm = np.vstack([pos[:20], cube_queries(20, 17)[0]]), unit(np.ones((40, 3)))
    check_all(pos, power, inc, tree, pts, nrm, 0.2)
    for kind, e in all_estimates(pos, power, inc, tree, pts, nrm, 0.0).items():
        finite_nonneg(e)
        if kind != "knn":
            assert np.all(e.density == 0.0)
            assert np.all(e.leaves_visited >= 1)


def test_no_queries():
    pos, power, inc = cube_map(100, 18)
    tree = build_point_tree(pos)
    z = np.zeros((0, 3))
    for e in all_estimates(pos, power, inc, tree, z, z, 0.1).values():
        assert e.density.shape == (0, 3) and e.photons_tested.shape == (0,)


def test_invalid_arguments():
    pos, power, inc = cube_map(100, 19)
    tree = build_point_tree(pos)
    pts, nrm = cube_queries(5, 20)
    with pytest.raises(ValueError):
        est.mvoxel_estimate(pos, power, inc, tree, pts, nrm, -0.1)
    with pytest.raises(ValueError):
        est.disk_estimate(pos, power, inc, tree, pts, nrm, float("nan"))
    with pytest.raises(ValueError):
        est.mvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, cone_k=0.5)
    with pytest.raises(ValueError):
        kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, k=0)
    with pytest.raises(ValueError):
        est.knn_estimate(pos, power, inc, pts, nrm, k_nearest=0)
    with pytest.raises(ValueError):
        est.disk_estimate(pos[:50], power[:50], inc[:50], tree, pts, nrm, 0.1)
    other = est.leaf_photons(pos, power, inc, build_point_tree(pos, 2))
    with pytest.raises(ValueError):
        est.mvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, prepared=other)


# ---------------------------------------------------------------- packet invariance


def run_all(pos, power, inc, tree, pts, nrm, keys, streams=None):
    """Every filter; ``streams``: one Streams per filter (a dict), or one to copy, or None."""
    if not isinstance(streams, dict):
        streams = {kind: None if streams is None else Streams(streams.page_words)
                   for kind in ("disk", "mvoxel", "kvoxel")}
    return {
        "disk": est.disk_estimate(pos, power, inc, tree, pts, nrm, 0.08, streams=streams["disk"]),
        "mvoxel": est.mvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.08, cone_k=CONE, streams=streams["mvoxel"]),
        "kvoxel": kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.08, k=6, seed=9, keys=keys,
                                      streams=streams["kvoxel"]),
        "knn": est.knn_estimate(pos, power, inc, pts, nrm, k_nearest=20),
    }


def assert_same(a: est.Estimate, b: est.Estimate, idx=slice(None), misses: bool = False) -> None:
    """Equal results and work; ``misses``: the page misses too (they depend on the queries
    before, so only for the same queries in the same order)."""
    names = ["density", "node_visits", "leaves_visited", "photons_tested", "photons_accepted", "probe_tests"]
    for name in names + ["gather_misses"] * misses:
        np.testing.assert_array_equal(getattr(a, name)[idx], getattr(b, name), err_msg=name)


@pytest.mark.slow
def test_packet_invariance(monkeypatch):
    pos, power, inc = cube_map(6000, 21)
    tree = build_point_tree(pos)
    pts, nrm = cube_queries(700, 22, -0.05, 1.05)
    keys = np.arange(700, dtype=np.int64) * 31 + 5
    full = run_all(pos, power, inc, tree, pts, nrm, keys)
    rng = np.random.default_rng(23)
    subsets = [rng.permutation(700)[:137], rng.permutation(700), np.array([411])]
    for idx in subsets:
        part = run_all(pos, power, inc, tree, pts[idx], nrm[idx], keys[idx])
        for kind in full:
            assert_same(full[kind], part[kind], idx)
    # tiny blocks and chunks (and halved traversal blocks) change nothing
    monkeypatch.setattr(est, "CHUNK", 50)
    monkeypatch.setattr(est, "QUERY_BLOCK", 40)
    monkeypatch.setattr(est, "PAIR_BUDGET", 60)
    small = run_all(pos, power, inc, tree, pts, nrm, keys)
    for kind in full:
        assert_same(full[kind], small[kind], misses=True)


def test_packet_invariance_with_layers(monkeypatch):
    """Queries on a traced plane (flat splits, extra branches) and in a cloud beside it."""
    pos, power, inc = traced_plane(5000, 37)
    pos = np.vstack([pos, cube_map(1000, 38)[0] + [1.5, 0.0, 0.0]])  # and a cloud beside the plane
    power, inc = np.vstack([power, power[:1000]]), np.vstack([inc, inc[:1000]])
    tree = build_point_tree(pos)
    pts, nrm = plane_queries(300, 39)
    pts[:, 2] = 0.5 + np.random.default_rng(40).uniform(-1e-13, 1e-13, 300)
    pts[200:] = cube_queries(100, 41)[0] + [1.5, 0.0, 0.0]
    nrm[250:] = cube_queries(50, 42)[1]
    keys = np.arange(300, dtype=np.int64) * 17 + 1

    def run(idx):
        return kvoxel.kvoxel_estimate(pos, power, inc, tree, pts[idx], nrm[idx], 0.08, k=6, seed=9, keys=keys[idx])

    full = run(np.arange(300))
    assert np.any(full.probe_tests > kvoxel.PROBES)
    rng = np.random.default_rng(43)
    for idx in (rng.permutation(300)[:71], rng.permutation(300), np.array([7])):
        assert_same(full, run(idx), idx)
    monkeypatch.setattr(est, "QUERY_BLOCK", 24)
    assert_same(full, run(np.arange(300)), misses=True)


def test_prepared_is_the_same():
    pos, power, inc = cube_map(3000, 24)
    tree = build_point_tree(pos)
    pts, nrm = cube_queries(100, 25)
    lp = est.leaf_photons(pos, power, inc, tree)
    a = kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1)
    b = kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, prepared=lp)
    assert_same(a, b)


# ---------------------------------------------------------------- work counts


def box_surface(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    p = rng.uniform(0, 1, (n, 3))
    axis = rng.integers(0, 3, n)
    p[np.arange(n), axis] = rng.integers(0, 2, n)
    return p


@pytest.mark.parametrize("surface", [False, True])
def test_mvoxel_work_counts(surface):
    n = 4000
    pos = box_surface(n, 26) if surface else cube_map(n, 26)[0]
    rng = np.random.default_rng(27)
    power, inc = rng.uniform(0, 1, (n, 3)), unit(rng.normal(size=(n, 3)))
    tree = build_point_tree(pos)
    pts, nrm = cube_queries(60, 28, -0.1, 1.1)
    sizes = tree.last[tree.leaf_offset :] - tree.first[tree.leaf_offset :]
    lo, hi = tree.lo[tree.leaf_offset :], tree.hi[tree.leaf_offset :]
    for r in (0.05, 0.2):
        e = est.mvoxel_estimate(pos, power, inc, tree, pts, nrm, r)
        for i in range(pts.shape[0]):
            leaves, inner = fig8(tree, pts[i], r)
            assert e.leaves_visited[i] == len(leaves) == len(set(leaves))
            assert e.photons_tested[i] == sizes[leaves].sum()
            assert e.node_visits[i] == inner
            gap = np.maximum(np.maximum(lo - pts[i], pts[i] - hi), 0.0)
            touching = np.flatnonzero(np.sum(gap * gap, axis=1) <= r * r)
            assert set(touching.tolist()) <= set(leaves)
            assert e.leaves_visited[i] >= touching.shape[0]


# ---------------------------------------------------------------- page misses


def test_gather_misses_are_those_of_the_photon_leaf_stream():
    """Disk and m-voxel: the misses of reading, query by query, every photon (2 words) of
    every leaf Fig. 8 lists, left to right; the k-voxel filter's of its own leaves."""
    pos, power, inc = cube_map(5000, 51)
    tree = build_point_tree(pos)
    pts, nrm = cube_queries(80, 52, -0.1, 1.1)
    lp = est.leaf_photons(pos, power, inc, tree)
    for page_words in (1024, 64):
        for e in (est.disk_estimate(pos, power, inc, tree, pts, nrm, 0.1, streams=Streams(page_words)),
                  est.mvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, streams=Streams(page_words))):
            words, owner = [], []
            for i in range(pts.shape[0]):
                leaves, _ = fig8(tree, pts[i], 0.1)
                w = span_addresses(lp.first[leaves], lp.first[leaves] + lp.size[leaves], 2)
                words.append(w)
                owner.append(np.full(w.shape[0], i))
            miss, _ = page_misses(np.concatenate(words), page_words=page_words)
            want = np.bincount(np.concatenate(owner)[miss], minlength=pts.shape[0])
            np.testing.assert_array_equal(e.gather_misses, want)
            assert want.sum() > (0 if page_words == 1024 else pts.shape[0])
    kv = kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, streams=Streams(64))
    assert np.all(kv.gather_misses <= 2 * kv.photons_tested) and kv.gather_misses.sum() > 0
    assert np.all(kv.gather_misses[kv.photons_tested == 0] == 0)
    # every query's leaves on a page of their own: one miss per leaf (read once each)
    one = kvoxel.kvoxel_estimate(pos, power, inc, tree, pts, nrm, 0.1, streams=Streams(1))
    full = kv.photons_tested > 0
    assert np.all(one.gather_misses[full] >= 1)
    assert np.all(one.gather_misses <= 2 * kv.photons_tested)
    knn = est.knn_estimate(pos, power, inc, pts, nrm, k_nearest=20)
    assert np.all(knn.gather_misses == 0)  # the cKDTree reference: no hardware leaves


@pytest.mark.slow
def test_gather_misses_of_packets_in_order_with_the_state_carried():
    pos, power, inc = cube_map(6000, 53)
    tree = build_point_tree(pos)
    pts, nrm = cube_queries(300, 54, -0.05, 1.05)
    order = np.lexsort(np.round(pts * 3).T[::-1])  # coherent, like neighbouring pixels
    pts, nrm = pts[order], nrm[order]
    keys = np.arange(300, dtype=np.int64) * 7 + 2
    for page_words in (1024, 32):
        whole = run_all(pos, power, inc, tree, pts, nrm, keys, Streams(page_words))
        streams = {kind: Streams(page_words) for kind in whole}
        parts = {kind: [] for kind in whole}
        cold = dict.fromkeys(whole, 0)
        for s0 in range(0, 300, 37):
            sl = slice(s0, s0 + 37)
            for kind, e in run_all(pos, power, inc, tree, pts[sl], nrm[sl], keys[sl], streams).items():
                parts[kind].append(e.gather_misses)
            for kind, e in run_all(pos, power, inc, tree, pts[sl], nrm[sl], keys[sl], Streams(page_words)).items():
                cold[kind] += int(e.gather_misses.sum())
        for kind, e in whole.items():
            np.testing.assert_array_equal(np.concatenate(parts[kind]), e.gather_misses, err_msg=kind)
            if kind != "knn":  # cold pairs per packet miss where the packets start
                assert cold[kind] >= e.gather_misses.sum() > 0, (kind, page_words)
                assert cold[kind] > e.gather_misses.sum() or page_words < 1024, kind


def test_leaf_order_rows_are_the_gathered_rows():
    """The map in leaf order holds row ``c`` of slot ``i`` = column ``c`` of photon
    ``tree.items[i]``, each (3, n) array C-contiguous (what the compiled gather reads)."""
    rng = np.random.default_rng(3)
    pos, power, inc = (rng.normal(size=(2000, 3)) for _ in range(3))
    tree = build_point_tree(pos, 6)
    lp = est.leaf_photons(pos, power, inc, tree)
    for got, a in ((lp.pos, pos), (lp.pow, power), (lp.inc, inc)):
        assert got.flags.c_contiguous and got.shape == (3, 2000)
        assert got.tobytes() == np.ascontiguousarray(a[tree.items].T).tobytes()
    empty = est.leaf_photons(pos[:0], power[:0], inc[:0], build_point_tree(pos[:0], 0))
    assert empty.pos.shape == (3, 0)
