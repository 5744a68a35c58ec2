"""Which worker ran a sweep's point (h288): a point's row (``worker``, ``host``, ``pid``) and its ``results.json``
(``ran``) say it, a Dask worker by the ``--name`` it was given, else its address; the lines on a worker name it by
its name; a path a worker does not see is one line on what, where and what to do; one reading of a null
``render.threads``."""

from __future__ import annotations

import concurrent.futures as cf
import json
import logging
import os
import socket
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

import tlm.experiments.executors as executors
from tlm.experiments.sweep_file import Point
from tlm.experiments.sweep_rows import RAN_COLUMNS, columns, point_row, write_rows

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 16}}
HOST = socket.gethostname()


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _point(index: int, hash_: str) -> Point:
    return Point(index=index, hash=hash_, factors={"seed": index}, config={**BASE, "seed": index})


def _results(ran: dict | None) -> dict:
    res = {"cycles": {"throughput": 10, "latency": 20}, "fps": 1.0,
           "timing": {"simpy_events": 3, "throughput_estimate": {"steady": True}, "units": {}},
           "functional": {"cached": False}, "host_seconds": {"functional": 0.1, "simulate": 0.2}}
    return res if ran is None else {**res, "ran": ran}


def test_a_rows_worker_host_and_pid_follow_its_mode_and_older_rows_have_none(tmp_path):
    w1 = {"worker": "w1", "host": "nodeB", "pid": 4242}
    ok = point_row(_point(0, "a0"), {"status": "ok", "results": _results(w1)})  # (results.json read back: resumed)
    failed = point_row(_point(1, "b1"), {"status": "failed", "ran": {"worker": "w2", "host": "nodeC", "pid": 7},
                                         "error": {"type": "PathNotOnWorker", "message": "gone"}})
    local = point_row(_point(2, "c2"), {"status": "ok", "results": _results({"worker": None, "host": HOST,
                                                                              "pid": os.getpid()})})
    assert [ok[k] for k in RAN_COLUMNS] == ["w1", "nodeB", 4242]
    assert [failed[k] for k in RAN_COLUMNS] == ["w2", "nodeC", 7] and failed["error"] == "PathNotOnWorker: gone"
    assert [local[k] for k in RAN_COLUMNS] == [None, HOST, os.getpid()]
    cols = columns([failed, ok, local])  # (a failed row first: who ran each point, after its mode, as ever)
    assert cols[cols.index("mode") + 1:][:4] == [*RAN_COLUMNS, "cycles.throughput"], cols
    # a row of an older sweep (its results.json without "ran"; a worker that died before it could say): none, and
    # the CSV's columns are those it always had
    old = point_row(_point(3, "d3"), {"status": "ok", "results": _results(None)})
    dead = point_row(_point(4, "e4"), {"status": "failed", "error": {"type": "WorkerDied", "message": "died"}})
    assert not set(RAN_COLUMNS) & set(old) and not set(RAN_COLUMNS) & set(dead)
    assert columns([old, dead]) == columns([old, dead], ()) and not set(RAN_COLUMNS) & set(columns([old, dead]))
    write_rows(tmp_path, [old, ok, dead])
    import csv

    with open(tmp_path / "sweep.csv", newline="") as fh:
        got = list(csv.DictReader(fh))
    head = list(got[0])
    assert head[head.index("mode") + 1:][:3] == list(RAN_COLUMNS), head
    assert [(r["worker"], r["host"], r["pid"]) for r in got] == [("w1", "nodeB", "4242"), ("", "", ""), ("", "", "")]
    jsonl = [json.loads(line) for line in (tmp_path / "sweep.jsonl").read_text().splitlines()]
    assert jsonl[0]["worker"] == "w1" and "worker" not in jsonl[1] and "worker" not in jsonl[2]  # (by point)


