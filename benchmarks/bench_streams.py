"""The address streams' compaction and page misses: compiled against numpy, in the same run.

``tlm.kernels.memory`` turns what a kernel read into per-page runs (``Accesses.of_ranges``:
a leaf's triangle or photon words; ``Accesses.of_csr``: the nodes each ray entered;
``compact``) and charges them to the cache pairs (``page_misses``). With numba they run
compiled (``tlm/kernels/_jit_memory.py``), with ``TLM_KERNELS=numpy`` as numpy code. This
bench times both engines on the same synthetic streams (``--ranges`` ranges of 2 to 40
words over 2M words, sorted owners; as many node ids in CSR lists of 20 a ray), checks
that they return the same arrays (FAIL and exit 1 otherwise), and prints each time (the
best of ``--repeat``) and the ratio numpy / compiled.

    python benchmarks/bench_streams.py [--ranges 1000000] [--repeat 5]
"""

from __future__ import annotations

import argparse
import os

import numpy as np
from timing import best_of, exit_status, verdict

from tlm.kernels.memory import Accesses, PairState, compact, page_misses

PAGE = 1024


def cases(m: int, rng: np.random.Generator) -> dict:
    owner = np.sort(rng.integers(0, max(1, m // 50), m))
    first = rng.integers(0, 2_000_000, m)
    last = first + rng.integers(2, 40, m)
    nodes = rng.integers(0, 5000, m).astype(np.int32)
    ptr = np.arange(0, m + 1, 20, dtype=np.int64)
    if ptr[-1] != m:
        ptr = np.append(ptr, m)
    words = np.sort(rng.integers(0, 4_000_000, m))
    return {
        "of_ranges": lambda: Accesses.of_ranges(first, last, owner, PAGE),
        "of_csr": lambda: Accesses.of_csr(nodes, ptr, PAGE),
        "compact": lambda: compact(words, owner, PAGE),
        "page_misses": lambda: page_misses(words, PairState(), PAGE),
    }


def flat(result) -> list[bytes]:
    if isinstance(result, Accesses):
        return [result.words.tobytes(), result.owner.tobytes()]
    return [x.tobytes() if isinstance(x, np.ndarray) else repr(x).encode() for x in result]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ranges", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    if args.ranges < 1 or args.repeat < 1:
        ap.error("--ranges and --repeat must be >= 1")
    fns = cases(args.ranges, np.random.default_rng(0))
    print(f"{args.ranges:,} ranges, {PAGE}-word pages; best of {args.repeat}")
    print(f"{'function':<12} {'numpy ms':>9} {'compiled ms':>12} {'numpy / compiled':>17}")
    for name, fn in fns.items():
        times, outs = {}, {}
        for engine in ("numpy", "numba"):
            os.environ["TLM_KERNELS"] = engine
            outs[engine] = flat(fn())  # (and the compiled code loaded)
            times[engine] = best_of(fn, args.repeat)
        print(f"{name:<12} {times['numpy'] * 1e3:>9.1f} {times['numba'] * 1e3:>12.1f} "
              f"{times['numpy'] / times['numba']:>16.1f}x")
        verdict(outs["numpy"] == outs["numba"], f"{name}: the same arrays from both engines", indent="  ")
    os.environ.pop("TLM_KERNELS", None)
    exit_status()


if __name__ == "__main__":
    main()
