"""Whole-frame render time against ``render.threads``, and the same bits at every count.

For each config (default: ``configs/cornell_pmap.yaml`` and the conference room,
``configs/conference.yaml``), renders the whole frame with
``tlm.experiments.run.render`` (load, BSP build, photon trace, every pass of every
batch: what ``tlm run`` spends before the timing model) at ``render.threads`` = 1, 2,
... up to ``--max-threads`` (default: the CPUs available to the process), all in this
one run: ``--repeat`` rounds (default 3), each at every thread count, ascending in one
round and descending in the next. A first, untimed render at the smallest resolution
loads the compiled kernels. Prints, per thread count, the wall seconds (the best of the
rounds), the speed-up of the best times, the *paired* speed-up (the median over the
rounds of each round's one-thread time over its own: a machine that slows down for a
while slows both of a pair) and the parallel efficiency
(paired speed-up / threads), the cores the render kept busy (the process's CPU seconds over
the wall seconds: near the thread count when the code runs on every thread all the
time, whatever the cores' speed; the CPU seconds beside it grow over one thread's when
the cores run slower together, shared or contended), and the seconds of the stages
(scene load, BSP build, photon trace, the ray passes, the photon-map pass; the passes'
summed over the workers when whole batches run at once, so they exceed the wall
seconds there). The scene load reads the scene cache (:mod:`tlm.scenes.cache`), as
every run after a scene's first does.

Checks that the radiance of every frame and every work count are byte-identical to
one thread's at every count (FAIL and exit 1 otherwise), and the bar of issue 25: two
threads at least ``1.8x`` one thread on the whole frame, paired. The bar means something only
on a machine with two idle cores or more; on a busy or a two-core machine shared with
other work it says what the machine had to spare, not what the code does: so the bench
first prints how fast as many busy-loop processes as the largest thread count run at
once against one alone (:func:`spare_cores`), and again at the end.

``--ceiling`` adds, in every round and for every thread count ``n`` above one, ``n``
one-thread renders of the same frame at once, each in a process of its own (spawned and
warmed up first, then started together): the most any threading of this work gets from
this machine's cores, whatever they are, as the processes share nothing but the machine
(its caches, memory and host). The bench prints that *ceiling* (``n`` frames in the
slowest process's wall seconds against one frame alone, paired per round) and the
threads' speed-up as a share of it (the median over the rounds of ``n`` processes'
slowest wall seconds over ``n`` times the ``n``-thread render's: 1.00, the threads do
the work as fast as ``n`` separate processes; less, the code's own overhead). Each
process's frame must give one thread's bits too.

Resolution: by default a fraction of the configs' own that renders in about a minute at
one thread on a current core (``--quick``: 64 x 64, seconds; ``--full``: the configs' own
resolution, minutes at one thread for Cornell, over ten for the conference room).

    python benchmarks/bench_threads.py [--configs configs/cornell_pmap.yaml ...]
                                       [--max-threads N | --threads 1 2 4 16] [--repeat 3]
                                       [--quick | --full] [--ceiling]
"""

from __future__ import annotations

import argparse
import hashlib
import time
from pathlib import Path

import numpy as np
from timing import exit_status, verdict

from tlm.config import load_config
from tlm.experiments.run import render
from tlm.kernels.threads import available

ROOT = Path(__file__).resolve().parents[1]
CONFIGS = [ROOT / "configs" / "cornell_pmap.yaml", ROOT / "configs" / "conference.yaml"]
SPEEDUP_BAR = 1.8  # issue 25: two threads at least 1.8x one thread on the whole frame
# the default resolutions: a whole frame in about a minute at one thread
DEFAULT_RESOLUTION = {"cornell_pmap": [160, 160], "conference": [128, 128]}
QUICK_RESOLUTION = [64, 64]
STAGES = {"load": ("load_scene",), "build": ("build_bsp",), "photons": ("photon_trace",),
          "cast+rays": ("cast", "pass_rcast", "pass_reflect", "pass_refract"),
          "pmap": ("pass_pmap", "pass_fgather")}


def digest(res) -> str:
    """A hash of every frame's radiance and every work count, in a fixed order."""
    h = hashlib.sha256()
    for name in sorted(res.radiance):
        h.update(name.encode())
        h.update(np.ascontiguousarray(res.radiance[name]).tobytes())
    for name in sorted(res.work):
        for k in sorted(res.work[name]):
            h.update(f"{name}.{k}".encode())
            h.update(np.ascontiguousarray(res.work[name][k], dtype=np.int64).tobytes())  # (the counts, not their width)
    return h.hexdigest()[:16]


def _spin(_=None) -> float:
    """Seconds of a fixed pure-Python busy loop (no memory traffic, no lock)."""
    t0 = time.perf_counter()
    s = 0
    for i in range(10_000_000):
        s += i
    return time.perf_counter() - t0


