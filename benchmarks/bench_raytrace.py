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

The *walk floor*: in every round the compiled kernel also traces the same rays on the
same tree with every leaf emptied (:func:`free_leaves`): the root clip, the walk that
lists the crossed leaves, the float32 range checks of each ray and the Python around
the kernel, with leaf tests that cost nothing. As no ray hits anything there, the floor
also leaves out the float64 check of each hit (and, for eye rays, the stop at the leaf
of the closest hit, so it goes through every crossed leaf's empty loop). Its paired
ratio against Embree is the best any faster leaf test could reach on this tree; for
Cornell the bench prints what the bar of 1/2 leaves the leaf tests and the check of
their hits (twice Embree's time less the floor) against what they take now (the
kernel's time less the floor), both from the round of the median paired ratio (the one
the verdict reads, with an odd ``--repeat``). The ``spread`` columns are each engine's
median round over its best: how far the machine's speed moved under each.

    python benchmarks/bench_raytrace.py [--scenes cornell ring room] [--repeat 5] [--levels 8 10]
"""

from __future__ import annotations

import argparse
import copy
import dataclasses
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


def free_leaves(accel):
    """A copy of ``accel`` whose compiled layout has every leaf empty: the same tree,
    root box and splits, so the compiled kernel clips, walks and lists the same leaves
    in the same order with the same intervals, but tests no triangle (a ray hits
    nothing, and every ray walks its whole length, as every ray's walk does before its
    first leaf test). ``accel`` itself is not changed."""
    lay = accel.jit_layout
    empty = copy.copy(accel)  # (a new instance dict: the cached layout is replaced in the copy only)
    empty.__dict__["jit_layout"] = dataclasses.replace(lay, last=lay.first.copy(), size=np.zeros_like(lay.size))
    return empty


@dataclasses.dataclass(frozen=True)
class Paired:
    """One kind of ray timed ``repeat`` rounds: per round tlm's compiled kernel, the same
    kernel on the emptied leaves (:func:`free_leaves`) and Embree, one after the other."""

    ours: np.ndarray
    floor: np.ndarray
    theirs: np.ndarray

    def ratio(self, times: np.ndarray) -> float:
        """The median of the rounds' ratios ``times`` / Embree's."""
        return float(np.median(times / self.theirs))

    def spread(self, times: np.ndarray) -> float:
        """The median round over the best one: how much the machine's speed moved."""
        return float(np.median(times) / times.min())

    def median_round(self) -> int:
        """The round of the median paired ratio (of the upper two for an even count)."""
        return int(np.argsort(self.ours / self.theirs, kind="stable")[self.ours.shape[0] // 2])

    def leaf_seconds(self) -> float:
        """What the leaf tests and the check of their hits take: the kernel's time less
        the floor, in the round of the median paired ratio."""
        k = self.median_round()
        return float(self.ours[k] - self.floor[k])

    def leaf_budget(self, bar: float) -> float:
        """What a paired ratio of ``1/bar`` leaves the leaf tests and the check of their
        hits: ``bar`` times Embree's time less the floor, in the same round (negative:
        the walk alone misses the bar). Below :meth:`leaf_seconds` exactly when that
        round's ratio misses the bar."""
        k = self.median_round()
        return float(bar * self.theirs[k] - self.floor[k])


def alternated(ours, floor, theirs, repeat: int) -> tuple[Paired, object]:
    """``ours`` (tlm's compiled kernel), ``floor`` (the same on emptied leaves) and
    ``theirs`` (Embree) timed one after the other, ``repeat`` rounds (a machine that
    slows down for a while slows all three of a round). Returns the :class:`Paired`
    times and what the untimed first call of ``ours`` returned (the rays' hits and
    counts: every call of it traces the same rays to the same result)."""
    fns = (ours, floor, theirs)
    times = [[] for _ in fns]
    with kernels("numba"):
        first = [fn() for fn in fns]  # the first call of the compiled kernel loads it
        for _ in range(repeat):
            for fn, into in zip(fns, times, strict=True):
                t0 = time.perf_counter()
                fn()
                into.append(time.perf_counter() - t0)
    return Paired(*(np.array(t) for t in times)), first[0]


def per_ray(counts) -> tuple[float, float, float]:
    """tlm's mean work per ray: inner nodes entered, leaves tested, triangles tested."""
    return tuple(float(np.mean(c)) for c in (counts.node_visits, counts.leaf_visits, counts.tri_tests))


def bench_scene(name: str, repeat: int, levels: int | None = None) -> tuple[int, list[tuple]]:
    """The tree's levels, and per kind of ray: (kind, rays, :class:`Paired` times,
    tlm-numpy seconds, tlm's work per ray (:func:`per_ray`)). ``levels``: the tree's
    depth (None: the thesis's rule)."""
    from embreex import rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    scene = load_scene(name)
    accel = build_accel(scene.triangles, levels=levels)
    walk = free_leaves(accel)
    w, h = scene.camera.width, scene.camera.height
    o, d = primary_rays(scene.camera, np.arange(w * h))
    emb = rtcs.EmbreeScene()
    TriangleMesh(emb, scene.triangles.astype(np.float32))
    o32, d32 = o.astype(np.float32), d.astype(np.float32)
    emb.run(o32[:16], d32[:16])  # build Embree's BVH outside the timing
    def primary():
        return closest_hit(accel, o, d, shared_origin=True)

    # (the eye rays' hits, which the shadow rays start from, and their counts: the untimed first call's)
    times, hits = alternated(primary, lambda: closest_hit(walk, o, d, shared_origin=True),
                             lambda: emb.run(o32, d32), repeat)
    rows = [("primary", o.shape[0], times, engine_time("numpy", primary, repeat), per_ray(hits.counts))]
    so, sd, sign, rel = shadow_rays(scene, accel, hits, o, d)
    # embreex's run() has no tnear: Embree's rays start at tmin and end at tmax
    so32 = (so + rel[:, None] * sd).astype(np.float32)
    sd32 = (sd * (1.0 - 2.0 * rel[:, None])).astype(np.float32)
    ones = np.ones(len(so32), np.float32)
    def shadow():
        return any_hit(accel, so, sd, tmin=rel, tmax=1.0 - rel, ignore=sign)

    times, occluded = alternated(shadow, lambda: any_hit(walk, so, sd, tmin=rel, tmax=1.0 - rel, ignore=sign),
                                 lambda: emb.run(so32, sd32, dists=ones, query="OCCLUDED"), repeat)
    rows.append(("shadow", so.shape[0], times, engine_time("numpy", shadow, repeat), per_ray(occluded.counts)))
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
          f"{'embree Mrays/s':>15s} {'tlm/embree':>11s} {'paired':>8s} {'walk floor':>11s} {'numpy/embree':>13s} "
          f"{'nodes/ray':>10s} {'leaves/ray':>11s} {'tests/ray':>10s} {'spread tlm':>11s} {'spread embree':>14s}")
    verdicts, budgets = [], []
    for name, depth in ((name, depth) for name in args.scenes for depth in [None, *args.levels]):
        levels, rows = bench_scene(name, args.repeat, depth)
        for kind, n, times, t_np, (nodes, leaves, tests) in rows:
            t_ours, t_emb = times.ours.min(), times.theirs.min()
            ratio = times.ratio(times.ours)
            print(f"{name:8s} {levels:6d} {n:8d} {kind:8s} {n / t_ours / 1e6:12.3f} {n / t_np / 1e6:14.3f} "
                  f"{n / t_emb / 1e6:15.3f} {'1/' + format(t_ours / t_emb, '.1f'):>11s} "
                  f"{'1/' + format(ratio, '.1f'):>8s} {'1/' + format(times.ratio(times.floor), '.1f'):>11s} "
                  f"{'1/' + format(t_np / t_emb, '.1f'):>13s} {nodes:10.1f} {leaves:11.2f} {tests:10.1f} "
                  f"{times.spread(times.ours):11.2f} {times.spread(times.theirs):14.2f}")
            if name == "cornell" and depth is None:
                for issue, bar in BARS:
                    verdicts.append((ratio <= bar, f"Cornell {kind} rays at 1/{ratio:.1f} of Embree's rate "
                                     f"(paired; bar of {issue}: at least 1/{bar:g})"))
                budgets.append(budget_line(kind, n, times, tests, BARS[-1][1]))
    if budgets:
        print("\nThe walk floor: the same kernel on the same tree with every leaf emptied, paired against Embree "
              "(the round of the median paired ratio).")
        for line in budgets:
            print(line)
    for ok, v in verdicts:
        verdict(ok, v)
    exit_status()


def budget_line(kind: str, n: int, times: Paired, tests: float, bar: float) -> str:
    """What the bar of ``1/bar`` leaves the leaf tests (and the check of their hits) of
    Cornell's ``kind`` rays, against what they take, in the round of the median paired
    ratio; per ray and per triangle test."""
    have, left = times.leaf_seconds(), times.leaf_budget(bar)
    now = (f"the leaf tests and the check of their hits take {have * 1e3:.2f} ms of the {n:,} rays "
           f"({have / n * 1e9:.0f} ns a ray, {have / (n * tests) * 1e9:.2f} ns a triangle test)")
    if left <= 0:
        k = times.median_round()
        return (f"Cornell {kind} rays: the walk alone is at 1/{times.floor[k] / times.theirs[k]:.1f} of Embree in that "
                f"round; the bar of 1/{bar:g} leaves the leaf tests nothing; {now}")
    return (f"Cornell {kind} rays: the bar of 1/{bar:g} leaves the leaf tests and the check of their hits "
            f"{left * 1e3:.2f} ms ({left / n * 1e9:.0f} ns a ray, {left / (n * tests) * 1e9:.2f} ns a triangle "
            f"test); {now}: {have / left:.2f}x their budget")


if __name__ == "__main__":
    main()
