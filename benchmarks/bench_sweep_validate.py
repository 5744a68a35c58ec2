"""Host seconds to check a sweep of 10^3, 10^4 and 10^5 points, and per point.

Writes in a temporary folder a sweep of Cornell RCast (an inline base config) whose grid
takes 10 values of each of its factors, as many factors as the size needs:
``arch.pipelines`` (1..10), ``arch.page_miss_cycles``, ``cache.block_words`` (10
functional results: 10 scene loads), then ``arch.fifo_depth`` (10^4) and
``arch.flush_cycles`` (10^5). Times ``tlm.experiments.sweep_file.load_sweep`` on it: every
point's config checked, the scenes and the programs table it names loaded, every point's
key computed, which ``tlm sweep`` does before it runs a point (best of ``--repeat``).
``--until-first-point`` also times ``run_sweep`` up to where it would start the first
point (the points' folder scanned for finished points, ``sweep.yaml`` written; with
``--jobs 1``, the worker pool left aside). Prints the seconds, the microseconds per point
and each size's time per point over the smallest size's (1.00: the time grows as the
points do). No bar: the figures are for reading (benchmarks/README.md).

    python benchmarks/bench_sweep_validate.py [--sizes 1000 10000 100000] [--repeat 1] [--until-first-point]
"""

from __future__ import annotations

import argparse
import math
import os
import tempfile
from pathlib import Path

import yaml
from timing import best_of

BASE = {"scene": "cornell", "mode": "rcast", "render": {"light_samples": 1}, "arch": {"trace": False}}
FACTORS = [
    ("arch.pipelines", list(range(1, 11))),
    ("arch.page_miss_cycles", list(range(0, 40, 4))),
    ("cache.block_words", [2 ** k for k in range(4, 14)]),
    ("arch.fifo_depth", [4 ** k for k in range(10)]),
    ("arch.flush_cycles", list(range(10))),
]


def sweep_file(folder: Path, points: int) -> Path:
    """A sweep of ``points`` (a power of 10, 10 to 10^5) points in ``folder``."""
    n = round(math.log10(points))
    if 10 ** n != points or not 1 <= n <= len(FACTORS):
        raise SystemExit(f"--sizes: {points} is not 10, 100, ... or {10 ** len(FACTORS)}")
    path = folder / f"sweep{points}.yaml"
    path.write_text(yaml.safe_dump({"description": f"{points} points", "base": BASE,
                                    "grid": dict(FACTORS[:n])}, sort_keys=False))
    return path


def until_first_point(path: Path, out: Path) -> None:
    """run_sweep up to where it would start the first point (its dispatch stopped)."""
    import tlm.experiments.sweep as sweep_mod

    class Stop(Exception):
        pass

    def stop(*args, **kwargs):
        raise Stop

    dispatch, sweep_mod._dispatch = sweep_mod._dispatch, stop
    try:
        sweep_mod.run_sweep(path, out, jobs=1)
    except Stop:
        pass
    finally:
        sweep_mod._dispatch = dispatch


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[1000, 10000, 100000])
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--until-first-point", action="store_true",
                    help="also time run_sweep up to its first point (writes sweep.yaml in the temporary folder)")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        os.environ["TLM_CACHE"] = str(Path(tmp) / "cache")  # (nothing is rendered; a cache of its own all the same)
        from tlm.experiments.sweep_file import load_sweep
        from tlm.fingerprint import code_fingerprint

        code_fingerprint()  # (read once per process: not any size's)
        rows = []
        for size in sorted(args.sizes):
            path = sweep_file(Path(tmp), size)
            got = {}

            def load(path=path, got=got):
                got["sweep"] = load_sweep(path)

            check = best_of(load, args.repeat)
            assert len(got["sweep"].points) == size
            del got
            first = None
            if args.until_first_point:
                outs = iter(range(args.repeat))

                def run(path=path, outs=outs, size=size):  # (into a new folder each time: no point is done)
                    until_first_point(path, Path(tmp) / f"out{size}-{next(outs)}")

                first = best_of(run, args.repeat)
            rows.append((size, check, first))

    print(f"sweep of Cornell RCast, 10 values per factor; best of {args.repeat}")
    head = f"{'points':>8s} {'check s':>9s} {'us/point':>9s} {'per point / smallest':>21s}"
    if args.until_first_point:
        head += f" {'first point s':>14s} {'us/point':>9s} {'per point / smallest':>21s}"
    print(head)
    for size, check, first in rows:
        line = f"{size:>8,d} {check:9.2f} {check / size * 1e6:9.1f} {check / size / (rows[0][1] / rows[0][0]):21.2f}"
        if first is not None:
            line += (f" {first:14.2f} {first / size * 1e6:9.1f} "
                     f"{first / size / (rows[0][2] / rows[0][0]):21.2f}")
        print(line)


if __name__ == "__main__":
    main()
