"""Host wall time of the whole thesis reproduction, cold: ``tlm thesis configs/thesis.yaml``.

Runs the command a user types (3 scenes x 4 modes, one pipeline; Tables I-III, the
comparison CSV and the report) in a fresh interpreter with an empty functional cache
(``TLM_CACHE`` a new temporary folder), and once more with ``--no-report``. The wall
time includes the interpreter's start and every import. The compiled kernel is loaded
from numba's on-disk cache as after any first run; ``--cold-jit`` also points
``NUMBA_CACHE_DIR`` at an empty folder, so that the run compiles it (what the very
first run after an install pays). Prints PASS/FAIL against the bar of issue [7 of 7]:
at most 30 s for the command with its report. Exits 1 if the bar fails.

    python benchmarks/bench_thesis.py [--config configs/thesis.yaml] [--cold-jit]
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

BAR_SECONDS = 30.0
ROOT = Path(__file__).resolve().parents[1]


def timed_run(config: Path, folder: Path, extra: list[str], cold_jit: bool) -> float:
    env = dict(os.environ, TLM_CACHE=str(folder / "cache"))
    if cold_jit:
        env["NUMBA_CACHE_DIR"] = str(folder / "numba")
    cmd = [sys.executable, "-m", "tlm", "thesis", str(config), "--out", str(folder / "out"), *extra]
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, cwd=ROOT, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "configs" / "thesis.yaml")
    ap.add_argument("--cold-jit", action="store_true", help="also compile the numba kernel (empty numba cache)")
    args = ap.parse_args()
    rows = []
    for label, extra in (("tlm thesis (with its report)", []), ("tlm thesis --no-report", ["--no-report"])):
        with tempfile.TemporaryDirectory() as tmp:
            rows.append((label, timed_run(args.config, Path(tmp), extra, args.cold_jit)))
    jit = "compiled in the run (empty numba cache)" if args.cold_jit else "loaded from numba's cache"
    print(f"{args.config.name}, empty functional cache, compiled kernel {jit}:")
    for label, s in rows:
        print(f"  {label:32s} {s:7.1f} s wall")
    wall = rows[0][1]
    verdict(wall <= BAR_SECONDS, f"the thesis reproduction took {wall:.1f} s (bar: at most {BAR_SECONDS:.0f} s)")
    exit_status()


if __name__ == "__main__":
    main()
