"""Peak resident memory of whole runs: the Cornell photon-map frame and a 1M-triangle mesh at 1080p.

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
ratio 1M / 20k, against the triangle ratio (the aim: less than linear growth).

Each run is ``python -m tlm run`` in a fresh interpreter (``--no-progress``), one after
another; its peak RSS is the kernel's (``os.wait4``'s ``ru_maxrss``), its wall time the
parent's clock. Exits 1 if a bar fails.

    python benchmarks/bench_memory.py [--config configs/cornell_pmap.yaml] [--set KEY=VALUE ...]
    python benchmarks/bench_memory.py --large-only [--spp 1 4] [--modes rcast refract]
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
LARGE_BAR_BYTES = 4 * 1024**3
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


def write_scene(folder: Path, name: str, n_seg: int, n_rings: int) -> tuple[Path, int]:
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
               resolution=RESOLUTION)
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
                verdict(rss <= LARGE_BAR_BYTES, f"spp {spp} {mode}: peak resident memory {rss / 2**20:.0f} MiB "
                        f"at {n_large:,} triangles (bar: at most {LARGE_BAR_BYTES / 2**30:.0f} GiB)", "  ")
                ratio, tri_ratio = wall / wall_small, n_large / n_small
                print(f"  spp {spp} {mode}: wall time {ratio:.2f}x for {tri_ratio:.1f}x the triangles "
                      f"({'less than' if ratio < tri_ratio else 'NOT less than'} linear)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "cornell_pmap.yaml",
                    help="the Cornell check's config")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="passed to every tlm run")
    ap.add_argument("--large-only", action="store_true", help="only the 1M-triangle 1080p runs")
    ap.add_argument("--spp", type=int, nargs="+", default=[1],
                    help="eye rays per pixel of the large runs (default: 1, the thesis's ray casting)")
    ap.add_argument("--modes", nargs="+", default=["rcast", "refract"], choices=["rcast", "refract"],
                    help="modes of the large runs")
    args = ap.parse_args()
    sets = [a for kv in args.set for a in ("--set", kv)]
    if not args.large_only:
        cornell_check(args, sets)
    large_check(args, sets)
    exit_status()


if __name__ == "__main__":
    main()
