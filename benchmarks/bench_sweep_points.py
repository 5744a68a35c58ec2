"""CPU seconds per point of an arch-only sweep, with and without the in-process memos.

Writes in a temporary folder a sweep of Cornell RCast at 16x16 (an inline base config,
one sample per pixel, one light sample, no trace) whose points differ only in ``arch``:
``arch.packet_size`` x ``arch.fifo_depth`` x ``arch.page_miss_cycles`` (4 x 5 x 5 = 100
points; ``--points 200`` takes 10 page-miss values), so every point shares one frame.
A first sweep renders that frame into the functional cache (and compiles the kernels); then
the same sweep runs ``--repeat`` times with the memos and as many times without them
(alternating, each into a fresh output folder, ``--jobs 1``, in this process). The memos are
the scene's fingerprint of a frame's key (:func:`tlm.experiments.frames.scene_key`) and the
programs table (:func:`tlm.arch.costs.load_programs`); "without" sets both memos' size to 0,
so every point loads the scene and parses the table again, as tlm did before them. Prints
the CPU seconds (``time.process_time``: the machine's load changes the wall time more) per
point of each run, the median of each way, their ratio, and whether the two ways gave the
same rows (``sweep.csv`` less the host seconds and ``functional_cached``).

``--report``: then the report's read of the last sweep's folder (:func:`tlm.report.collect.read`: every
point's ``results.json`` and ``config.resolved.yaml``), ``--repeat`` times with libyaml's parser and as many
with PyYAML's own (alternating), its CPU a point each way and whether the two reads are the same.

    python benchmarks/bench_sweep_points.py [--points 100|200] [--repeat 2] [--report]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import yaml

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"spp": 1, "light_samples": 1},
        "arch": {"trace": False}}
HOST = ["seconds.functional", "seconds.simulate", "seconds.one_off", "seconds.write", "functional_cached"]


def sweep_file(folder: Path, points: int) -> Path:
    misses = {100: [0, 6, 12, 24, 48], 200: [0, 3, 6, 9, 12, 18, 24, 36, 48, 64]}
    if points not in misses:
        raise SystemExit(f"--points: {points} is not 100 or 200")
    path = folder / f"sweep{points}.yaml"
    path.write_text(yaml.safe_dump({
        "description": f"{points} arch-only points", "base": BASE,
        "grid": {"arch.packet_size": [1, 16, 64, 256], "arch.fifo_depth": [1, 4, 16, 256, 1024],
                 "arch.page_miss_cycles": misses[points]}}, sort_keys=False))
    return path


def memos(on: bool) -> None:
    """The two memos at their size (on) or at 0 (off), emptied."""
    import tlm.arch.costs as costs
    import tlm.experiments.frames as frames

    for mod, size in ((frames, 8), (costs, 8)):
        mod.MEMO_SIZE = size if on else 0
    frames._SCENE_KEYS.clear()
    costs._MEMO.clear()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=100)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--report", action="store_true", help="time the report's read of the sweep's folder too")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        os.environ["TLM_CACHE"] = str(Path(tmp) / "cache")
        from tlm.experiments.sweep import run_sweep

        path = sweep_file(Path(tmp), args.points)
        run_sweep(path, Path(tmp) / "warm", jobs=1)  # (renders the frame; compiles the kernels)
        cpu: dict[bool, list[float]] = {True: [], False: []}
        rows: dict[bool, object] = {}
        for i in range(args.repeat):
            for on in (True, False):
                memos(on)
                c0 = time.process_time()
                out = run_sweep(path, Path(tmp) / f"run{i}_{'memo' if on else 'plain'}", jobs=1)
                per_point = (time.process_time() - c0) / args.points
                cpu[on].append(per_point)
                rows[on] = out.table.drop(columns=[c for c in HOST if c in out.table])
                print(f"run {i + 1} {'with' if on else 'without'} the memos: {per_point * 1e3:7.1f} ms CPU a point "
                      f"({out.ok} points ok)", flush=True)
        memos(True)
        with_, without = statistics.median(cpu[True]), statistics.median(cpu[False])
        print(f"median CPU a point: {with_ * 1e3:.1f} ms with the memos, {without * 1e3:.1f} ms without: "
              f"{without / with_:.2f}x")
        print(f"same rows both ways: {rows[True].equals(rows[False])}")
        if args.report:
            report_read(Path(tmp) / f"run{args.repeat - 1}_plain", args.points, args.repeat)


def report_read(folder: Path, points: int, repeat: int) -> None:
    """The report's read of the sweep ``folder``: CPU a point with libyaml's parser and with PyYAML's own."""
    import tlm.report.checks as checks
    from tlm.report.collect import read

    libyaml = checks._C_LOADER
    cpu: dict[bool, list[float]] = {True: [], False: []}
    got: dict[bool, object] = {}
    for i in range(repeat):
        for c in (True, False) if libyaml is not None else (False,):
            checks._C_LOADER = libyaml if c else None
            c0 = time.process_time()
            inputs = read([folder])
            cpu[c].append((time.process_time() - c0) / points)
            got[c] = [(r.path, r.results, r.config) for r in inputs.sweeps[0].runs] if inputs.sweeps else None
            print(f"report read {i + 1} with {'libyaml' if c else 'PyYAML'}: {cpu[c][-1] * 1e3:6.2f} ms CPU a point",
                  flush=True)
    checks._C_LOADER = libyaml
    if libyaml is not None:
        fast, slow = statistics.median(cpu[True]), statistics.median(cpu[False])
        print(f"median report read a point: {fast * 1e3:.2f} ms with libyaml, {slow * 1e3:.2f} ms with PyYAML: "
              f"{slow / fast:.2f}x; same read both ways: {got[True] == got[False]}")


if __name__ == "__main__":
    main()
