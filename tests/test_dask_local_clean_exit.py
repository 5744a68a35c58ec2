"""A ``--dask local`` sweep whose workers are killed ends with tlm's own lines alone: nothing
from Python's multiprocessing. A LocalCluster's workers share the sweep's resource tracker,
which writes to the sweep's stderr; a worker's first progress bar (a point's render) made
tqdm's default lock, a named multiprocessing semaphore, and a worker killed before it could
unlink it (a SIGTERM to the sweep's process group, a kill -9, or the cluster's close while a
busy machine kept it from ending in time) left the tracker to report it: "resource_tracker:
There appear to be 2 leaked semaphore objects to clean up at shutdown" and a line of its
source, after ``tlm: terminated (SIGTERM)``. Each worker now preloads
:mod:`tlm.experiments.dask_workers`, whose ``dask_setup`` gives its bars a thread lock."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import dask
import pytest
import yaml

from tlm.experiments import dask_workers, executors, executors_quiet

from .test_signals import tlm_lines
from .test_sweep import _descendants

REPO = Path(__file__).resolve().parents[1]
POSIX = pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="process groups and /proc (Linux)")


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) a cache of the test's own: every point renders its frame
    return cache


def sweep_file(tmp_path: Path, n: int = 8) -> Path:
    """``n`` points of other seeds: each renders its own frame (a progress bar in its worker)."""
    base = {"scene": "cornell", "mode": "rcast", "resolution": [24, 16], "render": {"light_samples": 1},
            "arch": {"frames": 1, "trace": False, "packet_size": 4}}
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"seed": list(range(1, n + 1))}}))
    return path


def rows(out: Path) -> list[dict]:
    path = out / "sweep.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines()] if path.exists() else []


def dask_workers_below(pid: int) -> list[int]:
    """The LocalCluster's worker processes below ``pid`` (spawned; not the resource tracker)."""
    found = []
    for child, _ in _descendants(pid):
        try:
            args = Path(f"/proc/{child}/cmdline").read_bytes().decode(errors="replace")
        except OSError:
            continue
        if "spawn_main" in args and "resource_tracker" not in args:
            found.append(child)
    return found


