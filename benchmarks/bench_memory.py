"""Peak resident memory of whole runs: the Cornell photon-map frame, a 69k-triangle glass mesh, 1M triangles at 1080p.

**Cornell** (issue [7 of 7]): ``tlm run configs/cornell_pmap.yaml`` (320 x 320 pixels,
120,000 photons, all four passes, the timing model and the report), once as is and once
with ``--no-report``. Bar: at most 2 GiB.

**Large scene** (issue 18): a mesh file of about 1M triangles (the Cornell box's walls,
blocks and mirror sphere from the ``cornell`` builder, and in place of the glass sphere
a bumpy glass blob tessellated procedurally into a latitude-longitude grid; written as
an OBJ file with one object per part into a temporary folder and loaded by ``tlm``'s
mesh loader) rendered at 1920 x 1080 in the RCast and Refract modes with the default
outputs (images, radiance, AOVs, trace). Bar: at most 4 GiB each. The same scene with
a blob of about 20k triangles is the reference measured in the same run: the wall time
ratio 1M / 20k, against the triangle ratio (the aim: less than linear growth). Bars
(issue 25): the Refract run at most 2 GiB; the RCast run, the reference measured in the
same run, at most 4 GiB (issue 18).

**Glass** (issue 25): the same Cornell box with a glass blob of 69,120 triangles (a
subdivided sphere, 70,500 triangles in all) at 320 x 320 in the pmap mode (every pass,
the scene's 120,000 photons; ``--no-reference``: no photon-map reference is computed),
beside the same scene in the RCast mode as the reference.
Bar: the pmap run at most 1 GiB.

**Depth** (``--quick``, what ``tests/test_walk_memory.py`` runs): the refract pass of a
small glass scene (a 2,400-triangle blob, 48 x 48 pixels, one sample each, every Fresnel
branch traced: ``render.min_weight`` 0) at two specular depths, 4 and 32, with
``render.batch_rays`` 512, each in a fresh interpreter: the pass's peak of
``tracemalloc``'s traced memory less the walk's ends and lights seen (its output, which
the photon-map pass gathers at: per-batch state that grows with the rays that end).
Bar: the deep walk, which traces several times the rays, peaks at most 1.5 x the shallow
one (memory bounded by the batch, whatever the depth).

Each run is ``python -m tlm run`` in a fresh interpreter (``--no-progress``), one after
another; its peak RSS is the kernel's (``os.wait4``'s ``ru_maxrss``), its wall time the
parent's clock. Exits 1 if a bar fails.

    python benchmarks/bench_memory.py [--config configs/cornell_pmap.yaml] [--set KEY=VALUE ...]
    python benchmarks/bench_memory.py --only glass
    python benchmarks/bench_memory.py --only large [--spp 1 4] [--modes rcast refract]
    python benchmarks/bench_memory.py --quick
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from timing import exit_status, verdict

BAR_BYTES = 2 * 1024**3
LARGE_BAR_BYTES = {"rcast": 4 * 1024**3, "refract": 2 * 1024**3}  # issue 18's, issue 25's
GLASS_BAR_BYTES = 1024**3
GLASS = (240, 145)  # 2 * 240 * 144 = 69,120 triangles
GLASS_RESOLUTION = [320, 320]
QUICK = (40, 31)  # 2 * 40 * 30 = 2,400 triangles
QUICK_DEPTHS = (4, 32)
QUICK_BATCH_RAYS = 512
QUICK_RATIO = 1.5
ROOT = Path(__file__).resolve().parents[1]
LARGE = (1000, 501)  # blob meridians, latitude bands: 2 * 1000 * 500 = 1,000,000 triangles
SMALL = (100, 101)  # 2 * 100 * 100 = 20,000 triangles
RESOLUTION = [1920, 1080]


def peak_rss(cmd: list[str], env: dict) -> tuple[int, float]:
    """Peak RSS in bytes (Linux reports kilobytes) and wall seconds of ``cmd``."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, cwd=ROOT, stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} exited with {proc.returncode}")
    return usage.ru_maxrss * 1024, wall


