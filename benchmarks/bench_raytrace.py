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

    python benchmarks/bench_raytrace.py [--scenes cornell ring room] [--repeat 5]
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


def bench_scene(name: str, repeat: int) -> list[tuple[str, int, float, float, float, float]]:
    """(kind, rays, tlm seconds, tlm-numpy seconds, Embree seconds, paired ratio tlm / Embree)
    per kind of ray."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    scene = load_scene(name)
    accel = build_accel(scene.triangles)
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
    rows = [("primary", o.shape[0], ours, engine_time("numpy", primary, repeat), theirs, ratio)]
    so, sd, sign, rel = shadow_rays(scene, accel, hits, o, d)
    # embreex's run() has no tnear: Embree's rays start at tmin and end at tmax
    so32 = (so + rel[:, None] * sd).astype(np.float32)
    sd32 = (sd * (1.0 - 2.0 * rel[:, None])).astype(np.float32)
    ones = np.ones(len(so32), np.float32)
    def shadow():
        return any_hit(accel, so, sd, tmin=rel, tmax=1.0 - rel, ignore=sign)

    ours, theirs, ratio = alternated(shadow, lambda: emb.run(so32, sd32, dists=ones, query="OCCLUDED"), repeat)
    rows.append(("shadow", so.shape[0], ours, engine_time("numpy", shadow, repeat), theirs, ratio))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["cornell", "ring", "room"])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    if args.repeat < 1:
        ap.error("--repeat must be >= 1")
    print(f"{'scene':8s} {'rays':>8s} {'kind':8s} {'tlm Mrays/s':>12s} {'numpy Mrays/s':>14s} "
          f"{'embree Mrays/s':>15s} {'tlm/embree':>11s} {'paired':>8s} {'numpy/embree':>13s}")
    verdicts = []
    for name in args.scenes:
        for kind, n, t_ours, t_np, t_emb, ratio in bench_scene(name, args.repeat):
            print(f"{name:8s} {n:8d} {kind:8s} {n / t_ours / 1e6:12.3f} {n / t_np / 1e6:14.3f} "
                  f"{n / t_emb / 1e6:15.3f} {'1/' + format(t_ours / t_emb, '.1f'):>11s} "
                  f"{'1/' + format(ratio, '.1f'):>8s} {'1/' + format(t_np / t_emb, '.1f'):>13s}")
            if name == "cornell":
                for issue, bar in BARS:
                    verdicts.append((ratio <= bar, f"Cornell {kind} rays at 1/{ratio:.1f} of Embree's rate "
                                     f"(paired; bar of {issue}: at least 1/{bar:g})"))
    for ok, v in verdicts:
        verdict(ok, v)
    exit_status()


if __name__ == "__main__":
    main()