def start(tmp_path: Path, env: dict | None = None) -> tuple[subprocess.Popen, Path]:
    out = tmp_path / "o"
    proc = subprocess.Popen([sys.executable, "-m", "tlm", "sweep", str(sweep_file(tmp_path)), "--out", str(out),
                             "--dask", "local", "--jobs", "2", "--no-report", "--no-progress"],
                            cwd=tmp_path, env={**os.environ, "PYTHONPATH": str(REPO), **(env or {})},
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and proc.poll() is None and not rows(out):  # a worker has rendered
        time.sleep(0.01)
    assert proc.poll() is None, f"the sweep ended before a point was done: {proc.communicate()[1]}"
    return proc, out


@POSIX
def test_a_dask_local_sweep_sigtermed_with_its_process_group_says_one_line(tmp_path):
    """SIGTERM to the whole process group (a batch system's, ``kill -TERM -- -PGID``) once a point
    is done: the workers die at once, each with the semaphore of its point's progress bar
    before; the sweep's stderr is exactly its one line (how many points it kept), exit status 143."""
    proc, out = start(tmp_path)
    try:
        os.killpg(proc.pid, signal.SIGTERM)
        _, err = proc.communicate(timeout=120)  # (a hang guard, not a timing: EOF once the tracker has ended)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    # (the points done, kept: as many as the rows in the folder, h450)
    assert tlm_lines(err, out, 8) == [err.rstrip("\n")] and err.startswith("tlm: terminated (SIGTERM) with "), err
    assert proc.returncode == 128 + signal.SIGTERM


@pytest.mark.slow
@POSIX
def test_a_dask_local_sweep_whose_workers_are_killed_runs_to_its_end_without_a_leak(tmp_path):
    """Both workers killed -9 once a point is done (at least one of them had rendered): Dask
    restarts them, records ``KilledWorker`` for the points they ran (no retry:
    ``allowed-failures`` 0) and the sweep runs to its end; nothing on its stderr but its own
    lines (the tracker said "1 leaked semaphore" per killed worker that had rendered)."""
    proc, out = start(tmp_path, {"DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"})
    try:
        workers = dask_workers_below(proc.pid)
        assert len(workers) == 2, workers
        for pid in workers:
            os.kill(pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=300)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
    assert "resource_tracker" not in err and "leaked" not in err, err
    lost = "tlm: warning: the Dask worker "  # (a worker killed while it held points: said, with why in its log)
    counted = re.compile(r"tlm: warning: [0-9]+ of 8 points: ")  # (the points' own warnings, counted: 746018c)
    assert all(line.startswith(("  point ", "8 points: ", lost)) or counted.match(line)
               for line in err.splitlines()), err
    assert all("older than the sweep's" not in line for line in err.splitlines()), err  # (its own tlm: no such hint)
    assert proc.returncode in (0, 1), err
    assert len(rows(out)) == 8


def test_a_local_clusters_workers_preload_tlms_setup_after_the_users_own():
    """The workers preload :mod:`tlm.experiments.dask_workers` (its ``dask_setup``), after the
    preloads of Dask's config, which an explicit ``preload`` would otherwise replace."""
    assert callable(dask_workers.dask_setup)
    with dask.config.set({"distributed.worker.preload": [], "distributed.worker.preload-argv": []}):
        assert executors._local_preloads() == {"preload": ["tlm.experiments.dask_workers"], "preload_argv": []}
    with dask.config.set({"distributed.worker.preload": ["mine.py"], "distributed.worker.preload-argv": ["--x"]}):
        assert executors._local_preloads() == {"preload": ["mine.py", "tlm.experiments.dask_workers"],
                                               "preload_argv": ["--x"]}
    with dask.config.set({"distributed.worker.preload": "mine.py", "distributed.worker.preload-argv": [["--x"]]}):
        assert executors._local_preloads() == {"preload": ["mine.py", "tlm.experiments.dask_workers"],
                                               "preload_argv": [["--x"], []]}


def test_dask_setup_gives_the_bars_a_thread_lock():
    """In a worker (here: this process, its lock put back after), tqdm's lock is no longer a
    multiprocessing semaphore once ``dask_setup`` ran."""
    from tqdm import tqdm

    before = tqdm.__dict__.get("_lock")
    try:
        dask_workers.dask_setup(None)
        assert isinstance(tqdm.get_lock(), type(threading.RLock())), tqdm.get_lock()
    finally:
        if before is None:
            tqdm.__dict__.get("_lock") is not None and delattr(tqdm, "_lock")
        else:
            tqdm.set_lock(before)


@pytest.mark.parametrize("ending", [KeyboardInterrupt, None])
def test_distributed_stays_silent_after_a_local_cluster_closed_on_a_signal(ending):
    """A signal ends the sweep (a KeyboardInterrupt, tlm.cli_signals): distributed's loggers stay
    silenced after the cluster closed, where its event loop thread logged each connection to a
    worker the process group's signal killed ("Batched Comm Closed" and a traceback) after
    tlm's one line (the cluster's own silence_logs ends with its close), then put back
    (``executors.QUIET_GRACE`` seconds later, by a timer). An ordinary end puts them back as they were."""
    import logging
    from contextlib import ExitStack

    import distributed  # noqa: F401  (its import sets its loggers' levels: before, as they are then)

    names = ["distributed", "distributed.batched", "distributed.core", "distributed.scheduler"]
    before = {n: logging.getLogger(n).level for n in names}
    try:
        with pytest.raises(KeyboardInterrupt) if ending else ExitStack(), ExitStack() as stack:
            executors.open_executor(stack, 1, "local", 1)
            if ending:
                raise ending
        quiet = not logging.getLogger("distributed.batched").isEnabledFor(logging.CRITICAL)
        assert quiet is bool(ending)
        if ending:  # (put back QUIET_GRACE seconds later: a session that goes on, a notebook's, hears them again)
            executors._put_back_left()
        assert {n: logging.getLogger(n).level for n in names} == before
    finally:
        for n, level in before.items():
            logging.getLogger(n).setLevel(level)


def test_loggers_left_silent_by_a_signal_come_back_and_a_later_sweep_keeps_their_own_levels(monkeypatch):
    """Left silenced by a signal, distributed's loggers are put back ``QUIET_GRACE`` seconds later
    (a notebook's session goes on after a Ctrl-C: it stayed silent for good); a sweep that
    silences them meanwhile records their levels before the silence, not the silence."""
    import logging

    log = logging.getLogger("distributed.worker")
    monkeypatch.setattr(log, "level", logging.INFO)
    monkeypatch.setattr(executors_quiet, "QUIET_GRACE", 0.2)
    executors._Quiet().after(KeyboardInterrupt)
    assert log.level > logging.CRITICAL
    later = executors._Quiet()
    later.now()  # (a second sweep, within the grace)
    assert later.levels["distributed.worker"] == logging.INFO
    later.restore()
    assert log.level == logging.INFO
    executors._Quiet().after(KeyboardInterrupt)
    deadline = time.monotonic() + 30
    while log.level != logging.INFO and time.monotonic() < deadline:
        time.sleep(0.01)
    assert log.level == logging.INFO
