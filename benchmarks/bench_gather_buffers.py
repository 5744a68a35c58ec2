"""The photon-map pass with the compiled gather's pair buffers learned per map and radius, against forgetting them.

The compiled fixed-radius gather (``tlm/kernels/_jit_gather.py``) writes each query's
(query, leaf) pairs into a buffer sized up front; a chunk of queries that needs more is
gathered again with a larger one. The buffers are sized by the pairs a query needed in
earlier gathers at the same radius, kept on the map in leaf order
(``LeafPhotons.pairs``). Before (``forget``), every gather started again from the default
size, so the first chunk of every gather call (every batch, every final-gather chunk)
could run twice.

Renders a config's whole frame (``tlm.experiments.run.render``) the two ways, alternated
``--rounds`` times after an untimed render, and prints per way the median seconds of the
``pass_pmap`` stage (summed over the workers when whole batches run at once), how many
gather chunks ran twice, and the paired median ratio learned / forget. Checks that
both ways give byte-identical radiance and work (exits 1 otherwise).

    python benchmarks/bench_gather_buffers.py [--config configs/cornell_pmap.yaml]
        [--resolution 160 160] [--threads 1 2] [--rounds 3]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from bench_threads import digest  # (radiance and work, hashed in a fixed order)
from timing import exit_status, verdict

from tlm.config import load_config
from tlm.experiments.run import render
from tlm.kernels import _jit_gather, estimate

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default=str(ROOT / "configs" / "cornell_pmap.yaml"))
    ap.add_argument("--resolution", type=int, nargs=2, default=[160, 160])
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()

    forget = {"on": False}
    reruns = [0]
    gather_jit, kernel = estimate._fixed_radius_jit, _jit_gather.fixed_radius

    def gather(lp, *a, **k):
        if forget["on"]:
            lp.pairs.clear()  # (every gather from the default size, as before)
        return gather_jit(lp, *a, **k)

    def counted(*a):
        need = kernel(*a)
        reruns[0] += need > a[16].shape[0]  # (the pair buffer was too small: the chunk runs again)
        return need

    estimate._fixed_radius_jit, _jit_gather.fixed_radius = gather, counted
    print(f"{Path(args.config).name} at {args.resolution[0]}x{args.resolution[1]}, {args.rounds} rounds alternated")
    print(f"{'threads':>7s} {'buffers':8s} {'pass_pmap s':>12s} {'chunks run twice':>17s} "
          f"{'learned/forget':>15s}  digest")
    for n in args.threads:
        cfg, base = load_config(args.config, [f"resolution=[{args.resolution[0]},{args.resolution[1]}]",
                                              f"render.threads={n}"])
        render(cfg, base)  # (loads the compiled kernels and the scene cache)
        seconds: dict[str, list[float]] = {"learned": [], "forget": []}
        twice: dict[str, int] = {}
        digests: dict[str, str] = {}
        for _ in range(args.rounds):
            for way in ("forget", "learned"):
                forget["on"] = way == "forget"
                reruns[0] = 0
                res = render(cfg, base)
                seconds[way].append(res.timer.seconds["pass_pmap"])
                twice[way] = reruns[0]
                digests.setdefault(way, digest(res))
        ratio = float(np.median(np.array(seconds["learned"]) / np.array(seconds["forget"])))
        for way in ("forget", "learned"):
            print(f"{n:7d} {way:8s} {np.median(seconds[way]):12.2f} {twice[way]:17d} "
                  f"{format(ratio, '.3f') if way == 'learned' else '':>15s}  {digests[way]}")
        verdict(digests["learned"] == digests["forget"],
                f"{n} thread(s): radiance and work byte-identical with the buffers learned or forgotten")
    exit_status()


if __name__ == "__main__":
    main()