def test_a_dask_worker_is_named_by_its_given_name_else_its_address():
    from tlm.experiments.dask_workers import worker_name, worker_words

    assert worker_name("w1", "tcp://10.0.0.7:4242") == "w1"
    assert worker_name(None, "tcp://10.0.0.7:4242") == "tcp://10.0.0.7:4242"  # (none given: dask's is its address)
    assert worker_name("tcp://10.0.0.7:4242", "tcp://10.0.0.7:4242") == "tcp://10.0.0.7:4242"
    assert worker_name(0, "tcp://127.0.0.1:1") == "tcp://127.0.0.1:1"  # (a local cluster's number: not a name)
    words = worker_words("w1", "tcp://10.0.0.7:4242", "nodeB")
    assert words == "the Dask worker w1 (tcp://10.0.0.7:4242) on host nodeB", words
    assert worker_words(None, "tcp://10.0.0.7:4242") == "the Dask worker tcp://10.0.0.7:4242"


def _named_cluster(*names: str):
    """An in-process cluster whose workers are given ``names`` (as ``dask worker --name``)."""
    from distributed import Scheduler, SpecCluster, Worker

    return SpecCluster(workers={n: {"cls": Worker, "options": {"nthreads": 1}} for n in names},
                       scheduler={"cls": Scheduler, "options": {"dashboard_address": "127.0.0.1:0",
                                                                "dashboard": False}},
                       silence_logs=logging.CRITICAL, asynchronous=False)


def test_a_process_says_who_it_is_a_named_dask_worker_by_its_name():
    pytest.importorskip("distributed")
    from distributed import Client

    from tlm.experiments.dask_workers import dask_worker_where, ran_here

    assert ran_here() == {"worker": None, "host": HOST, "pid": os.getpid()}  # (a local process: its host and pid)
    assert dask_worker_where() is None
    with _named_cluster("w1") as cluster, Client(cluster) as client:
        (address,) = client.scheduler_info(n_workers=-1)["workers"]
        assert client.submit(ran_here, pure=False).result() == {"worker": "w1", "host": HOST, "pid": os.getpid()}
        where = client.submit(dask_worker_where, pure=False).result()
        assert where == f"the Dask worker w1 ({address}) on host {HOST}", where


class _Client:
    """A client of a scheduler whose workers answer the probe with ``answers`` (tests/test_dask_old_worker_h282.py)."""

    status = "running"

    def __init__(self, answers: dict) -> None:
        self.answers = answers
        self.handlers: dict = {}

    def get_executor(self, pure=False):
        return self

    def subscribe_topic(self, topic, handler):
        self.handlers[topic] = handler

    def run(self, fn, *args, workers=None, on_error="raise", callback_timeout=None):
        return {a: s for a, s in self.answers.items() if workers is None or a in workers}


def test_the_lines_on_a_worker_name_it_by_its_name():
    from tlm.experiments.executors_dask import WorkerCannotRun, worker_probe

    probe = worker_probe()
    assert probe("tlm.experiments.sweep_point")["name"] is None  # (no worker: none)
    seen = probe("tlm.experiments.sweep_point", dask_worker=SimpleNamespace(name="w1"))  # (Client.run passes it)
    assert seen["name"] == "w1" and seen["runner"] is True
    assert probe("tlm.experiments.sweep_point", dask_worker=SimpleNamespace(name=3))["name"] is None
    old = {"host": "hostB", "tlm": "/old/tlm", "runner": False, "fingerprint": "0e55f6ed1c4ae811", "error": None,
           "name": "w2"}
    with pytest.raises(WorkerCannotRun) as e:
        executors.DaskPool(_Client({"tcp://10.0.0.2:2": old}), "tcp://s:8786", remote=True).watch.refuse()
    assert str(e.value).startswith("the Dask worker w2 (tcp://10.0.0.2:2) on host hostB cannot run tlm's points"), e
    good = {"host": "hostA", "tlm": "/new/tlm", "runner": True, "fingerprint": None, "error": None, "name": "w1"}
    client = _Client({"tcp://10.0.0.1:1": good})
    pool = executors.DaskPool(client, "tcp://s:8786", remote=True)
    pool.watch.refuse()  # (it can run them: asked, its name kept)
    key = pool.watch.key(executors.DaskPool)
    client.handlers["all"]((time.time(), {"action": "remove-worker", "worker": "tcp://10.0.0.1:1",
                                          "processing-tasks": [key]}))
    assert pool.lost() == ["the Dask worker w1 (tcp://10.0.0.1:1) on host hostA left the cluster while it held 1 "
                           "of the sweep's points (why is in its own log)"], pool.lost()
    pool.shutdown()


