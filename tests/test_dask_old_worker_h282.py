"""A remote Dask worker whose tlm is older than the sweep's (no ``tlm.experiments.sweep_point``): Dask ended it
at its first point, unpickling the point, and the sweep said only that its scheduler had no worker (after 300 s
by default), or, with a good worker beside it, nothing. Now each worker is asked, before any point is sent,
whether it can load them (a probe pickled by value: the standard library only), and one that cannot is named in
one line; a worker that leaves while it holds points is named, with how many."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time

import pytest

import tlm.experiments.executors as executors
from tlm.errors import EnvironmentFailure

pytest.importorskip("distributed")

RUNNER = "tlm.experiments.sweep_point"  # (executors_dask.RUNNER: checked below)


def _old_tlm(root):
    """A tlm package with ``tlm.experiments`` and ``tlm.fingerprint`` but no point runner (an older tlm's)."""
    (root / "tlm" / "experiments").mkdir(parents=True)
    (root / "tlm" / "__init__.py").write_text("")
    (root / "tlm" / "experiments" / "__init__.py").write_text("")
    (root / "tlm" / "fingerprint.py").write_text("def code_fingerprint():\n    return 'feedc0de00000000'\n")
    return root


def test_the_probe_is_pickled_by_value_and_runs_on_a_worker_with_an_older_tlm(tmp_path):
    """distributed's pickle of the probe names no module of tlm's (a worker lacking it could not load it), and a
    Python whose tlm has no point runner runs it and says so, with the folder its tlm is in."""
    from distributed.protocol.pickle import dumps

    from tlm.experiments.executors_dask import RUNNER as runner
    from tlm.experiments.executors_dask import cannot_run, worker_probe

    assert runner == RUNNER
    payload = dumps(worker_probe())
    assert b"executors_dask" not in payload and b"tlm.experiments" not in payload
    root = _old_tlm(tmp_path / "old")
    code = textwrap.dedent(f"""
        import pickle, sys
        probe = pickle.loads(sys.stdin.buffer.read())
        print(repr(probe({RUNNER!r})))
        print(sorted(m for m in sys.modules if m == "tlm" or m.startswith("tlm.")))
    """)
    env = {**os.environ, "PYTHONPATH": str(root)}
    got = subprocess.run([sys.executable, "-c", code], input=payload, capture_output=True, env=env, cwd=tmp_path,
                         timeout=60)
    assert got.returncode == 0, got.stderr.decode()
    seen_line, modules = got.stdout.decode().splitlines()
    seen = eval(seen_line)  # (a dict's repr)
    assert seen["runner"] is False and seen["tlm"] == str(root / "tlm") and seen["error"] is None, seen
    assert seen["fingerprint"] == "feedc0de00000000", seen
    assert "tlm.experiments.executors_dask" not in modules, modules
    why = cannot_run(seen, "0123456789abcdef")
    assert why == (f"its tlm at {root / 'tlm'} (code fingerprint feedc0de00000000; the sweep's 0123456789abcdef) "
                   f"has no {RUNNER} (it is older than the sweep's)"), why


class _Client:
    """A client of a scheduler whose workers answer the probe with ``answers``."""

    status = "running"

    def __init__(self, answers: dict, nthreads: dict | None = None) -> None:
        self.answers = answers
        self.threads = nthreads if nthreads is not None else {}
        self.handlers: dict = {}
        self.asked: list = []

    def get_executor(self, pure=False):
        return self

    def subscribe_topic(self, topic, handler):
        self.handlers[topic] = handler

    def run(self, fn, *args, workers=None, on_error="raise", callback_timeout=None):
        self.asked.append(workers)
        return {a: s for a, s in self.answers.items() if workers is None or a in workers}

    def nthreads(self, callback_timeout=None):
        return self.threads


GOOD = {"host": "hostA", "tlm": "/new/tlm", "runner": True, "fingerprint": None, "error": None}
OLD = {"host": "hostB", "tlm": "/old/tlm", "runner": False, "fingerprint": "0e55f6ed1c4ae811", "error": None}


def test_a_worker_that_cannot_load_the_points_is_named_in_one_line_before_any_is_sent():
    from tlm.experiments.executors_dask import WorkerCannotRun

    client = _Client({"tcp://10.0.0.1:1": GOOD, "tcp://10.0.0.2:2": OLD,
                      "tcp://10.0.0.3:3": {"host": "hostC", "tlm": None, "runner": False, "fingerprint": None,
                                           "error": None}})
    pool = executors.DaskPool(client, "tcp://s:8786", remote=True)
    with pytest.raises(WorkerCannotRun) as e:
        pool.watch.refuse()
    line = str(e.value)
    assert isinstance(e.value, EnvironmentFailure) and "\n" not in line, line
    assert line.startswith("the Dask worker tcp://10.0.0.2:2 on host hostB cannot run tlm's points: its tlm at "
                           "/old/tlm (code fingerprint 0e55f6ed1c4ae811; the sweep's "), line
    assert f"has no {RUNNER} (it is older than the sweep's); the Dask worker tcp://10.0.0.3:3 on host hostC " \
           "cannot run tlm's points: it has no tlm: install the sweep's tlm on the workers" in line, line
    assert "10.0.0.1" not in line, line
    executors.DaskPool(_Client({"tcp://10.0.0.1:1": GOOD}), "tcp://s:8786", remote=True).watch.refuse()  # (none)


def test_a_worker_that_left_holding_points_is_named_with_how_many():
    """The scheduler's remove-worker event names the tasks the worker held: the sweep's (its keys) are counted;
    a worker that joined while the sweep waited, and that cannot load the points, says why; the stop line on a
    scheduler left with no worker names it."""
    client = _Client({"tcp://10.0.0.2:2": OLD}, nthreads={"tcp://10.0.0.2:2": 1})
    pool = executors.DaskPool(client, "tcp://s:8786", remote=True, wait=0.01)
    assert pool.trouble(cancelled=False) is None  # (a worker: it joined, and is asked what it has)
    assert client.asked == [["tcp://10.0.0.2:2"]]
    keys = [pool.watch.key(executors.DaskPool) for _ in range(3)]
    client.threads = {}
    client.handlers["all"]((time.time(), {"action": "remove-worker", "worker": "tcp://10.0.0.2:2",
                                          "processing-tasks": {keys[0], keys[1], "another-client's-task"}}))
    client.handlers["all"]((time.time(), {"action": "remove-worker", "worker": "tcp://10.0.0.9:9",
                                          "processing-tasks": {"another-client's-task"}}))
    client.handlers["all"]((time.time(), {"action": "remove-worker", "worker": "tcp://10.0.0.7:7",
                                          "processing-tasks": [keys[2]]}))  # (never asked: it left at once)
    pool.asked = -float("inf")
    why = None
    try:
        deadline = time.monotonic() + 5
        while why is None and time.monotonic() < deadline:
            pool.asked = -float("inf")
            why = pool.trouble(cancelled=False)
            time.sleep(0.02)
    finally:
        pool.quiet.restore()
    lost = ("the Dask worker tcp://10.0.0.2:2 on host hostB left the cluster while it held 2 of the sweep's points "
            "(it cannot run tlm's points: its tlm at /old/tlm")
    assert why is not None and why.startswith("the Dask scheduler tcp://s:8786 has had no worker for "), why
    assert f"(--dask-wait: 0.01 s); {lost}" in why, why
    assert len(pool.lost()) == 2 and pool.lost()[0].startswith(lost), pool.lost()
    assert pool.lost()[1] == ("the Dask worker tcp://10.0.0.7:7 left the cluster while it held 1 of the sweep's "
                              "points (why is in its own log; it left before the sweep could ask what tlm it has: one "
                              "whose tlm is older than the sweep's leaves so at its first point)"), pool.lost()


def test_a_points_key_is_the_sweeps_own_only_on_a_dask_client():
    """A distributed client's executor gets each point's key (the watch knows the sweep's); a stand-in executor
    (the tests') is called as before."""
    from concurrent.futures import ThreadPoolExecutor

    class Client(_Client):
        def get_executor(self, pure=False):
            return ThreadPoolExecutor(1)

    pool = executors.DaskPool(Client({}), "local", remote=False)
    assert pool.submit(abs, -3).result() == 3 and not pool.watch.keys
    pool.executor.shutdown()


@pytest.mark.slow  # (a real scheduler and worker processes)
def test_a_sweep_on_a_cluster_with_an_older_tlms_worker_is_refused_in_one_line(tmp_path, monkeypatch, capsys):
    """A ``dask worker`` whose PYTHONPATH gives a tlm without the point runner: the sweep says so at once, naming
    the worker and its tlm's folder, exit 1, no folder written (it waited --dask-wait, then said the scheduler
    had no worker: Dask had ended the worker at its first point)."""
    from tlm.cli import main

    from .test_dask_cluster import Cluster, sweep_file

    path = sweep_file(tmp_path / "s", grid={"arch.fifo_depth": [1, 16]})
    root = _old_tlm(tmp_path / "old")
    c = Cluster(tmp_path / "cluster")
    try:
        c.scheduler()
        monkeypatch.setenv("PYTHONPATH", str(root))
        c.workers(1)
        monkeypatch.delenv("PYTHONPATH")
        rc = main(["sweep", str(path), "--out", str(tmp_path / "o"), "--dask", c.address, "--dask-wait", "5",
                   "--no-report", "--no-progress"])
    finally:
        c.close()
    err = capsys.readouterr().err
    assert rc == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("tlm: error: the Dask worker tcp://127.0.0.1:"), err
    assert f"cannot run tlm's points: its tlm at {root / 'tlm'} (code fingerprint feedc0de00000000; " in err, err
    assert "(no point was sent)" in err and not (tmp_path / "o").exists(), err


def test_a_sweep_that_finished_says_a_worker_lost_with_points(tmp_path, monkeypatch):
    """The pool's lines on a worker that left holding points are the sweep's warnings (Outcome.warnings, warn)."""
    import tlm.experiments.sweep as sweep_mod
    from tlm.experiments.sweep import run_sweep

    from .test_sweep_dispatch import _Client, sweep_file

    line = "the Dask worker tcp://10.0.0.7:7 left the cluster while it held 1 of the sweep's points (why ...)"

    class Pool(executors.DaskPool):
        def lost(self):
            return [line]

    monkeypatch.setattr(sweep_mod, "open_executor", lambda *a, **k: Pool(_Client(), "local", remote=False))
    warned: list[str] = []
    done = run_sweep(sweep_file(tmp_path, 2), tmp_path / "o", jobs=1, dask="local", warn=warned.append)
    assert (done.ok, done.failed) == (2, 0)
    assert line in warned and line in done.warnings, (warned, done.warnings)
