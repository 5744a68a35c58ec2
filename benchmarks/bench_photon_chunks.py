"""The photon trace's time against ``render.batch_rays``, with and without the chunk floor.

The photon tracer goes in chunks of at most ``batch_rays // max_bounces`` photons (all
bounces of a chunk traced and charged before the next, so memory does not grow with the
bounces), but of at least ``tlm.kernels.photons.PHOTON_MIN_BATCH`` photons: each chunk has
a fixed cost. For each budget, times ``trace_photon_map`` of the config's frame (one
thread, the best of ``--repeat``) with the floor and without it (``PHOTON_MIN_BATCH = 1``:
the budget alone sets the chunks), all in this one run, and prints each against the
configured budget's time. Checks that the maps and work are the same at every budget
(FAIL and exit 1 otherwise).

    python benchmarks/bench_photon_chunks.py [--config configs/conference.yaml]
                                             [--budgets 2731 8192 32768] [--repeat 2]
"""

from __future__ import annotations

import argparse
import dataclasses
import hashlib
import time
from pathlib import Path

import numpy as np
from timing import exit_status, verdict

from tlm.config import load_config
from tlm.experiments.loading import load_frame
from tlm.kernels import photons as photon_module
from tlm.render.planner import photon_count
from tlm.render.pmap import trace_photon_map

ROOT = Path(__file__).resolve().parents[1]


def digest(traced) -> str:
    h = hashlib.sha256()
    for m in traced.photons.gathered:
        for a in (m.position, m.power, m.incoming):
            h.update(np.ascontiguousarray(a).tobytes())
    for k in sorted(traced.work):
        h.update(np.ascontiguousarray(traced.work[k], dtype=np.int64).tobytes())
    return h.hexdigest()[:16]


def timed(frame, budget: int, floor: int, repeat: int) -> tuple[float, str, int]:
    """(best seconds, digest, chunks) of the photon trace with ``render.batch_rays = budget``."""
    fr = dataclasses.replace(frame, cfg=dataclasses.replace(
        frame.cfg, render=dataclasses.replace(frame.cfg.render, batch_rays=budget)))
    old = photon_module.PHOTON_MIN_BATCH
    photon_module.PHOTON_MIN_BATCH = floor
    try:
        chunks = len(photon_module.photon_spans(photon_count(fr.scene, fr.cfg), fr.cfg.photons.max_bounces, budget))
        best, traced = float("inf"), None
        for _ in range(repeat):
            t0 = time.perf_counter()
            traced = trace_photon_map(fr)
            best = min(best, time.perf_counter() - t0)
    finally:
        photon_module.PHOTON_MIN_BATCH = old
    return best, digest(traced), chunks


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "conference.yaml")
    ap.add_argument("--budgets", type=int, nargs="+", default=[2731, 8192, 32768])
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    cfg, base = load_config(args.config, ["render.threads=1"])
    frame = load_frame(cfg, base)
    trace_photon_map(frame, n=2000)  # (loads the compiled kernels)
    floor = photon_module.PHOTON_MIN_BATCH
    ref, ref_digest, ref_chunks = timed(frame, cfg.render.batch_rays, floor, args.repeat)
    print(f"{args.config.name}: {photon_count(frame.scene, frame.cfg)} photons, max_bounces {cfg.photons.max_bounces}; "
          f"configured render.batch_rays={cfg.render.batch_rays}: {ref:.2f} s, {ref_chunks} chunks")
    print(f"{'batch_rays':>10} {'floor':>6} {'chunks':>6} {'seconds':>8} {'x configured':>12}")
    same = True
    for budget in args.budgets:
        for fl in (floor, 1):
            seconds, d, chunks = timed(frame, budget, fl, args.repeat)
            same &= d == ref_digest
            print(f"{budget:>10} {fl:>6} {chunks:>6} {seconds:>8.2f} {seconds / ref:>11.2f}x"
                  + ("" if d == ref_digest else "  DIFFERS"))
    verdict(same, "photon maps and work the same at every budget, with and without the floor")
    exit_status()


if __name__ == "__main__":
    main()
