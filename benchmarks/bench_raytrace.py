"""Rays per second of tlm's BSP kernels against Embree (embreex), in the same run.

For each built-in scene: the primary rays of the whole image (closest hit) and one
shadow ray per Lambertian primary hit towards the centre of every light (any hit).
Both engines trace the same rays, one thread each (Embree's ``run`` traces the rays one
after another on the calling thread). tlm runs twice: with its compiled kernel (numba,
the default) and with the numpy reference (``TLM_KERNELS=numpy``), which gives
bit-identical answers. The compiled kernel and Embree are timed one after the other,
``--repeat`` rounds; the numpy reference the best of ``--repeat`` runs. Prints a table
with the rates (from each one's best time), the ratios tlm / Embree of the best times
and the *paired* ratio (the median of the rounds' ratios: a machine that slows down for
a while slows both of a round), then PASS/FAIL of the paired ratio against two bars for
primary and shadow rays on Cornell: at least 1/10 of Embree's rate (issue [7 of 7]) and
at least 1/2 (issue 25, item 2: vectorizable inner loops). Exits 1 if a bar fails.

Beside the rates, tlm's work per ray (its own counts, which Embree does not report):
inner nodes entered, leaves whose triangles were tested, and triangles tested. The
bars are judged on the tree the thesis's rule builds (``floor(ln n)`` levels);
``--levels`` adds rows for other depths of the same scene, so the share of the ratio
that is the tree's (leaves of ~40 triangles against Embree's BVH) can be read off.

    python benchmarks/bench_raytrace.py [--scenes cornell ring room] [--repeat 5] [--levels 8 10]
"""

from __future__ import annotations

import argparse
import os
import time
from contextlib import contextmanager

import numpy as np
from timing import best_of, exit_status, verdict

from tlm.kernels.camera import primary_rays
from tlm.kernels.shade import SPAWN_EPS
from tlm.kernels.traverse import any_hit, build_accel, closest_hit
from tlm.scenes.loader import load_scene
from tlm.scenes.model import KIND


def shadow_rays(scene, accel, hits, o, d):
    hit = hits.triangle >= 0
    kinds = scene.material_table()["kind"]
    lam = hit & (kinds[np.maximum(hits.triangle, 0)] == KIND["lambertian"])
    pts = o[lam] + hits.t[lam, None] * d[lam]
    tri = hits.triangle[lam]
    origins, dirs, ignore = [], [], []
    for light in scene.lights:
        if light.kind == "point":
            target = np.asarray(light.position)
        else:
            target = np.asarray(light.corner) + 0.5 * (np.asarray(light.edge_u) + np.asarray(light.edge_v))
        origins.append(pts)
        dirs.append(target[None, :] - pts)
        ignore.append(tri)
    o_s, d_s = np.concatenate(origins), np.concatenate(dirs)
    rel = SPAWN_EPS * accel.scale / np.linalg.norm(d_s, axis=1)
    return o_s, d_s, np.concatenate(ignore), rel


# Embree's rate / tlm's rate, at most (Cornell, primary and shadow rays): the issue
# that set the bar, and the bar
BARS = (("issue [7 of 7]", 10.0), ("issue 25", 2.0))


@contextmanager
def kernels(engine: str):
    """``TLM_KERNELS=engine`` inside the block, restored after it."""
    old = os.environ.get("TLM_KERNELS")
    os.environ["TLM_KERNELS"] = engine
    try:
        yield
    finally:
        if old is None:
            del os.environ["TLM_KERNELS"]
        else:
            os.environ["TLM_KERNELS"] = old


def engine_time(engine: str, fn, repeat: int) -> float:
    """Best time of ``fn`` with ``TLM_KERNELS=engine``."""
    with kernels(engine):
        fn()  # the first call of the compiled kernel loads it
        return best_of(fn, repeat)


def alternated(ours, theirs, repeat: int) -> tuple[float, float, float]:
    """``ours`` (tlm's compiled kernel) and ``theirs`` (Embree) timed one after the other,
    ``repeat`` times: the best time of each and the median of the per-round ratios
    ours / theirs (a machine that slows down for a while slows both of a round)."""
    with kernels("numba"):
        ours()  # the first call of the compiled kernel loads it
        theirs()
        a, b = [], []
        for _ in range(repeat):
            for fn, into in ((ours, a), (theirs, b)):
                t0 = time.perf_counter()
                fn()
                into.append(time.perf_counter() - t0)
    return min(a), min(b), float(np.median(np.array(a) / np.array(b)))


