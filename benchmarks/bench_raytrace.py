"""Rays per second of tlm's BSP kernels against Embree (embreex), in the same run.

For each built-in scene: the primary rays of the whole image (closest hit) and one
shadow ray per Lambertian primary hit towards the centre of every light (any hit).
Both engines trace the same rays; each timing is the best of ``--repeat`` runs, one
thread each (Embree's ``run`` traces the rays one after another on the calling
thread). Prints a table and the ratio tlm / Embree; the bar of issue [1 of 7] is a
primary-ray ratio of at least 1/20 on Cornell (the project goal: 1/10).

    python benchmarks/bench_raytrace.py [--scenes cornell ring room] [--repeat 5]
"""

from __future__ import annotations

import argparse

import numpy as np
from timing import best_of

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


def bench_scene(name: str, repeat: int) -> list[tuple[str, int, float, float]]:
    """(kind, rays, tlm seconds, Embree seconds) for the primary and the shadow rays."""
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
    rows = [(
        "primary", o.shape[0],
        best_of(lambda: closest_hit(accel, o, d, shared_origin=True), repeat),
        best_of(lambda: emb.run(o32, d32), repeat),
    )]
    so, sd, sign, rel = shadow_rays(scene, accel, hits, o, d)
    # embreex's run() has no tnear: Embree's rays start at tmin and end at tmax
    so32 = (so + rel[:, None] * sd).astype(np.float32)
    sd32 = (sd * (1.0 - 2.0 * rel[:, None])).astype(np.float32)
    ones = np.ones(len(so32), np.float32)
    rows.append((
        "shadow", so.shape[0],
        best_of(lambda: any_hit(accel, so, sd, tmin=rel, tmax=1.0 - rel, ignore=sign), repeat),
        best_of(lambda: emb.run(so32, sd32, dists=ones, query="OCCLUDED"), repeat),
    ))
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["cornell", "ring", "room"])
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    print(f"{'scene':8s} {'rays':>8s} {'kind':8s} {'tlm Mrays/s':>12s} {'embree Mrays/s':>15s} {'ratio':>9s}")
    for name in args.scenes:
        for kind, n, t_ours, t_emb in bench_scene(name, args.repeat):
            print(f"{name:8s} {n:8d} {kind:8s} {n / t_ours / 1e6:12.3f} {n / t_emb / 1e6:15.3f} "
                  f"1/{t_ours / t_emb:6.1f}")


if __name__ == "__main__":
    main()
