"""Peak resident memory of the Cornell photon-map frame: ``tlm run configs/cornell_pmap.yaml``.

Runs the command (320 x 320 pixels, 120,000 photons, all four passes, the timing model
and the report) in a fresh interpreter and reads its peak resident set size from the
kernel (``os.wait4``'s ``ru_maxrss``), once as is and once with ``--no-report``.
Prints PASS/FAIL against the bar of issue [7 of 7]: at most 2 GiB. Exits 1 if the
bar fails.

    python benchmarks/bench_memory.py [--config configs/cornell_pmap.yaml] [--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from timing import exit_status, verdict

BAR_BYTES = 2 * 1024**3
ROOT = Path(__file__).resolve().parents[1]


def peak_rss(cmd: list[str], env: dict) -> tuple[int, float]:
    """Peak RSS in bytes (Linux reports kilobytes) and wall seconds of ``cmd``."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, cwd=ROOT, stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} exited with {proc.returncode}")
    return usage.ru_maxrss * 1024, wall


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "cornell_pmap.yaml")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="passed to tlm run")
    args = ap.parse_args()
    sets = [a for kv in args.set for a in ("--set", kv)]
    rows = []
    for label, extra in (("tlm run (with its report)", []), ("tlm run --no-report", ["--no-report"])):
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, TLM_CACHE=str(Path(tmp) / "cache"))
            cmd = [sys.executable, "-m", "tlm", "run", str(args.config), "--out", str(Path(tmp) / "run"),
                   *sets, *extra]
            rows.append((label, *peak_rss(cmd, env)))
    print(f"{args.config.name}{' ' + ' '.join(args.set) if args.set else ''}:")
    for label, rss, wall in rows:
        print(f"  {label:28s} peak RSS {rss / 2**20:8.0f} MiB   {wall:6.1f} s wall")
    worst = max(r[1] for r in rows)
    verdict(worst <= BAR_BYTES, f"peak resident memory {worst / 2**20:.0f} MiB "
            f"(bar: at most {BAR_BYTES / 2**30:.0f} GiB)")
    exit_status()


if __name__ == "__main__":
    main()
