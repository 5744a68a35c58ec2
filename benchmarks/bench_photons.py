"""Photon-map throughput of tlm's kernels against scipy's cKDTree, in the same run.

For each photon count (photons uniform on the six faces of the unit cube, arriving
from inside the box; or ``--dist cube``: uniform in the unit cube, random directions):

* **build**: ``build_point_tree(position)`` (Algorithm 1, default depth ``floor(ln n)``)
  against ``scipy.spatial.cKDTree(position)``; also the leaf-order copy of the photon
  arrays (``leaf_photons``) that the gathers read. Bar of issue [7 of 7]: the tree within
  2x of cKDTree's build time (issue [2 of 7] asked for 3x).
* **tracing**: photons emitted and traced per second on the thesis scenes.
* **gathers**: radiance estimates per second at ``--queries`` query points (also on the
  faces, normals pointing into the box) with the m-voxel (eq. 3.3, Fig. 8), k-voxel
  (eq. 3.5) and disk (eq. 3.2) filters, against ``cKDTree.query_ball_point(points, r,
  workers=1)`` with the same ``r``, chosen so that about ``--per-sphere`` photons lie
  within ``r`` of a query. Bar of issue [7 of 7]: m-voxel at least 0.5x cKDTree's
  throughput (issue [2 of 7] asked for 0.25x). The exact
  k-NN reference (``knn_estimate``, cKDTree inside) is shown for information.

Each timing is the best of ``--repeat`` runs, one thread. Prints PASS/FAIL per bar and
exits 1 if a bar fails.

    python benchmarks/bench_photons.py [--sizes 20000 80000 120000] [--queries 20000] [--repeat 5]
"""

from __future__ import annotations

import argparse
import math

import numpy as np
from scipy.spatial import cKDTree
from timing import best_of, exit_status, verdict

from tlm.kernels.bsp import build_point_tree
from tlm.kernels.estimate import disk_estimate, knn_estimate, leaf_photons, mvoxel_estimate
from tlm.kernels.kvoxel import kvoxel_estimate


