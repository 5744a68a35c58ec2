"""A sweep on a Dask scheduler's worker: points that size their threads against points that
each take every CPU of the machine.

Starts a Dask scheduler and one worker of ``--slots`` task slots (default: the CPUs
available) on this machine, as a remote cluster's would run, then runs ``tlm sweep
--dask tcp://...`` of ``--points`` photon-map renders of the Cornell box, ``--repeat``
rounds, alternating two sweeps that differ only in ``render.threads``:

* ``null``: each point sizes its threads on the worker
  (:func:`tlm.experiments.dask_workers.dask_worker_threads`: the machine's CPUs over the
  task slots of its workers, here ``CPUs // slots``);
* the CPU count: what every point took before that, whatever the worker's slots
  (``slots`` points at once, each on every CPU).

An untimed sweep first loads tlm and its compiled kernels in the worker. Every sweep
renders points of its own (seeds that no other sweep of the run uses), so none reads
another's cached render. Prints each sweep's wall seconds and the median
ratio of the rounds. Measures speed only; the images do not depend on the threads.

    python benchmarks/bench_dask_threads.py [--slots N] [--points 6] [--repeat 3] [--resolution 96]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from tlm.kernels.threads import available


def scheduler_address(file: Path, scheduler: subprocess.Popen, log: Path, timeout: float = 120.0) -> str:
    """The address the scheduler bound (``--port 0``: a free port, chosen by the scheduler itself
    when it binds, so no other process can take it in between), read from its scheduler file.
    A scheduler that exits first, or writes no address in ``timeout`` seconds, stops the bench
    with the last lines of its ``log`` (which goes with the bench's temporary folder)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if scheduler.poll() is not None:
            raise SystemExit(f"the Dask scheduler exited ({scheduler.returncode}) before it wrote {file}:\n"
                             + _tail(log))
        try:
            return json.loads(file.read_text())["address"]
        except (FileNotFoundError, json.JSONDecodeError, KeyError):  # (not written yet, or half written)
            time.sleep(0.2)
    raise SystemExit(f"the Dask scheduler wrote no address to {file} in {timeout:.0f} s:\n" + _tail(log))


def _tail(log: Path, lines: int = 20) -> str:
    try:
        return "\n".join(log.read_text(errors="replace").splitlines()[-lines:])
    except OSError as e:
        return f"(its log {log} cannot be read: {e})"


def sweep_file(folder: Path, name: str, threads: int | None, seeds: list[int], resolution: int) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump({
        "base": {"scene": "cornell", "mode": "pmap", "resolution": [resolution, resolution],
                 "photons": {"count": 20000}, "render": {"threads": threads}, "arch": {"frames": 1, "trace": False}},
        "grid": {"seed": seeds}}, sort_keys=False))
    return path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--slots", type=int, default=available(), help="the worker's task slots (default: the CPUs)")
    ap.add_argument("--points", type=int, default=6)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--resolution", type=int, default=96)
    args = ap.parse_args()
    if min(args.slots, args.points, args.repeat, args.resolution) < 1:
        ap.error("--slots, --points, --repeat and --resolution must be >= 1")
    cpus = available()
    with tempfile.TemporaryDirectory(prefix="tlm-dask-bench-") as tmp:
        folder = Path(tmp)
        env = {**os.environ, "TLM_CACHE": str(folder / "cache")}  # (the worker's cache: this run's alone)
        log = open(folder / "cluster.log", "w")  # noqa: SIM115 (open while the cluster runs)
        file = folder / "scheduler.json"
        # (port 0 for the scheduler and for its HTTP server, which --no-dashboard still starts: no fixed port)
        daemons = [subprocess.Popen(["dask", "scheduler", "--host", "127.0.0.1", "--port", "0", "--scheduler-file",
                                     str(file), "--no-dashboard", "--dashboard-address", "127.0.0.1:0"],
                                    stdout=log, stderr=subprocess.STDOUT, env=env)]
        try:
            address = scheduler_address(file, daemons[0], folder / "cluster.log")
            daemons.append(subprocess.Popen(["dask", "worker", address, "--nthreads", str(args.slots), "--nworkers",
                                             "1", "--no-dashboard"], stdout=log, stderr=subprocess.STDOUT, env=env))
            from distributed import Client

            with Client(address, timeout=60) as client:  # (the scheduler up, and the worker joined)
                client.wait_for_workers(1, timeout=120)
            print(f"{cpus} CPUs available; one Dask worker of {args.slots} task slots; {args.points} points a sweep, "
                  f"cornell pmap {args.resolution} x {args.resolution}")
            # an untimed sweep first: the worker loads tlm and the compiled kernels once
            warm = sweep_file(folder, "warm", None, [10**6, 10**6 + 1], 16)
            done = subprocess.run([sys.executable, "-m", "tlm", "sweep", str(warm), "--out", str(folder / "out_warm"),
                                   "--dask", address, "--no-progress"], capture_output=True, text=True, env=env,
                                  timeout=3600)
            if done.returncode != 0:
                raise SystemExit(f"the warm-up sweep failed ({done.returncode}): {done.stdout}{done.stderr}")
            seconds: dict[str, list[float]] = {"null": [], str(cpus): []}
            seed = 1
            for r in range(args.repeat):
                for name in (("null", str(cpus)) if r % 2 == 0 else (str(cpus), "null")):
                    seeds = list(range(seed, seed + args.points))
                    seed += args.points
                    path = sweep_file(folder, f"sweep_{name}", None if name == "null" else cpus, seeds,
                                      args.resolution)
                    t0 = time.perf_counter()
                    done = subprocess.run([sys.executable, "-m", "tlm", "sweep", str(path), "--out",
                                           str(folder / f"out_{r}_{name}"), "--dask", address, "--no-progress"],
                                          capture_output=True, text=True, env=env, timeout=3600)
                    wall = time.perf_counter() - t0
                    if done.returncode != 0:
                        raise SystemExit(f"tlm sweep failed ({done.returncode}): {done.stdout}{done.stderr}")
                    seconds[name].append(wall)
                    print(f"  round {r + 1}: render.threads {name:>4}: {wall:6.2f} s", flush=True)
        finally:
            for p in reversed(daemons):  # (the worker, then the scheduler; each killed if it lingers)
                p.terminate()
                try:
                    p.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()
            log.close()
    ratio = float(np.median(np.array(seconds["null"]) / np.array(seconds[str(cpus)])))
    print(f"points that size their threads: {min(seconds['null']):.2f} s (best), each point on every CPU: "
          f"{min(seconds[str(cpus)]):.2f} s; paired ratio {ratio:.3f} (below 1: sizing is faster)")


if __name__ == "__main__":
    main()
