"""CPU seconds per point of an arch-only sweep, with and without the in-process memos.

Writes in a temporary folder a sweep of Cornell RCast at 16x16 (an inline base config,
one sample per pixel, one light sample, no trace) whose points differ only in ``arch``:
``arch.packet_size`` x ``arch.fifo_depth`` x ``arch.page_miss_cycles`` (4 x 5 x 5 = 100
points; ``--points 200`` takes 10 page-miss values), so every point shares one frame.
A first sweep renders that frame into the functional cache (and compiles the kernels); then
the same sweep runs ``--repeat`` times with the memos and as many times without them
(alternating, each into a fresh output folder, ``--jobs 1``, in this process). The memos are
the scene's fingerprint of a frame's key (:func:`tlm.experiments.frame_keys.scene_key`) and the
programs table (:func:`tlm.arch.costs.load_programs`); "without" sets both memos' size to 0,
so every point loads the scene and parses the table again, as tlm did before them. Prints
the CPU seconds (``time.process_time``: the machine's load changes the wall time more) per
point of each run, the median of each way, their ratio, and whether the two ways gave the
same rows (``sweep.csv`` less the host seconds and ``functional_cached``).

``--report``: then the report's read of the last sweep's folder (:func:`tlm.report.collect.read`: every
point's ``results.json`` and ``config.resolved.yaml``), ``--repeat`` times with libyaml's parser and as many
with PyYAML's own (alternating), its CPU a point each way and whether the two reads are the same.

``--fresh N``: then the whole cached sweep as a command, ``N`` times, each in a fresh interpreter
(:func:`tlm.cli.main` ``sweep FILE --jobs 1 --no-progress --no-report``: its imports and fixed costs
included, which the in-process runs above share): the child's CPU seconds (user + sys) and whether it
imported numba (a sweep whose frames are all cached runs no kernel: since 2026-12-01 it imports none).
``--against DIR``: those commands alternated with the ``tlm`` of another copy of the repository
(``DIR/tlm`` first on ``PYTHONPATH``: the code before a change), whose code has frames of its own in
the cache (one warm-up sweep each first).

    python benchmarks/bench_sweep_points.py [--points 100|200] [--repeat 2] [--report] [--fresh N [--against DIR]]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
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

    try:  # (the scene-key memo's module since h487; an older tree's: frames)
        import tlm.experiments.frame_keys as frames
    except ImportError:
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
    ap.add_argument("--fresh", type=int, default=0, metavar="N",
                    help="time N cached sweeps as commands, each in a fresh interpreter")
    ap.add_argument("--against", type=Path, default=None, metavar="DIR",
                    help="with --fresh: alternate with the tlm of another copy of the repository")
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
        if args.fresh:
            fresh(path, Path(tmp), args.fresh, args.against)


# a cached sweep as `tlm sweep` runs it, in a fresh interpreter; prints whether numba was imported
SWEEP = ("import sys\nfrom tlm.cli import main\n"
         "status = main(['sweep', sys.argv[1], '--out', sys.argv[2], '--jobs', '1', '--no-progress', '--no-report'])\n"
         "print('numba' in sys.modules)\nsys.exit(status)\n")


def _command(root: Path, path: Path, out: Path) -> tuple[float, float, bool]:
    """One sweep in a fresh interpreter with ``root``'s tlm: its CPU seconds (user + sys), wall seconds,
    and whether it imported numba."""
    paths = [str(root), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(paths)}
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    # (in the sweep's folder: ``python -c`` puts the working folder first on sys.path, before PYTHONPATH)
    done = subprocess.run([sys.executable, "-c", SWEEP, str(path), str(out)], capture_output=True, text=True,
                          env=env, cwd=path.parent, check=False)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:  # (a failed point says why on stdout, the sweep exits 1: both said)
        said = "\n".join(text.strip()[-2000:] for text in (done.stdout, done.stderr) if text.strip())
        raise SystemExit(f"the sweep with {root}/tlm failed (exit status {done.returncode}): "
                         f"{said or 'it said nothing'}")
    cpu = after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
    return cpu, wall, done.stdout.split()[-1] == "True"


def fresh(path: Path, tmp: Path, n: int, against: Path | None) -> None:
    """``n`` cached sweeps of ``path``, each a command in a fresh interpreter, with this tlm (and ``against``'s,
    alternated): CPU and wall seconds each, whether numba was imported, the median CPU each way."""
    here = Path(__file__).resolve().parents[1]
    trees = {"this": here, **({"against": against.resolve()} if against is not None else {})}
    for name, root in trees.items():  # (the other tree's code: its frames are its own in the cache)
        _command(root, path, tmp / f"fresh_warm_{name}")
    cpu: dict[str, list[float]] = {name: [] for name in trees}
    for i in range(n):
        for name, root in trees.items():
            c, w, numba = _command(root, path, tmp / f"fresh{i}_{name}")
            cpu[name].append(c)
            print(f"fresh sweep {i + 1} ({name} tlm): {c:5.2f} s CPU, {w:5.2f} s wall, numba imported: {numba}",
                  flush=True)
    print("median CPU of a cached sweep as a command: "
          + ", ".join(f"{statistics.median(v):.2f} s ({name} tlm)" for name, v in cpu.items()))


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