def blob(n_seg: int, n_rings: int, center=(400.0, 112.0, 130.0), radius: float = 100.0,
         bumps: float = 0.06) -> tuple[np.ndarray, np.ndarray]:
    """A bumpy sphere on a latitude-longitude grid with welded vertices, pole fans
    included: ``2 * n_seg * (n_rings - 1)`` triangles, outward winding."""
    phi = np.pi * np.arange(1, n_rings) / n_rings
    theta = 2.0 * np.pi * np.arange(n_seg) / n_seg
    p, t = np.meshgrid(phi, theta, indexing="ij")
    r = radius * (1.0 + bumps * np.sin(7.0 * p) * np.sin(9.0 * t))
    ring = np.stack([r * np.sin(p) * np.cos(t), -r * np.cos(p), r * np.sin(p) * np.sin(t)], axis=-1)
    vertices = np.vstack([[0.0, -radius, 0.0], ring.reshape(-1, 3), [0.0, radius, 0.0]]) + center
    k = np.arange(n_seg)
    faces = [np.stack([np.zeros(n_seg, dtype=np.int64), 1 + (k + 1) % n_seg, 1 + k], axis=1)]
    for i in range(n_rings - 2):
        a, b = 1 + i * n_seg + k, 1 + (i + 1) * n_seg + k
        a1, b1 = 1 + i * n_seg + (k + 1) % n_seg, 1 + (i + 1) * n_seg + (k + 1) % n_seg
        faces += [np.stack([a, a1, b1], axis=1), np.stack([a, b1, b], axis=1)]
    last = 1 + (n_rings - 2) * n_seg
    faces.append(np.stack([last + k, last + (k + 1) % n_seg, np.full(n_seg, vertices.shape[0] - 1)], axis=1))
    return vertices, np.concatenate(faces)


def write_scene(folder: Path, name: str, n_seg: int, n_rings: int, resolution=RESOLUTION) -> tuple[Path, int]:
    """The Cornell box with a glass blob of ``2 n_seg (n_rings - 1)`` triangles as an OBJ
    mesh and a scene file naming it; returns the scene file and its triangle count."""
    from tlm.scenes.builders import cornell
    from tlm.scenes.loader import scenes_dir

    geom = cornell()
    lines, offset, n = [], 1, 0
    for i, part in enumerate(geom.part_names):
        if part == "glass_object":
            v, f = blob(n_seg, n_rings)
        else:
            v = geom.triangles[geom.part == i].reshape(-1, 3)
            f = np.arange(v.shape[0]).reshape(-1, 3)
        lines.append(f"o {part}")
        lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v.tolist()]
        lines += [f"f {a} {b} {c}" for a, b, c in (f + offset).tolist()]
        offset += v.shape[0]
        n += f.shape[0]
    (folder / f"{name}.obj").write_text("\n".join(lines) + "\n")
    raw = yaml.safe_load((scenes_dir() / "cornell.yaml").read_text())
    raw.update(name=name, description=f"Cornell box with a {n}-triangle glass blob", geometry={"mesh": f"{name}.obj"},
               resolution=list(resolution))
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path, n


def cornell_check(args, sets: list[str]) -> None:
    rows = []
    for label, extra in (("tlm run (with its report)", []), ("tlm run --no-report", ["--no-report"])):
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, TLM_CACHE=str(Path(tmp) / "cache"))
            cmd = [sys.executable, "-m", "tlm", "run", str(args.config), "--out", str(Path(tmp) / "run"),
                   "--no-progress", *sets, *extra]
            rows.append((label, *peak_rss(cmd, env)))
    print(f"{args.config.name}{' ' + ' '.join(args.set) if args.set else ''}:")
    for label, rss, wall in rows:
        print(f"  {label:28s} peak RSS {rss / 2**20:8.0f} MiB   {wall:6.1f} s wall")
    worst = max(r[1] for r in rows)
    verdict(worst <= BAR_BYTES, f"peak resident memory {worst / 2**20:.0f} MiB "
            f"(bar: at most {BAR_BYTES / 2**30:.0f} GiB)")