def on_box_faces(n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Points uniform on the faces of the unit cube, and the inward unit normal of their face."""
    p = rng.uniform(0.0, 1.0, (n, 3))
    axis = rng.integers(0, 3, n)
    side = rng.integers(0, 2, n).astype(np.float64)
    p[np.arange(n), axis] = side
    normal = np.zeros((n, 3))
    normal[np.arange(n), axis] = 1.0 - 2.0 * side
    return p, normal


def photon_map(n: int, dist: str, rng: np.random.Generator):
    """(position, power, incoming, query points, query normals, r for ``per`` photons) builder."""
    if dist == "box":
        pos, face = on_box_faces(n, rng)
        inc = -face + rng.uniform(-0.7, 0.7, (n, 3)) * (1.0 - np.abs(face))  # arriving into the face
    else:
        pos = rng.uniform(0.0, 1.0, (n, 3))
        inc = rng.normal(size=(n, 3))
    inc /= np.linalg.norm(inc, axis=1, keepdims=True)
    power = rng.uniform(0.5, 1.5, (n, 3)) / n
    return pos, power, inc


def queries(q: int, dist: str, rng: np.random.Generator):
    if dist == "box":
        return on_box_faces(q, rng)
    pts = rng.uniform(0.05, 0.95, (q, 3))
    nrm = rng.normal(size=(q, 3))
    return pts, nrm / np.linalg.norm(nrm, axis=1, keepdims=True)


TREE_BAR = 2.0  # photon tree build time / cKDTree build time, at most
GATHER_BAR = 0.5  # m-voxel gather throughput / cKDTree.query_ball_point throughput, at least


def radius_for(n: int, dist: str, per: float) -> float:
    if dist == "box":  # a sphere meets a face in a disk; n / 6 photons per unit area
        return math.sqrt(per * 6.0 / (math.pi * n))
    return (per * 3.0 / (4.0 * math.pi * n)) ** (1.0 / 3.0)


def bench_size(n: int, args) -> None:
    rng = np.random.default_rng(n)
    pos, power, inc = photon_map(n, args.dist, rng)
    pts, nrm = queries(args.queries, args.dist, rng)
    r = radius_for(n, args.dist, args.per_sphere)
    q = pts.shape[0]

    t_tree = best_of(lambda: build_point_tree(pos), args.repeat)
    t_kd = best_of(lambda: cKDTree(pos), args.repeat)
    tree, kd = build_point_tree(pos), cKDTree(pos)
    t_leaf = best_of(lambda: leaf_photons(pos, power, inc, tree), args.repeat)
    lp = leaf_photons(pos, power, inc, tree)
    print(f"\n{n} photons ({args.dist}), {tree.levels} levels, {tree.n_leaves} leaves, "
          f"{n / tree.n_leaves:.1f} photons per leaf, r = {r:.5f}")
    print(f"  build   tlm tree {t_tree * 1e3:8.2f} ms   + leaf_photons {t_leaf * 1e3:6.2f} ms   "
          f"cKDTree {t_kd * 1e3:8.2f} ms   tree / cKDTree time {t_tree / t_kd:5.2f}x "
          f"(with leaf_photons {(t_tree + t_leaf) / t_kd:5.2f}x)")
    ok = t_tree / t_kd <= TREE_BAR
    verdict(ok, f"tree build {t_tree / t_kd:.2f}x cKDTree's time (bar: at most {TREE_BAR:g}x)", "  ")

    est_args = (pos, power, inc, tree, pts, nrm, r)
    t_ball = best_of(lambda: kd.query_ball_point(pts, r, workers=1), args.repeat)
    found = np.mean([len(b) for b in kd.query_ball_point(pts[:2000], r, workers=1)])
    runs = {
        "mvoxel": lambda: mvoxel_estimate(*est_args, prepared=lp),
        "kvoxel": lambda: kvoxel_estimate(*est_args, k=args.k, prepared=lp),
        "disk": lambda: disk_estimate(*est_args, prepared=lp),
        "knn": lambda: knn_estimate(pos, power, inc, pts, nrm, k_nearest=args.per_sphere, kdtree=kd),
    }
    print(f"  cKDTree.query_ball_point   {q / t_ball / 1e3:8.1f} kqueries/s   "
          f"({found:.1f} photons within r)")
    for name, fn in runs.items():
        t = best_of(fn, args.repeat)
        e = fn()
        print(f"  {name:8s} gather            {q / t / 1e3:8.1f} kqueries/s   ours / cKDTree {t_ball / t:5.2f}x"
              f"   leaves {e.leaves_visited.mean():5.2f}  tested {e.photons_tested.mean():7.1f}  "
              f"accepted {e.photons_accepted.mean():6.1f}")
        if name == "mvoxel":
            ok = t_ball / t >= GATHER_BAR
            verdict(ok, f"m-voxel gather {t_ball / t:.2f}x cKDTree's throughput (bar: at least {GATHER_BAR:g}x)",
                    "  ")


def bench_tracing(scenes: list[str], repeat: int) -> None:
    """Photons emitted and traced (through the geometry BSP, to the end of their paths)
    per second on the thesis scenes at their default photon counts, tree build included."""
    from tlm.kernels.photons import trace_photons
    from tlm.kernels.traverse import build_accel
    from tlm.scenes.loader import load_scene

    for name in scenes:
        scene = load_scene(name)
        accel = build_accel(scene.triangles)
        n = scene.photons
        result = []
        t = best_of(lambda: result.append(trace_photons(scene, accel, n, seed=0)), repeat)  # noqa: B023
        tr = result[-1]
        print(f"tracing {name:8s} {n:7d} photons  {n / t / 1e3:8.1f} k photons/s   "
              f"{tr.totals()['rays'] / t / 1e3:8.1f} k photon rays/s   stored {tr.photons.n}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[20000, 80000, 120000])
    ap.add_argument("--queries", type=int, default=20000)
    ap.add_argument("--per-sphere", type=int, default=50, help="photons expected within r (and k of k-NN)")
    ap.add_argument("--k", type=int, default=8, help="voxels sampled by the k-voxel filter")
    ap.add_argument("--dist", choices=["box", "cube"], default="box")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--trace-scenes", nargs="*", default=["ring", "room", "cornell"],
                    help="scenes whose photon tracing is timed (none: skip)")
    args = ap.parse_args()
    bench_tracing(args.trace_scenes, args.repeat)
    print(f"queries {args.queries}, best of {args.repeat}, one thread; photons {args.dist}: "
          + ("uniform on the faces of the unit cube" if args.dist == "box" else "uniform in the unit cube"))
    for n in args.sizes:
        bench_size(n, args)
    exit_status()


if __name__ == "__main__":
    main()
