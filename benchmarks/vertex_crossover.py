"""Where a frame stops being Vertex-bound: the image side at which the throughput leaves T_vert0, per N and scheduler.

Cornell, rcast, ``render.spp`` 1 and ``render.light_samples`` 1 (``arch.trace`` off): the one Vertex PM's
cycles (T_vert0, the BSP build) do not depend on the image or on N, so a small image's throughput is T_vert0
whatever N. Per N, square images around the crossover, every 8 pixels a side, are rendered once each (the
functional cache, ``$TLM_CACHE``) and simulated with N pipelines and each scheduler. Prints every measurement,
then the table of docs/architecture.md ("Small images are Vertex-bound"): per N and scheduler the largest
side measured at T_vert0, the smallest above it (and by how much), and the first of these per pipeline
(side / sqrt(N)). Not a test: a few minutes on 2 cores, most of it the renders.

    PYTHONPATH=. python benchmarks/vertex_crossover.py [--n 4 16]
"""

from __future__ import annotations

import argparse
import math

# per N, the sides (pixels, square images) measured: around where the throughput leaves T_vert0
SIDES = {1: range(24, 65, 8), 2: range(40, 73, 8), 4: range(64, 105, 8), 8: range(88, 129, 8),
         16: range(128, 177, 8), 64: range(240, 329, 8)}
SCHEDULERS = ("static", "dynamic")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=list(SIDES), choices=list(SIDES), help="pipelines to measure")
    args = ap.parse_args()
    import tlm

    results = {}  # side -> the rendered frame (each side rendered once, for every N that measures it)
    table = []
    for n in args.n:
        thru: dict[str, list[tuple[int, int]]] = {s: [] for s in SCHEDULERS}
        vert = None
        for side in SIDES[n]:
            if side not in results:
                cfg = tlm.load_config("cornell", {"mode": "rcast", "resolution": [side, side], "render.spp": 1,
                                                  "render.light_samples": 1, "arch.trace": False})
                results[side] = tlm.render_image(cfg)
            line = []
            for sched in SCHEDULERS:
                t = tlm.simulate(results[side], {"pipelines": n, "scheduler": sched})
                vert = t.cycles["vertex"]
                thru[sched].append((side, t.cycles["throughput"]))
                line.append(f"{sched} {t.cycles['throughput']:>10,} ({t.cycles['throughput'] / vert - 1:+.1%})")
            print(f"N = {n:<3} {side:>3}x{side:<3} T_vert0 {vert:,}: " + "  ".join(line), flush=True)
        for sched in SCHEDULERS:
            at = [side for side, t in thru[sched] if t == vert]
            above = [(side, t) for side, t in thru[sched] if t > vert and (not at or side > max(at))]
            table.append((n, sched, max(at) if at else None, above[0] if above else None, vert))
    print("\nN    scheduler  at T_vert0  first above      per pipeline (side / sqrt(N))")
    for n, sched, at, above, vert in table:
        last = f"{at}x{at}" if at else "(none measured)"
        first = f"{above[0]}x{above[0]} ({above[1] / vert - 1:+.1%})" if above else "(none measured)"
        per = f"{at / math.sqrt(n):.0f}-{above[0] / math.sqrt(n):.0f} px" if at and above else ""
        print(f"{n:<4} {sched:<10} {last:<11} {first:<16} {per}")


if __name__ == "__main__":
    main()
