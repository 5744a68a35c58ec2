"""How much of a render holds Python's interpreter lock (GIL), and where: the bound on threads.

A render's batches run at once on ``render.threads`` threads (:mod:`tlm.kernels.threads`);
the compiled kernels release the GIL, the Python and small-array numpy between them do
not. If a share ``g`` of one thread's render holds the GIL, ``N`` threads render at most
``1 / (g + (1 - g) / N)`` times faster than one (Amdahl's law over the lock), and waiting
for the lock costs more as ``N`` grows. On 16 cores (benchmarks/README.md, "16 cores")
cornell_pmap ran 3.91x faster at 8 threads and 2.43x at 16.

The bench samples a one-thread render with py-spy (``pip install py-spy``) twice, in this
one run: every sample of the render's thread, and only the samples where it holds the
GIL (``py-spy record --gil``). It prints the GIL-held share of the render (the samples
under ``render_batches``: the batches, what runs on the threads; the scene load, BSP
build and photon trace before them are left out), the speed-up bound it sets at 2, 4, 8
and 16 threads, and the tlm functions that hold the GIL most (the innermost tlm frame of
each sample and its caller). The batches are cut as ``--threads`` threads would cut them
(``render.batch_rays`` over ``2 x threads``, as :func:`tlm.render.batches.batches_for`
does; default 16): the smaller the batches, the larger the share of their fixed cost.

    python benchmarks/bench_gil.py [--config configs/cornell_pmap.yaml] [--resolution 160 160]
                                   [--threads 16] [--rate 200] [--top 20]

py-spy samples wall time: a thread that holds the GIL while the machine runs other work
counts as holding it all the while, so the share means something only on a quiet machine
(with other jobs on the machine it reads high). The shares of two quiet runs differ by a few hundredths
(sampling); compare trees in one session, alternating.
"""

from __future__ import annotations

import argparse
import collections
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_RENDER = """
import sys
from pathlib import Path
from tlm.config import load_config
from tlm.experiments.run import render
from tlm.render.batches import batches_for

config, width, height, threads = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
cfg, base = load_config(Path(config), ["resolution=[8,8]", "render.threads=1"])
render(cfg, base)  # (loads the compiled kernels and the scene cache)
cfg, base = load_config(Path(config), [f"resolution=[{width},{height}]", "render.threads=1"])
cuts = batches_for(width * height, cfg.render.spp, cfg.render.batch_rays, threads)
rays = max(s.stop - s.start for s in cuts) * cfg.render.spp
cfg, base = load_config(Path(config), [f"resolution=[{width},{height}]", "render.threads=1",
                                       f"render.batch_rays={rays}"])
print(f"{len(cuts)} batches of up to {rays} eye rays (as {threads} threads cut them), on one thread")
render(cfg, base)
"""


def samples(raw: Path) -> tuple[int, collections.Counter]:
    """The samples under ``render_batches`` in a py-spy raw file, and their count by the
    innermost tlm frame and its caller."""
    total = 0
    where: collections.Counter = collections.Counter()
    for line in raw.read_text().splitlines():
        stack, _, n = line.rpartition(" ")
        frames = stack.split(";")
        if not any(f.startswith("render_batches ") for f in frames):
            continue
        total += int(n)
        tlm = [f.split(" (")[0] for f in frames if "tlm/" in f]
        where[" < ".join(reversed(tlm[-2:]))] += int(n)
    return total, where


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "cornell_pmap.yaml")
    ap.add_argument("--resolution", type=int, nargs=2, default=[160, 160], metavar=("W", "H"))
    ap.add_argument("--threads", type=int, default=16, help="cut the batches as this many threads would")
    ap.add_argument("--rate", type=int, default=200, help="py-spy samples a second")
    ap.add_argument("--top", type=int, default=20)
    a = ap.parse_args()
    spy = shutil.which("py-spy")
    if spy is None:
        raise SystemExit("bench_gil.py: py-spy is not installed (python -m pip install py-spy)")
    with tempfile.TemporaryDirectory(prefix="bench-gil-") as tmp:
        script = Path(tmp) / "render_one.py"
        script.write_text(_RENDER)
        got = {}
        for kind, extra in (("all", []), ("gil", ["--gil"])):
            raw = Path(tmp) / f"{kind}.txt"
            run = subprocess.run([spy, "record", *extra, "-r", str(a.rate), "-f", "raw", "-o", str(raw), "--",
                                  sys.executable, str(script), str(a.config), *map(str, a.resolution), str(a.threads)],
                                 cwd=ROOT, capture_output=True, text=True)
            if run.returncode != 0 or not raw.exists():
                raise SystemExit(f"bench_gil.py: py-spy failed ({run.returncode}): {run.stderr.strip()[-500:]}")
            if kind == "all":
                print(run.stdout.strip())
            got[kind] = samples(raw)
    (every, _), (held, where) = got["all"], got["gil"]
    share = held / max(every, 1)
    print(f"{a.config.name} {a.resolution[0]}x{a.resolution[1]}: {every} samples of the batches at {a.rate} Hz, "
          f"{held} holding the GIL: GIL-held share {share:.3f}")
    bounds = ", ".join(f"{n} threads {1.0 / (share + (1.0 - share) / n):.2f}x" for n in (2, 4, 8, 16))
    print(f"the most N threads can gain over one with that share (Amdahl): {bounds}")
    print("the tlm functions that hold the GIL most (samples, share of the held samples; innermost < caller):")
    for name, n in where.most_common(a.top):
        print(f"  {n:6d} {n / max(held, 1):6.1%}  {name}")


if __name__ == "__main__":
    main()