def spare_cores(n: int) -> float:
    """How fast ``n`` busy-loop processes at once run against one alone (1.0: ``n``
    whole cores to spare; less: the machine is shared or its cores are not whole)."""
    import multiprocessing

    alone = min(_spin() for _ in range(2))
    with multiprocessing.get_context("spawn").Pool(n) as pool:
        pool.map(_spin, range(n))  # (the workers start)
        together = max(pool.map(_spin, range(n)))
    return alone / together


def timed(path: Path, overrides: list[str], threads: int):
    """(wall seconds, the result, CPU seconds of the process) of one whole-frame render
    on ``threads`` threads."""
    cfg, base = load_config(path, [*overrides, f"render.threads={threads}"])
    c0, t0 = time.process_time(), time.perf_counter()
    res = render(cfg, base)
    return time.perf_counter() - t0, res, time.process_time() - c0


def _one_process(path: Path, overrides: list[str], start, out) -> None:
    """A process of :func:`processes`: warms up, says so on ``out``, waits at ``start`` (a
    barrier), renders the frame on one thread and puts (wall seconds, CPU seconds, digest)
    on ``out``."""
    timed(path, ["resolution=[8,8]"], 1)  # (loads the compiled kernels, as the bench's own warm-up)
    out.put(None)
    start.wait(timeout=600)  # (a bench that is gone leaves no process waiting for ever)
    seconds, got, used = timed(path, overrides, 1)
    out.put((seconds, used, digest(got)))


def _take(out, procs, n: int, what: str) -> list:
    """``n`` messages from ``out``, or a RuntimeError as soon as a process has failed (or
    all have ended without them)."""
    import queue

    got = []
    while len(got) < n:
        try:
            got.append(out.get(timeout=1.0))
            continue
        except queue.Empty:
            pass
        failed = any(p.exitcode not in (None, 0) for p in procs)
        if failed or all(p.exitcode is not None for p in procs):
            try:  # (what a process put just before it ended)
                while len(got) < n:
                    got.append(out.get(timeout=0.5))
            except queue.Empty:
                raise RuntimeError(f"a one-thread render process failed {what} (exit codes "
                                   f"{[p.exitcode for p in procs]})") from None
    return got


def processes(path: Path, overrides: list[str], n: int) -> list[tuple[float, float, str]]:
    """``(wall seconds, CPU seconds, digest)`` of ``n`` one-thread renders of the frame run
    at once, each in a spawned process of its own, started together after their warm-up;
    a RuntimeError (at once, not at a timeout) where a process fails. The processes are
    daemons: they end with the bench."""
    import multiprocessing
    import threading

    ctx = multiprocessing.get_context("spawn")
    start, out = ctx.Barrier(n + 1), ctx.Queue()
    procs = [ctx.Process(target=_one_process, args=(path, overrides, start, out), daemon=True) for _ in range(n)]
    for p in procs:
        p.start()
    try:
        _take(out, procs, n, f"warming up on {path.name}")
        try:
            start.wait(timeout=60)
        except threading.BrokenBarrierError:
            raise RuntimeError(f"a one-thread render process of {path.name} did not reach the start (exit codes "
                               f"{[p.exitcode for p in procs]})") from None
        return _take(out, procs, n, f"rendering {path.name}")
    finally:
        for p in procs:  # (every one stopped first, then each waited for)
            if p.is_alive() and p.exitcode is None:
                p.join(timeout=0.1)
        for p in procs:
            if p.is_alive():
                p.terminate()
        for p in procs:
            p.join()


