"""Whole runs of the ladder of standard scenes (issue 23): wall time, peak memory and the
work a setting can blow up (photons tested and accepted per gather, triangle tests per ray).

Each config is ``python -m tlm run CONFIG --no-progress --no-reference`` in a fresh
interpreter, one after another (its report included, as a user runs it), on one thread: the
run alone, not the converged photon-map reference that ``reference.auto`` would compute
first with a cold cache (``tlm reference``: minutes, and only once); its peak RSS is
the kernel's (``os.wait4``'s ``ru_maxrss``), its wall time the parent's clock, its work
read back from the run's ``results.json``. ``configs/cornell_pmap.yaml`` (the thesis's
Cornell box, 2,604 triangles, 320 x 320) is the reference measured in the same run: each
scene's wall time is printed as a ratio to it.

Bars (the conference room, 331,179 triangles at 512 x 512 in pmap mode): at most 500
photons tested per gather on average, at most 60 s wall and 2 GiB peak for the whole
``tlm run``. Exits 1 if a bar fails.

    python benchmarks/bench_ladder.py [--configs configs/conference.yaml ...]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from timing import exit_status, verdict

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = "configs/cornell_pmap.yaml"
LADDER = ("configs/cornell-box.yaml", "configs/cornell-sphere.yaml", "configs/cornell-water.yaml",
          "configs/conference.yaml")
BARS = {"configs/conference.yaml": {"wall": 60.0, "rss": 2 * 1024**3, "tested": 500.0}}


def run(config: str, out: Path) -> dict:
    cmd = [sys.executable, "-m", "tlm", "run", config, "--out", str(out), "--no-progress", "--no-reference"]
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=env)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed: {proc.stderr.read().decode()[-2000:]}")
    results = json.loads((out / "results.json").read_text())
    work = results["work"]
    row = {"config": config, "wall": wall, "rss": usage.ru_maxrss * 1024,
           "triangles": results["scene"]["triangles"], "warnings": results["warnings"],
           "tri_tests_per_ray": work.get("rcast", {}).get("tri_tests_per_ray")}
    pmap = work.get("pmap")
    if pmap is not None:
        row["tested"] = pmap["photons_tested_per_gather"]
        row["accepted"] = pmap["photons_accepted_per_gather"]
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--configs", nargs="+", default=list(LADDER))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        ref = run(REFERENCE, Path(tmp) / "reference")
        rows = [run(c, Path(tmp) / f"run{i}") for i, c in enumerate(args.configs)]
    print("each 'tlm run CONFIG --no-progress --no-reference' (the run alone, not the photon-map reference)")
    print(f"reference {REFERENCE}: {ref['wall']:.1f} s, {ref['rss'] / 2**20:.0f} MiB, "
          f"{ref['tested']:.1f} photons tested per gather")
    print(f"{'config':32s} {'triangles':>10s} {'wall s':>7s} {'x ref':>6s} {'peak MiB':>9s} "
          f"{'tested/gather':>14s} {'accepted':>9s} {'tri tests/ray':>14s}")
    for r in rows:
        tested = f"{r['tested']:14.1f} {r['accepted']:9.1f}" if "tested" in r else f"{'-':>14s} {'-':>9s}"
        print(f"{r['config']:32s} {r['triangles']:10d} {r['wall']:7.1f} {r['wall'] / ref['wall']:6.2f} "
              f"{r['rss'] / 2**20:9.0f} {tested} {r['tri_tests_per_ray']:14.1f}")
        for w in r["warnings"]:
            print(f"  warning: {w}")
    for r in rows:
        bar = BARS.get(r["config"])
        if bar is None:
            continue
        verdict(r["tested"] <= bar["tested"], f"{r['config']}: {r['tested']:.1f} photons tested per gather "
                                              f"(bar: at most {bar['tested']:g})")
        verdict(r["wall"] <= bar["wall"], f"{r['config']}: tlm run {r['wall']:.1f} s wall (bar: at most "
                                          f"{bar['wall']:g} s; {r['wall'] / ref['wall']:.2f}x the reference's)")
        verdict(r["rss"] <= bar["rss"], f"{r['config']}: peak {r['rss'] / 2**30:.2f} GiB (bar: at most "
                                        f"{bar['rss'] / 2**30:g} GiB)")
    exit_status()


if __name__ == "__main__":
    main()
