"""A run's host-side writes: trace.json and the .npz files, each against the way tlm wrote them before.

Renders a frame (``configs/cornell_pmap.yaml`` at 128x128 unless told), simulates it, then
times in this process, alternating the two ways ``--repeat`` times (CPU seconds,
``time.process_time``, the median of each; the machine's load changes the wall time more):

* ``trace.json``: ``Trace.write`` (each slice's event spelt out) against the writer it replaced
  (each event's dict made and dumped with ``json_text``, kept below as ``old_write``), each on a
  fresh copy of the trace (its work slices not read yet, as a run's first write finds them);
  the two files must be the same bytes;
* ``aov/primary.npz``, ``aov/work.npz`` and the functional cache's entry: ``save_npz`` (zlib
  level 1) against ``np.savez_compressed`` (level 6); the arrays read back must be the same.

PASS/FAIL (exit status 1 on a FAIL): trace.json at least 2x faster and the same bytes; each
``.npz`` faster and the same arrays.

    python benchmarks/bench_writes.py [--config configs/cornell_pmap.yaml] [--set resolution=[128,128]]
        [--repeat 5]
"""

from __future__ import annotations

import argparse
import io
import json
import statistics
import tempfile
import time
from pathlib import Path

import numpy as np


def old_write(trace, path: Path, clock_hz) -> None:
    """``Trace.write`` as it was: each event's dict (``Trace.to_json``'s) through ``json_text``."""
    from tlm.storage import json_text, write_atomic

    events, rest = trace._document(clock_hz, None)
    with write_atomic(path, "w") as fh:
        fh.write('{"traceEvents": [')
        sep, chunk = "", []
        for ev in events:
            chunk.append(json_text(ev))
            if len(chunk) == 4096:
                fh.write(sep + ", ".join(chunk))
                sep, chunk = ", ", []
        if chunk:
            fh.write(sep + ", ".join(chunk))
        fh.write("]")
        for key, value in rest.items():
            fh.write(f", {json.dumps(key)}: {json_text(value)}")
        fh.write("}")


def fresh(trace):
    """A copy of ``trace`` with its slices as the simulation left them (work slices' args unread)."""
    from tlm.arch.units import Trace

    copy = Trace()
    copy.__dict__.update(trace.__dict__, _flat=list(trace._flat))
    return copy


def timed(fn) -> float:
    c0 = time.process_time()
    fn()
    return time.process_time() - c0


def same_arrays(a: bytes, b: bytes) -> bool:
    with np.load(io.BytesIO(a), allow_pickle=False) as x, np.load(io.BytesIO(b), allow_pickle=False) as y:
        return x.files == y.files and all(x[k].dtype == y[k].dtype and x[k].shape == y[k].shape
                                          and np.array_equal(x[k], y[k], equal_nan=True) for k in x.files)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", default="configs/cornell_pmap.yaml")
    ap.add_argument("--set", action="append", default=None, help="a config override (default resolution=[128,128])")
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()

    from tlm.arch.functional import save_npz
    from tlm.config import load_config
    from tlm.experiments.run import programs_for, render, simulate_render

    cfg, base = load_config(Path(args.config), args.set or ["resolution=[128,128]"])
    t0 = time.perf_counter()
    res = simulate_render(render(cfg, base), programs_for(cfg, base))
    trace, hz = res.timing.trace, cfg.arch.clock_hz
    n = len(trace._flat) // 8
    print(f"{args.config} {args.set or ['resolution=[128,128]']}: rendered and simulated in "
          f"{time.perf_counter() - t0:.1f} s; {n} slices on {len(trace.rows)} rows", flush=True)

    h, w = res.scene.camera.height, res.scene.camera.width
    p = res.primary
    files = {"aov/primary.npz": {"origin": p.origin.reshape(h, w, 3), "direction": p.direction.reshape(h, w, 3),
                                 "t": p.t.reshape(h, w), "triangle": p.triangle.reshape(h, w),
                                 "normal": p.normal.reshape(h, w, 3)},
             "aov/work.npz": {f"{q}.{k}": v for q, counts in res.work.items() for k, v in counts.items()}}
    with tempfile.TemporaryDirectory() as tmp:  # (the functional cache's entry: the arrays Functional.save writes)
        res.functional().save(Path(tmp) / "f.npz")
        with np.load(Path(tmp) / "f.npz", allow_pickle=False) as z:
            files["functional entry"] = {k: z[k] for k in z.files}

    failed = False
    with tempfile.TemporaryDirectory() as tmp:
        old_path, new_path = Path(tmp) / "old.json", Path(tmp) / "new.json"
        t_old, t_new, same = [], [], True
        for _ in range(args.repeat):
            a, b = fresh(trace), fresh(trace)
            t_old.append(timed(lambda a=a: old_write(a, old_path, hz)))
            t_new.append(timed(lambda b=b: b.write(new_path, hz)))
            same &= old_path.read_bytes() == new_path.read_bytes()
        o, m = statistics.median(t_old), statistics.median(t_new)
        ok = same and o >= 2 * m
        failed |= not ok
        print(f"{'PASS' if ok else 'FAIL'} trace.json ({new_path.stat().st_size / 1e6:.1f} MB, {n} slices): before "
              f"{o:.3f} s ({o / n * 1e6:.2f} us a slice), after {m:.3f} s ({m / n * 1e6:.2f} us): {o / m:.2f}x "
              f"(bar: 2x); same bytes: {same}", flush=True)

        for name, arrays in files.items():
            raw = sum(np.asarray(v).nbytes for v in arrays.values())
            t_old, t_new, r_old, r_new, sizes, same = [], [], [], [], {}, True
            for _ in range(args.repeat):
                bufs = {"old": io.BytesIO(), "new": io.BytesIO()}
                t_old.append(timed(lambda f=bufs["old"], a=arrays: np.savez_compressed(f, **a)))
                t_new.append(timed(lambda f=bufs["new"], a=arrays: save_npz(f, a)))
                sizes = {k: len(f.getvalue()) for k, f in bufs.items()}
                same &= same_arrays(bufs["old"].getvalue(), bufs["new"].getvalue())
                r_old.append(timed(lambda f=bufs["old"]: same_arrays(f.getvalue(), f.getvalue())))
                r_new.append(timed(lambda f=bufs["new"]: same_arrays(f.getvalue(), f.getvalue())))
            o, m = statistics.median(t_old), statistics.median(t_new)
            ok = same and o > m
            failed |= not ok
            print(f"{'PASS' if ok else 'FAIL'} {name} ({raw / 1e6:.2f} MB raw): savez_compressed {o:.3f} s, "
                  f"{sizes['old'] / 1e3:.0f} KB; save_npz {m:.3f} s, {sizes['new'] / 1e3:.0f} KB: {o / m:.2f}x; "
                  f"same arrays: {same}; "
                  f"read back twice {statistics.median(r_old):.3f} s and {statistics.median(r_new):.3f} s",
                  flush=True)
    raise SystemExit(1 if failed else 0)


if __name__ == "__main__":
    main()
