"""The report of a Quick-start run: its time against the run's and against one bare figure.

The Quick-start (README.md) is ``tlm run configs/cornell.yaml``: a render, its simulation
and, at the end, the report (``OUT/report``: figures and ``report.html``). This bench writes
that run folder once (``tlm run CONFIG --no-report``; ``--set KEY=VALUE``, repeatable, passed
on to it: ``--set resolution=[48,48]`` for a small run, whose report costs about as much as
the run), then times, in ``--repeat`` rounds, each command in a fresh interpreter:

* ``tlm run CONFIG --no-report`` (with an empty ``TLM_CACHE`` of its own, as a first
  Quick-start has): the run without its report, the reference;
* the report as a run writes it: an interpreter that has just run ``tlm run CONFIG
  --no-report`` itself (:func:`tlm.cli.main`, with what a run leaves in the process: its
  compiled kernels, scene and caches, tens of thousands of objects for the garbage collector
  to scan) times :func:`tlm.api.write_report` of that run folder (matplotlib's import and the
  first uses of fonts and parsers included, as at the end of a run); with ``--run DIR``, an
  interpreter that has imported what ``tlm run`` imports, of DIR;
* ``tlm report RUN``: the report as a command of its own, all its imports included;

and, in this process, :func:`tlm.report.build_report` of the folder after a first build (the
report's own work) beside matplotlib's bare cost of one figure (an empty axes on a
``new_figure()`` saved with ``savefig`` at the report's DPI), one after the other in each
round, and each section's part of the build (the folder read afresh in each round and the
parts run in one :func:`tlm.experiments.provenance.identities_remembered` scope, as a build
runs them: the first part to judge a thesis cell computes its scene files' identities).

Each time is given as wall seconds and CPU seconds (the process's, or the child's), the best
of the rounds; each ratio is the median over the rounds of that round's ratio of CPU seconds
(on a machine shared with other work the wall time also measures the others' load; the
slow spells fall on both of a pair). ``--against DIR`` also times the two report commands
with the ``tlm`` of another copy of the repository (``DIR/tlm`` first on ``PYTHONPATH``:
the code before a change), alternated with this one's. No bar: the figures are for
reading (benchmarks/README.md).

    python benchmarks/bench_report.py [--config configs/cornell.yaml] [--set KEY=VALUE ...] [--repeat 3]
        [--run DIR] [--against DIR]
"""

from __future__ import annotations

import argparse
import importlib
import os
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
# the report's parts, in its order (tlm.report.sections, then the first screen)
PARTS = ("tables", "images", "scaling", "sweeps", "cycles", "tradeoff", "peers", "extreme", "provenance", "summary")
# the report as 'tlm run' writes it at its end: after the run (argv[3:], 'tlm run' less its --out; none:
# after the run's imports alone), in the same process
AS_IN_A_RUN = """import sys, time
from pathlib import Path
import tlm.api, tlm.cli, tlm.experiments.run
if sys.argv[3:] and tlm.cli.main(["run", *sys.argv[3:], "--out", sys.argv[1]]) != 0:
    raise SystemExit("the run failed")
t0, c0 = time.perf_counter(), time.process_time()
tlm.api.write_report([Path(sys.argv[1])], Path(sys.argv[2]))
print(time.perf_counter() - t0, time.process_time() - c0)
"""


def _env(code: Path, cache: Path | None = None) -> dict[str, str]:
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(code), *filter(None, [os.environ.get("PYTHONPATH")])])}
    if cache is not None:
        env["TLM_CACHE"] = str(cache)
    return env


def _children_cpu() -> float:
    use = resource.getrusage(resource.RUSAGE_CHILDREN)
    return use.ru_utime + use.ru_stime


def timed(argv: list[str], cache: Path, code: Path = ROOT) -> tuple[float, float]:
    """Wall and CPU seconds of ``python ARGV`` in a fresh interpreter with the ``tlm`` of the
    repository ``code`` and ``TLM_CACHE=cache`` (emptied first); for ``-c``, the two the code prints."""
    shutil.rmtree(cache, ignore_errors=True)
    t0, c0 = time.perf_counter(), _children_cpu()
    # (in the cache's folder: 'python -m' puts its working folder first on sys.path)
    done = subprocess.run([sys.executable, *argv], cwd=cache.parent, env=_env(code, cache), capture_output=True,
                          text=True)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - c0
    if done.returncode != 0:
        raise SystemExit(f"python {' '.join(argv)}: exit status {done.returncode}\n{done.stderr}")
    if argv[0] == "-c":
        wall, cpu = map(float, done.stdout.split()[-2:])
    return wall, cpu


def in_process(fn) -> tuple[float, float]:
    """Wall and CPU seconds of ``fn()`` in this process."""
    t0, c0 = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - t0, time.process_time() - c0


def package(code: Path) -> Path:
    """The tlm package a fresh interpreter imports with the repository ``code`` first on PYTHONPATH."""
    done = subprocess.run([sys.executable, "-c", "import tlm; print(tlm.__file__)"], cwd=tempfile.gettempdir(),
                          env=_env(code), capture_output=True, text=True, check=True)
    return Path(done.stdout.strip()).parent