def per_ray(counts) -> tuple[float, float, float]:
    """tlm's mean work per ray: inner nodes entered, leaves tested, triangles tested."""
    return tuple(float(np.mean(c)) for c in (counts.node_visits, counts.leaf_visits, counts.tri_tests))


def bench_scene(name: str, repeat: int, levels: int | None = None) -> tuple[int, list[tuple]]:
    """The tree's levels, and per kind of ray: (kind, rays, tlm seconds, tlm-numpy seconds,
    Embree seconds, paired ratio tlm / Embree, tlm's work per ray (:func:`per_ray`)).
    ``levels``: the tree's depth (None: the thesis's rule)."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    scene = load_scene(name)
    accel = build_accel(scene.triangles, levels=levels)
    w, h = scene.camera.width, scene.camera.height
    o, d = primary_rays(scene.camera, np.arange(w * h))
    emb = rtcs.EmbreeScene()
    TriangleMesh(emb, scene.triangles.astype(np.float32))
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    emb.run(o32[:16], d32[:16])  # build Embree's BVH outside the timing
    hits = closest_hit(accel, o, d, shared_origin=True)
    def primary():
        return closest_hit(accel, o, d, shared_origin=True)

    ours, theirs, ratio = alternated(primary, lambda: emb.run(o32, d32), repeat)
    rows = [("primary", o.shape[0], ours, engine_time("numpy", primary, repeat), theirs, ratio, per_ray(hits.counts))]
    so, sd, sign, rel = shadow_rays(scene, accel, hits, o, d)
    # embreex's run() has no tnear: Embree's rays start at tmin and end at tmax
    so32 = (so + rel[:, None] * sd).astype(np.float32)
    sd32 = (sd * (1.0 - 2.0 * rel[:, None])).astype(np.float32)
    ones = np.ones(len(so32), np.float32)
    def shadow():
        return any_hit(accel, so, sd, tmin=rel, tmax=1.0 - rel, ignore=sign)

    ours, theirs, ratio = alternated(shadow, lambda: emb.run(so32, sd32, dists=ones, query="OCCLUDED"), repeat)
    rows.append(("shadow", so.shape[0], ours, engine_time("numpy", shadow, repeat), theirs, ratio,
                 per_ray(shadow().counts)))
    return accel.tree.levels, rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["cornell", "ring", "room"])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--levels", type=int, nargs="+", default=[],
                    help="also time trees of these depths (the bars: the thesis's rule only)")
    args = ap.parse_args()
    if args.repeat < 1:
        ap.error("--repeat must be >= 1")
    if any(not 0 <= v <= 24 for v in args.levels):
        ap.error("--levels must be between 0 and 24 (the BSP builder's range)")
    print(f"{'scene':8s} {'levels':>6s} {'rays':>8s} {'kind':8s} {'tlm Mrays/s':>12s} {'numpy Mrays/s':>14s} "
          f"{'embree Mrays/s':>15s} {'tlm/embree':>11s} {'paired':>8s} {'numpy/embree':>13s} "
          f"{'nodes/ray':>10s} {'leaves/ray':>11s} {'tests/ray':>10s}")
    verdicts = []
    for name, depth in ((name, depth) for name in args.scenes for depth in [None, *args.levels]):
        levels, rows = bench_scene(name, args.repeat, depth)
        for kind, n, t_ours, t_np, t_emb, ratio, (nodes, leaves, tests) in rows:
            print(f"{name:8s} {levels:6d} {n:8d} {kind:8s} {n / t_ours / 1e6:12.3f} {n / t_np / 1e6:14.3f} "
                  f"{n / t_emb / 1e6:15.3f} {'1/' + format(t_ours / t_emb, '.1f'):>11s} "
                  f"{'1/' + format(ratio, '.1f'):>8s} {'1/' + format(t_np / t_emb, '.1f'):>13s} "
                  f"{nodes:10.1f} {leaves:11.2f} {tests:10.1f}")
            if name == "cornell" and depth is None:
                for issue, bar in BARS:
                    verdicts.append((ratio <= bar, f"Cornell {kind} rays at 1/{ratio:.1f} of Embree's rate "
                                     f"(paired; bar of {issue}: at least 1/{bar:g})"))
    for ok, v in verdicts:
        verdict(ok, v)
    exit_status()


if __name__ == "__main__":
    main()