def test_a_killed_workers_line_names_the_last_worker_by_its_name(tmp_path):
    pytest.importorskip("distributed")
    from distributed.scheduler import KilledWorker

    from tlm.experiments.executors_dask import killed_worker_line

    e = KilledWorker("run_point-1f2e", SimpleNamespace(address="tcp://10.0.0.7:4242", name="w2"), 3)
    assert killed_worker_line(e).startswith("the Dask workers that held this point died 4 times, the last the Dask "
                                            "worker w2 (tcp://10.0.0.7:4242): "), killed_worker_line(e)


def _task(tmp_path: Path, name: str = "p", **kwargs):
    from tlm.experiments.sweep_point import Task

    (tmp_path / "sweep.yaml").write_text("{}\n")  # (the marker a worker looks for above the point's folder)
    return Task("h", kwargs.pop("config", BASE), {}, str(tmp_path), "sweep.yaml", str(tmp_path / "points" / name),
                {}, **kwargs)


def test_a_points_results_json_error_json_and_record_say_who_ran_it(tmp_path):
    from tlm.experiments.sweep_point import run_point

    here = {"worker": None, "host": HOST, "pid": os.getpid()}
    got = run_point(_task(tmp_path, "ok"))
    assert got["status"] == "ok" and got["ran"] == here and got["results"]["ran"] == here
    assert json.loads((tmp_path / "points" / "ok" / "results.json").read_text())["ran"] == here
    row = point_row(_point(0, "ok"), got)
    assert [row[k] for k in RAN_COLUMNS] == [None, HOST, os.getpid()]
    bad = run_point(_task(tmp_path, "bad", config={**BASE, "scene": str(tmp_path / "none.yaml")}))
    assert bad["status"] == "failed" and bad["ran"] == here
    assert json.loads((tmp_path / "points" / "bad" / "error.json").read_text())["ran"] == here


def test_a_named_dask_workers_point_records_its_name(tmp_path):
    pytest.importorskip("distributed")
    from distributed import Client

    from tlm.experiments.sweep_point import run_point

    run_point(_task(tmp_path, "warm"))  # (compiled here first: the worker is this process)
    with _named_cluster("w1") as cluster, Client(cluster) as client:
        got = client.submit(run_point, _task(tmp_path, "p"), pure=False).result()
    assert got["status"] == "ok", got
    ran = json.loads((tmp_path / "points" / "p" / "results.json").read_text())["ran"]
    assert ran == got["ran"] == {"worker": "w1", "host": HOST, "pid": os.getpid()}


def test_a_path_a_worker_does_not_see_says_what_on_which_worker_and_what_to_do(tmp_path):
    from tlm.experiments.sweep import _seen_here
    from tlm.experiments.sweep_point import PathNotOnWorker, _check_worker_sees

    where = "the Dask worker w1 (tcp://10.0.0.7:4242) on host nodeB"
    scene, table = tmp_path / "scenes" / "box.yaml", tmp_path / "tables" / "programs.yaml"
    config = {**BASE, "scene": "scenes/box.yaml", "arch": {**BASE["arch"], "programs": "tables/programs.yaml"}}
    for inputs, what in (((str(scene),), f"the scene file {scene}"), ((str(table),), f"the programs table {table}")):
        with pytest.raises(PathNotOnWorker) as e:
            _check_worker_sees(_task(tmp_path, config=config, inputs=inputs), where)
        line = str(e.value)
        assert "\n" not in line and line.startswith(f"cannot read {what} on {where}: copy it to that path on the "
                                                    "worker's machine, or share its folder with the workers"), line
    task = _task(tmp_path)
    (tmp_path / "sweep.yaml").unlink()  # (the sweep's folder, as a worker without it sees it)
    with pytest.raises(PathNotOnWorker) as e:
        _check_worker_sees(task, where)
    assert str(e.value).startswith(f"the sweep's output folder {tmp_path} is not there on {where}, which writes the "
                                   "point's folder into it: share that folder with the workers' machines"), e
    # a point its worker wrote where this machine does not see it
    (tmp_path / "sweep.yaml").write_text("{}\n")
    ran = {"worker": "w1", "host": "nodeB", "pid": 7}
    got = _seen_here({"status": "ok", "results": {"tlm": "x"}, "worker": where, "ran": ran}, task)
    line = got["error"]["message"]
    assert got["status"] == "failed" and got["ran"] == ran
    assert "\n" not in line and line.startswith(f"{where} wrote {task.out}, which this machine does not see"), line
    assert "share the sweep's output folder between this machine and the workers'" in line, line