def empty_figure(path: Path) -> None:
    """matplotlib's bare cost: one empty axes on the report's figure, saved as savefig saves it."""
    from tlm.report.common import DPI, new_figure

    fig = new_figure()
    fig.add_subplot()
    fig.savefig(path, dpi=DPI)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "cornell.yaml")
    ap.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                    help="passed on to 'tlm run' (repeatable): --set 'resolution=[48,48]' for a small run")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--run", type=Path, help="the report of this run folder; no 'tlm run' is timed")
    ap.add_argument("--against", type=Path, help="another copy of the repository whose tlm is timed too")
    args = ap.parse_args()
    if args.against is not None and not (args.against / "tlm" / "report").is_dir():
        raise SystemExit(f"--against: {args.against} has no tlm/report")

    sys.path.insert(0, str(ROOT))  # (this repository's tlm, in this process too)
    import tlm.report
    from tlm.experiments.provenance import identities_remembered
    from tlm.report.collect import read
    from tlm.report.common import DPI

    codes = {"this": ROOT} | ({"against": args.against.resolve()} if args.against else {})
    print(f"timing {package(ROOT)}" + (f" against {package(codes['against'])}" if args.against else "")
          + f" ({args.repeat} rounds; {os.cpu_count()} CPUs)")
    t: dict[str, list[tuple[float, float]]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cache = tmp / "cache"
        config = str(args.config.resolve())
        run = args.run.resolve() if args.run else tmp / "run"
        sets = [a for kv in args.overrides for a in ("--set", kv)]
        if args.run is None:
            timed(["-m", "tlm", "run", config, *sets, "--out", str(run), "--no-progress", "--no-report"], cache)
        os.environ["TLM_CACHE"] = str(cache)
        tlm.report.build_report([run], tmp / "first")  # (the first uses of fonts and parsers: not the build's)
        n_fig = len(list((tmp / "first").glob("*.png")))
        for i in range(args.repeat):
            if args.run is None:
                t.setdefault("run", []).append(timed(["-m", "tlm", "run", config, *sets, "--out",
                                                      str(tmp / f"run{i}"), "--no-progress", "--no-report"], cache))
            for name, code in (codes.items() if i % 2 == 0 else reversed(codes.items())):
                ran = [] if args.run else [config, *sets, "--no-progress", "--no-report"]  # (its own run first)
                shutil.rmtree(tmp / "ran", ignore_errors=True)
                t.setdefault(f"in_run {name}", []).append(timed(
                    ["-c", AS_IN_A_RUN, str(tmp / "ran" if ran else run), str(tmp / "in_run"), *ran], cache, code))
                t.setdefault(f"command {name}", []).append(timed(["-m", "tlm", "report", str(run), "--out",
                                                                  str(tmp / "command")], cache, code))
            t.setdefault("figure", []).append(min((in_process(lambda: empty_figure(tmp / "empty.png"))
                                                   for _ in range(3)), key=lambda wc: wc[1]))
            t.setdefault("build", []).append(in_process(lambda: tlm.report.build_report([run], tmp / "again")))
        for _ in range(args.repeat):
            inputs = read([run])  # (afresh each round, as a build reads it: no section's memo carried over)
            with identities_remembered():  # (as in a build: one scope for all its parts)
                for name in PARTS:
                    out = tmp / f"part_{name}"
                    out.mkdir(exist_ok=True)
                    make = getattr(importlib.import_module(f"tlm.report.{name}"), f"{name}_section")
                    t.setdefault(f"part {name}", []).append(
                        in_process(lambda make=make, out=out, inputs=inputs: make(inputs, out)))

    def best(key: str) -> str:
        return f"{min(w for w, _ in t[key]):6.2f} s wall {min(c for _, c in t[key]):6.2f} s CPU"

    def ratio(a: str, b: str) -> float:  # (of CPU seconds)
        return statistics.median(x[1] / y[1] for x, y in zip(t[a], t[b], strict=True))

    what = run if args.run else " ".join(["tlm run", args.config.name, *(f"--set {kv}" for kv in args.overrides)])
    print(f"the report of {what}: {n_fig} figures at {DPI} DPI")
    print("each in a fresh interpreter (best of the rounds; ratios of CPU seconds, the median of the rounds'):")
    if args.run is None:
        print(f"  tlm run --no-report                  {best('run')}   (the reference)")
    for key, what in (("in_run", "the report, as at the end of a run"), ("command", "tlm report RUN")):
        line = f"  {what:36s} {best(f'{key} this')}"
        if args.run is None:
            line += f"   {ratio(f'{key} this', 'run'):.2f} x the run"
        print(line)
        if args.against:
            print(f"    against                            {best(f'{key} against')}   this / against "
                  f"{ratio(f'{key} this', f'{key} against'):.2f}")
    print("in this process:")
    print(f"  one empty figure saved               {best('figure')}   (matplotlib's bare cost of a figure)")
    print(f"  build_report, after a first build    {best('build')}   = {ratio('build', 'figure'):.1f} empty figures")
    for name in PARTS:
        print(f"    {name:34s} {best(f'part {name}')}")


if __name__ == "__main__":
    main()