def bench(path: Path, overrides: list[str], counts: list[int], repeat: int, ceiling: bool = False) -> bool:
    """Print one config's table; returns whether every render gave one thread's bits.

    ``repeat`` rounds, each rendering at every thread count, in ascending order in even
    rounds and descending in odd ones, so that a machine that slows down or speeds up for
    a while weighs on both ends of a pair. The speed-up of a count is the best one-thread
    time over its best time; ``paired`` is the median over the rounds of the round's own
    ratio (as ``bench_raytrace.py`` pairs tlm with Embree), which the bar reads. With
    ``ceiling``, each round also runs :func:`processes` after every count above one."""
    print(f"\n{path.name} ({', '.join(overrides) or 'as configured'}; {repeat} round{'s' * (repeat > 1)})")
    print(f"{'threads':>7} {'seconds':>8} {'speed-up':>8} {'paired':>7} {'efficiency':>10} {'cores busy':>10} "
          f"{'CPU s':>7}  " + " ".join(f"{s:>9}" for s in STAGES) + "  digest")
    runs: dict[int, list[tuple[float, float, str, list[float]]]] = {n: [] for n in counts}
    alone: dict[int, list[list[tuple[float, float, str]]]] = {n: [] for n in counts[1:]}  # (ceiling)
    for r in range(repeat):
        for n in counts if r % 2 == 0 else counts[::-1]:
            seconds, got, used = timed(path, overrides, n)
            stages = [sum(got.timer.seconds.get(k, 0.0) for k in keys) for keys in STAGES.values()]
            runs[n].append((seconds, used, digest(got), stages))
            del got  # (a whole frame's arrays: one at a time)
            if ceiling and n > 1:
                alone[n].append(processes(path, overrides, n))
    first = runs[counts[0]][0][2]
    same = True
    one = min(runs[1])[0]
    for n in counts:
        best, cpu, _, stages = min(runs[n])
        digests = {d for _, _, d, _ in runs[n]}
        same &= digests == {first}
        speedup = one / best
        paired = float(np.median([a[0] / b[0] for a, b in zip(runs[1], runs[n], strict=True)]))
        print(f"{n:>7} {best:>8.2f} {speedup:>7.2f}x {paired:>6.2f}x {paired / n:>10.2f} {cpu / best:>10.2f} "
              f"{cpu:>7.2f}  " + " ".join(f"{s:>9.2f}" for s in stages)
              + f"  {' '.join(sorted(digests))}{'' if digests == {first} else '  DIFFERS'}")
        if n == 2:
            verdict(paired >= SPEEDUP_BAR, f"{path.name}: 2 threads {paired:.2f}x one thread (median of "
                    f"{repeat} paired round{'s' * (repeat > 1)}; best times {speedup:.2f}x; bar: at least "
                    f"{SPEEDUP_BAR}x; {available()} CPUs available)", indent="  ")
    verdict(same, f"{path.name}: radiance and work byte-identical at {', '.join(map(str, counts))} threads",
            indent="  ")
    for n, rounds in alone.items() if ceiling else ():
        slowest = [max(w for w, _, _ in procs) for procs in rounds]
        cap = float(np.median([n * a[0] / w for a, w in zip(runs[1], slowest, strict=True)]))
        share = float(np.median([w / (n * b[0]) for b, w in zip(runs[n], slowest, strict=True)]))
        cpu = float(np.median([np.mean([c for _, c, _ in procs]) for procs in rounds]))
        print(f"  ceiling: {n} one-thread renders at once, in {n} processes: the slowest {min(slowest):.2f} s "
              f"(best of {len(rounds)}; CPU seconds each {cpu:.2f}, median): {n} frames {cap:.2f}x as fast as one "
              f"alone, paired; {n} threads {share:.2f} of that")
        digests = {d for procs in rounds for _, _, d in procs}
        same &= digests == {first}
        verdict(digests == {first}, f"{path.name}: each of the {n} processes' frames byte-identical to one "
                f"thread's ({' '.join(sorted(digests))})", indent="  ")
    return same


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--configs", nargs="+", type=Path, default=CONFIGS)
    ap.add_argument("--max-threads", type=int, default=available(),
                    help="the largest thread count (default: the CPUs available)")
    ap.add_argument("--threads", type=int, nargs="+", help="these thread counts instead (1 is added first)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="rounds: renders per thread count, alternating the order (default 3)")
    size = ap.add_mutually_exclusive_group()
    size.add_argument("--quick", action="store_true", help=f"{QUICK_RESOLUTION[0]} x {QUICK_RESOLUTION[1]} pixels")
    size.add_argument("--full", action="store_true", help="the configs' own resolution")
    ap.add_argument("--ceiling", action="store_true",
                    help="also run N one-thread renders at once in N processes per thread count N (the "
                         "machine's ceiling for this work)")
    args = ap.parse_args()
    if args.max_threads < 1 or args.repeat < 1:
        ap.error("--max-threads and --repeat must be >= 1")
    counts = list(range(1, args.max_threads + 1))
    if args.threads:
        if min(args.threads) < 1:
            ap.error("--threads must be >= 1")
        counts = [1, *sorted(set(args.threads) - {1})]
    print(f"{available()} CPUs available; threads {counts[0]}..{counts[-1]}")
    if counts[-1] > 1:
        print(f"the machine: {counts[-1]} busy-loop processes at once each ran at "
              f"{spare_cores(counts[-1]):.2f}x one alone's speed (1.00: the cores are there to spare)")
    for path in args.configs:
        res = QUICK_RESOLUTION if args.quick else DEFAULT_RESOLUTION.get(path.stem, [128, 128])
        overrides = [] if args.full else [f"resolution=[{res[0]},{res[1]}]"]
        timed(path, ["resolution=[8,8]"], 1)  # loads the compiled kernels (and fills the scene cache)
        bench(path, overrides, counts, args.repeat, args.ceiling)
    if counts[-1] > 1:
        print(f"\nthe machine after: {counts[-1]} busy-loop processes at once each ran at "
              f"{spare_cores(counts[-1]):.2f}x one alone's speed")
    exit_status()


if __name__ == "__main__":
    main()