def test_a_null_render_threads_is_read_by_one_helper(monkeypatch):
    from tlm.experiments import dask_workers
    from tlm.kernels import threads

    monkeypatch.setattr(threads, "available", lambda: 16)
    assert threads.shared_threads(4) == 4 and threads.shared_threads(32) == 1
    assert threads.shared_threads() == threads.default_threads()
    asked = []

    def shared(slots=None):
        asked.append(slots)
        return 5

    monkeypatch.setattr(threads, "shared_threads", shared)
    assert executors.kernel_threads(3, None, 10) == 5 and asked == [3]  # (the sweep's share of its machine)
    worker = SimpleNamespace(address="tcp://x:1", state=SimpleNamespace(nthreads=2))
    monkeypatch.setattr(dask_workers, "_dask_worker", lambda: worker)
    monkeypatch.setitem(dask_workers._SLOTS, "tcp://x:1", (time.monotonic(), 6))
    assert dask_workers.dask_worker_threads() == 5 and asked == [3, 6]  # (a Dask worker's share of its machine)


@pytest.mark.slow
def test_a_cluster_of_named_workers_and_a_local_one_say_which_worker_ran_each_point(tmp_path):
    """A scheduler and two ``dask worker --name w1/w2 --nworkers 1 --nthreads 1`` started by hand (other processes):
    each point's row and results.json name its worker and host; with ``--dask local``, its worker's address."""
    pytest.importorskip("distributed")
    from distributed import Client

    from tlm.experiments.sweep import run_sweep

    from .test_dask_cluster import WORKER, Cluster, sweep_file

    cluster = Cluster(tmp_path / "cluster")
    try:
        cluster.scheduler()
        with Client(cluster.address, timeout=30) as client:
            for name in ("w1", "w2"):
                cluster._start([*WORKER, cluster.address, "--name", name, "--nworkers", "1", "--nthreads", "1",
                                "--no-dashboard"], tmp_path / "cluster" / name)
            client.wait_for_workers(2, timeout=90)
        path = sweep_file(tmp_path / "s", grid={"seed": [1, 2, 3]})
        done = run_sweep(path, tmp_path / "o", dask=cluster.address)
    finally:
        cluster.close()
    assert done.failed == 0
    for row in done.rows:
        ran = json.loads((tmp_path / "o" / "points" / row["hash"] / "results.json").read_text())["ran"]
        assert row["worker"] in ("w1", "w2") and row["host"] == HOST and ran == {k: row[k] for k in RAN_COLUMNS}
        assert row["pid"] != os.getpid()
    csv_text = (tmp_path / "o" / "sweep.csv").read_text().splitlines()
    assert ",mode,worker,host,pid,cycles." in csv_text[0], csv_text[0]
    local = run_sweep(path, tmp_path / "l", jobs=2, dask="local")
    assert local.failed == 0 and all(str(r["worker"]).startswith("tcp://127.0.0.1:") for r in local.rows)
    assert sys.modules.get("distributed") is not None


def test_a_local_pools_points_say_their_host_and_process(tmp_path):
    from tlm.experiments.executors import LocalPool
    from tlm.experiments.sweep_point import run_point

    pool = LocalPool(1)
    try:
        f = pool.submit(run_point, _task(tmp_path, "p"))
        pool.run_next()
        got = f.result()
    finally:
        pool.shutdown()
    assert isinstance(f, cf.Future) and got["status"] == "ok", got
    assert got["ran"]["worker"] is None and got["ran"]["host"] == HOST and got["ran"]["pid"] != os.getpid()