def large_check(args, sets: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        env = dict(os.environ, TLM_CACHE=str(folder / "cache"))
        scenes = {label: write_scene(folder, label, *grid) for label, grid in (("large", LARGE), ("small", SMALL))}
        n_large, n_small = scenes["large"][1], scenes["small"][1]
        print(f"large scene: {n_large:,} and {n_small:,} triangles (the mesh of the Cornell box with a glass blob), "
              f"{RESOLUTION[0]}x{RESOLUTION[1]}, default outputs, one run at a time")
        print(f"{'spp':>3s} {'mode':8s} {'triangles':>10s} {'peak RSS':>12s} {'wall':>9s}")
        for spp in args.spp:
            for mode in args.modes:
                measured = {}
                for label in ("small", "large"):
                    scene, n = scenes[label]
                    config = folder / f"{label}_{mode}_{spp}.yaml"
                    config.write_text(yaml.safe_dump({"scene": str(scene), "mode": mode, "render": {"spp": spp}}))
                    cmd = [sys.executable, "-m", "tlm", "run", str(config), "--out", str(folder / "run"),
                           "--no-report", "--no-progress", *sets]
                    rss, wall = peak_rss(cmd, env)
                    shutil.rmtree(folder / "run")
                    measured[label] = (rss, wall)
                    print(f"{spp:3d} {mode:8s} {n:>10,d} {rss / 2**20:8.0f} MiB {wall:7.1f} s", flush=True)
                (rss, wall), (_, wall_small) = measured["large"], measured["small"]
                bar = LARGE_BAR_BYTES[mode]
                verdict(rss <= bar, f"spp {spp} {mode}: peak resident memory {rss / 2**20:.0f} MiB "
                        f"at {n_large:,} triangles (bar: at most {bar / 2**30:.0f} GiB)", "  ")
                ratio, tri_ratio = wall / wall_small, n_large / n_small
                print(f"  spp {spp} {mode}: wall time {ratio:.2f}x for {tri_ratio:.1f}x the triangles "
                      f"({'less than' if ratio < tri_ratio else 'NOT less than'} linear)")


def glass_check(args, sets: list[str]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        env = dict(os.environ, TLM_CACHE=str(folder / "cache"))
        scene, n = write_scene(folder, "glass", *GLASS, resolution=GLASS_RESOLUTION)
        print(f"glass scene: the Cornell box with a {2 * GLASS[0] * (GLASS[1] - 1):,}-triangle glass blob "
              f"({n:,} triangles), {GLASS_RESOLUTION[0]}x{GLASS_RESOLUTION[1]}, one run at a time")
        measured = {}
        for mode in ("rcast", "pmap"):
            config = folder / f"glass_{mode}.yaml"
            config.write_text(yaml.safe_dump({"scene": str(scene), "mode": mode}))
            cmd = [sys.executable, "-m", "tlm", "run", str(config), "--out", str(folder / "run"), "--no-report",
                   "--no-progress", "--no-reference", *sets]  # (the render, not a reference's hundred rounds)
            measured[mode] = peak_rss(cmd, env)
            shutil.rmtree(folder / "run")
            print(f"  {mode:8s} peak RSS {measured[mode][0] / 2**20:8.0f} MiB   {measured[mode][1]:6.1f} s wall"
                  f"{'   (the reference)' if mode == 'rcast' else ''}", flush=True)
        rss = measured["pmap"][0]
        verdict(rss <= GLASS_BAR_BYTES, f"pmap: peak resident memory {rss / 2**20:.0f} MiB at {n:,} triangles, "
                f"{rss / measured['rcast'][0]:.2f}x the RCast run's (bar: at most {GLASS_BAR_BYTES / 2**30:.0f} GiB)",
                "  ")


def walk_peak(scene: Path, depth: int) -> None:
    """(In a fresh interpreter) the refract pass of ``scene`` at ``depth``: prints its traced
    peak less the walk's output, the rays it traced and that output's bytes."""
    import tracemalloc

    from tlm.config import config_from_dict
    from tlm.kernels.traverse import build_accel
    from tlm.render import frame as render_frame
    from tlm.render import passes, walk
    from tlm.scenes.loader import load_scene

    sc = load_scene(str(scene))
    cfg = config_from_dict({"resolution": [sc.camera.width, sc.camera.height], "mode": "refract",
                            "render": {"spp": 1, "refract_depth": depth, "min_weight": 0.0,
                                       "batch_rays": QUICK_BATCH_RAYS}})
    frame = render_frame.Frame.create(sc, build_accel(sc.triangles), cfg)
    g = render_frame.cast(frame, np.arange(sc.camera.width * sc.camera.height))
    passes.refract_pass(frame, render_frame.cast(frame, np.arange(4)))  # compile and warm what the pass runs
    tracemalloc.start()
    base = tracemalloc.get_traced_memory()[0]
    _, work = passes.refract_pass(frame, g)
    peak = tracemalloc.get_traced_memory()[1] - base
    tracemalloc.stop()
    out = sum(a.nbytes for w in g.memo.values() if isinstance(w, walk.Walk)
              for a in (w.emitted_sample, w.emitted_radiance, *vars(w.ends).values()))
    print(peak - out, int(work["secondary_rays"].sum()), out)


def quick_check(args) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        scene, _ = write_scene(Path(tmp), "quick", *QUICK, resolution=(48, 48))
        print(f"depth: the refract pass of the Cornell box with a {2 * QUICK[0] * (QUICK[1] - 1):,}-triangle glass "
              f"blob, 48x48, 1 spp, render.min_weight 0, render.batch_rays {QUICK_BATCH_RAYS}")
        rows = {}
        for depth in QUICK_DEPTHS:
            out = subprocess.run([sys.executable, __file__, "--walk-peak", str(scene), str(depth)], cwd=ROOT,
                                 check=True, capture_output=True, text=True).stdout.split()
            peak, rays, kept = (int(x) for x in out[-3:])
            rows[depth] = (peak, rays)
            print(f"  refract_depth {depth:3d}: {rays:8,d} rays traced, peak {peak / 2**20:7.2f} MiB "
                  f"(the walk's ends, {kept / 2**20:.2f} MiB, left out)", flush=True)
    (p0, r0), (p1, r1) = rows[QUICK_DEPTHS[0]], rows[QUICK_DEPTHS[1]]
    verdict(r1 >= 4 * r0, f"the deep walk traces {r1 / r0:.1f}x the rays of the shallow one (at least 4x: a real test)",
            "  ")
    verdict(p1 <= QUICK_RATIO * p0, f"the deep walk peaks at {p1 / p0:.2f}x the shallow one's memory "
            f"(bar: at most {QUICK_RATIO}x)", "  ")


def main() -> None:
    if sys.argv[1:2] == ["--walk-peak"]:
        sys.path.insert(0, str(ROOT))
        walk_peak(Path(sys.argv[2]), int(sys.argv[3]))
        return
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "cornell_pmap.yaml",
                    help="the Cornell check's config")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="passed to every tlm run")
    ap.add_argument("--only", choices=["cornell", "glass", "large"], nargs="+",
                    help="only these checks (default: all three)")
    ap.add_argument("--large-only", action="store_true", help="only the 1M-triangle 1080p runs (--only large)")
    ap.add_argument("--quick", action="store_true",
                    help="only the depth check: a small glass walk's memory at two depths (seconds)")
    ap.add_argument("--spp", type=int, nargs="+", default=[1],
                    help="eye rays per pixel of the large runs (default: 1, the thesis's ray casting)")
    ap.add_argument("--modes", nargs="+", default=["rcast", "refract"], choices=["rcast", "refract"],
                    help="modes of the large runs")
    args = ap.parse_args()
    sets = [a for kv in args.set for a in ("--set", kv)]
    if args.quick:
        quick_check(args)
        exit_status()
    only = set(args.only or (["large"] if args.large_only else ["cornell", "glass", "large"]))
    if "cornell" in only:
        cornell_check(args, sets)
    if "glass" in only:
        glass_check(args, sets)
    if "large" in only:
        large_check(args, sets)
    exit_status()


if __name__ == "__main__":
    main()
