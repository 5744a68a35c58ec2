"""Golden fingerprints: the images, work counts and cycles that a speed-up must not change.

``tests/data/golden.json`` holds, for a handful of small runs and kernel calls, a
SHA-256 of every radiance array and hit array (their exact bytes) and the integer work
counts and simulated cycles. It was written before the performance work of issue
[7 of 7] and is compared by ``tests/test_golden.py``: a faster kernel or timing model
must reproduce it bit for bit. Rewritten once since, when TThru became a steady-state
measure (``model.steady_throughput``): only the ``cycles.throughput`` entries changed
(the runs' streams are shorter than a steady window: their TThru is now the elapsed
cycles per frame). Rewritten a second time when the memory modules and the crossbar
became SimPy processes of their own: only the ``events`` entries changed (every cycle,
unit breakdown, image and count stayed the same). Rewritten a third time, for the ``run:``
entries only, by issue 17 (images a rendering researcher trusts): four jittered eye rays
per pixel, shading normals, glass split by Fresnel, index-matched glass letting shadow
rays through, caustic and indirect photon maps gathered also at the ends of the specular
paths; every ``kernel:`` entry (traversal, intersection, BSP) stayed the same. The runs
use the programs' scales of that time (:data:`SCALES`, with no cycles per record).
Rewritten a fourth time when the gather's cone weight became a work item of its own
(``photons_weighted``, h235): the photon-map runs' ``work.pmap`` gained it, and the disk
run's Fragment PM no longer pays the cone weight (its ``cycles`` and ``units`` fell);
images, photons, every other count and the cone filters' cycles stayed the same. Rewritten
a fifth time, for ``run:ring-pmap-kvoxel-dynamic`` alone and its timing alone (``cycles``,
``events``, ``units``), when a dynamic stream of two images came to run on until its
completions repeat (``tlm.arch.steady``): images and counts stayed the same. Rewritten a sixth
time, for that entry's ``cycles``, ``events`` and ``units`` alone, when a period came to be confirmed
over at least 12 gaps (h308): its stream runs longer, its ``cycles.throughput`` and ``latency`` stayed
the same. (The
AVX2 file was written on an AVX512 machine with ``NPY_DISABLE_CPU_FEATURES="X86_V4
AVX512_ICL"``, which reproduced the file of HEAD exactly first.)

Regenerate only when a change *means* to alter results (and say so in the commit)::

    python -m tests.golden --write      # from the repository's root
    python -m tests.golden              # print the differences against the file
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

from tlm.arch.costs import load_programs
from tlm.arch.model import simulate
from tlm.config import config_from_dict
from tlm.experiments.run import render
from tlm.kernels.traverse import any_hit, build_accel, closest_hit
from tlm.scenes.loader import load_scene

DATA = Path(__file__).resolve().parent / "data"


def math_class() -> str:
    """Which of numpy's float64 transcendental kernels this CPU runs.

    numpy computes ``sin``, ``cos``, ``exp``, ``log`` ... of float64 arrays with SVML
    where the CPU has AVX512_SKX and with the C library elsewhere; the two differ in the
    last bit, and sampled directions, photons and images follow. Traversal, intersection
    and the BSP use no such function: their ``kernel:`` entries are the same on both.
    """
    from numpy._core._multiarray_umath import __cpu_features__

    return "avx512" if __cpu_features__.get("AVX512_SKX") else "avx2"


# one file per class: the file written on an AVX512_SKX machine (before 2026-11-27 the
# only one) and the file for every other x86-64 or ARM CPU
GOLDEN = DATA / ("golden.json" if math_class() == "avx512" else f"golden.{math_class()}.json")
# The programs' scales the file was written with (the calibration of commit e0101eb): the
# golden runs use them whatever the packaged table holds, so a refit of the table (a
# deliberate change of the defaults) does not touch the fingerprints of the model.
SCALES = {"vertex": 7.44214, "traversal": 0.570522, "fragment": 2.57008}
# ... and its cycles per record (none then: the parameter came with the refit of 2026-11-25)
RECORD_CYCLES = {"vertex": 0.0, "traversal": 0.0, "fragment": 0.0}

# the search radii of the rule the file was written with (fractions of the scene's diagonal),
# pinned: the default became the density rule (estimate.radius_photons)
OLD_RADII = {"radius_fraction": 0.04, "caustic_radius_fraction": 0.01, "final_gather": 0}
# (and no final gathering, estimate.final_gather); the photon trees' depth of then, floor(ln n)
# (the default became photons.leaf_photons) and the caustic group aimed at one box (photons.aim)
OLD_TREE = {"leaf_photons": None, "aim": "box"}
# runs: every frame kind, every gather filter, the three scenes, N and the schedulers
RUNS = {
    "cornell-pmap-mvoxel": {"scene": "cornell", "mode": "pmap", "resolution": [48, 48],
                            "photons": {"count": 4000, **OLD_TREE}, "estimate": OLD_RADII,
                            "arch": {"frames": 2, "packet_size": 64, "trace": False}},
    "cornell-pmap-disk-n4": {"scene": "cornell", "mode": "pmap", "resolution": [32, 32],
                             "photons": {"count": 3000, **OLD_TREE}, "estimate": {"filter": "disk", **OLD_RADII},
                             "arch": {"frames": 3, "pipelines": 4, "trace": False}},
    "ring-pmap-kvoxel-dynamic": {"scene": "ring", "mode": "pmap", "resolution": [40, 30],
                                 "photons": {"count": 3000, **OLD_TREE}, "estimate": {"filter": "kvoxel", **OLD_RADII},
                                 "arch": {"frames": 2, "pipelines": 3, "scheduler": "dynamic",
                                          "packet_size": 32, "trace": False}},
    "room-pmap-knn": {"scene": "room", "mode": "pmap", "resolution": [32, 24],
                      "photons": {"count": 3000, **OLD_TREE}, "estimate": {"filter": "knn", **OLD_RADII},
                      "arch": {"frames": 2, "trace": False}},
    "room-refract": {"scene": "room", "mode": "refract", "resolution": [64, 48],
                     "arch": {"frames": 4, "packet_size": 128, "trace": False}},
    "cornell-refract-1": {"scene": "cornell", "mode": "refract", "resolution": [40, 40],
                          "arch": {"frames": 2, "packet_size": 1, "trace": False}},
}
# kernel calls on random rays: general origins (not the eye's), finite tmax, ignore
KERNEL_SCENES = ("cornell", "room", "ring")
KERNEL_RAYS = 6000


def digest(a: np.ndarray) -> str:
    a = np.ascontiguousarray(a)
    h = hashlib.sha256(f"{a.dtype.str}{a.shape}".encode())
    h.update(a.tobytes())
    return h.hexdigest()[:20]


def _ints(d: dict) -> dict:
    """The integer entries of a (nested) stats dict: cycles and counts, not fractions."""
    out = {}
    for k, v in sorted(d.items()):
        if isinstance(v, dict):
            sub = _ints(v)
            if sub:  # (a dict of fractions only has no integer entries)
                out[k] = sub
        elif isinstance(v, (int, np.integer)) and not isinstance(v, bool):
            out[k] = int(v)
    return out


def _run(raw: dict) -> dict:
    cfg = config_from_dict({"seed": 0, **raw})
    res = render(cfg)
    tm = simulate(res.functional(), load_programs().with_scales(SCALES, RECORD_CYCLES), cfg.arch)
    out = {
        "radiance": {name: digest(rad) for name, rad in sorted(res.radiance.items())},
        "work": {name: {k: int(v.sum()) for k, v in sorted(wk.items())} for name, wk in sorted(res.work.items())},
        "cycles": {k: int(v) for k, v in sorted(tm.cycles.items())},
        "events": int(tm.events),
        "units": {name: _ints(u) for name, u in sorted(tm.units.items())},
    }
    if res.photons is not None:  # both maps: the caustic one, then the indirect one
        maps = zip(("caustic", "indirect"), res.photons.photons.maps, strict=True)
        out["photons"] = {f"{which}.{k}": digest(v) for which, m in maps
                          for k, v in sorted(vars(m).items()) if isinstance(v, np.ndarray)}
    return out


def _rays(scene, n: int, seed: int):
    rng = np.random.default_rng(seed)
    tri = scene.triangles.reshape(-1, 3, 3)
    lo, hi = tri.reshape(-1, 3).min(axis=0), tri.reshape(-1, 3).max(axis=0)
    o = lo + rng.random((n, 3)) * (hi - lo)
    # aim at random points on random triangles, so most rays hit
    pick = rng.integers(0, tri.shape[0], n)
    b = rng.dirichlet([1.0, 1.0, 1.0], n)
    target = np.einsum("nk,nkj->nj", b, tri[pick])
    d = target - o
    d[::7] *= -1.0  # and some away from them
    tmax = np.where(np.arange(n) % 3 == 0, 0.999, np.inf)
    ignore = np.where(np.arange(n) % 5 == 0, pick, -1)
    return o, d, tmax, ignore


def _kernel(name: str) -> dict:
    scene = load_scene(name, None, None, None)
    accel = build_accel(scene.triangles)
    o, d, tmax, ignore = _rays(scene, KERNEL_RAYS, seed=len(name))
    h = closest_hit(accel, o, d, tmin=1e-6, tmax=tmax, ignore=ignore, record=True)
    s = any_hit(accel, o, d, tmin=1e-6, tmax=tmax, ignore=ignore, record=True)
    out = {"tree": {"items": digest(accel.tree.items), "split": digest(accel.tree.split)}}
    for kind, r in (("closest", h), ("any", s)):
        arrays = {"occluded": s.occluded} if kind == "any" else {"t": h.t, "triangle": h.triangle, "u": h.u, "v": h.v}
        arrays.update({f"counts.{k}": v for k, v in vars(r.counts).items()})
        arrays.update({f"touched.{k}": v for k, v in vars(r.touched).items()})
        out[kind] = {k: digest(v) for k, v in sorted(arrays.items())}
    return out


def compute(names: list[str] | None = None) -> dict:
    out = {}
    for name, raw in RUNS.items():
        if names is None or name in names:
            out[f"run:{name}"] = _run(raw)
    for name in KERNEL_SCENES:
        if names is None or f"kernel:{name}" in names:
            out[f"kernel:{name}"] = _kernel(name)
    return out


def load() -> dict:
    return json.loads(GOLDEN.read_text())


def differences(a, b, path: str = "") -> list[str]:
    """Where two fingerprints differ, as dotted paths."""
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                out.append(f"{path}{k}: {'missing' if k not in b else 'new'}")
            else:
                out.extend(differences(a[k], b[k], f"{path}{k}."))
        return out
    return [] if a == b else [f"{path.rstrip('.')}: {a!r} -> {b!r}"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--write", action="store_true", help="overwrite this CPU class's golden file")
    args = ap.parse_args(argv)
    now = compute()
    if args.write:
        GOLDEN.parent.mkdir(exist_ok=True)
        GOLDEN.write_text(json.dumps(now, indent=1, sort_keys=True) + "\n")
        print(f"wrote {GOLDEN}")
        return 0
    diff = differences(load(), now)
    print(f"{GOLDEN.name} ({math_class()})")
    print("\n".join(diff) if diff else "identical")
    return 1 if diff else 0


if __name__ == "__main__":
    sys.exit(main())
