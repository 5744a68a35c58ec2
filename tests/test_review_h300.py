"""Review of 81ec1d4 (h300): who ran each sweep point (``worker``, ``host``, ``pid``).

* A sweep of an older tlm resumed by this one has rows without the columns (points done before) and rows with them
  (points run now): ``sweep.csv`` and :attr:`Outcome.table` keep them after ``mode``, as the docs say, whichever row
  comes first (they went after ``seconds.write`` where the first point was an old one).
* A Dask worker that leaves is not named by its name once another worker joins at its address (a worker started
  again on the same ``--worker-port`` without ``--name``): the lines on the new one name it as it says.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import socket
import time

import pytest
import yaml

from tlm import storage
from tlm.experiments.sweep_file import Point
from tlm.experiments.sweep_rows import RAN_COLUMNS, columns, point_row

HOST = socket.gethostname()
BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 16}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _row(index: int, ran: dict | None) -> dict:
    res = {"cycles": {"throughput": 10, "latency": 20}, "fps": 1.0,
           "timing": {"simpy_events": 3, "throughput_estimate": {"steady": True}, "units": {}},
           "functional": {"cached": False}, "host_seconds": {"functional": 0.1, "simulate": 0.2}}
    point = Point(index=index, hash=f"h{index}", factors={"seed": index}, config={**BASE, "seed": index})
    return point_row(point, {"status": "ok", "results": res if ran is None else {**res, "ran": ran}})


def test_who_ran_follows_mode_though_the_first_row_is_of_an_older_tlm():
    old, new = _row(0, None), _row(1, {"worker": None, "host": "nodeA", "pid": 7})
    cols = columns([old, new])
    assert cols[cols.index("mode") + 1:][:3] == list(RAN_COLUMNS), cols
    assert columns([new, old]) == cols  # (the order of the rows changes nothing)
    assert not set(RAN_COLUMNS) & set(columns([old]))  # (a sweep all of an older tlm: the columns it always had)


def test_a_resumed_sweep_of_an_older_tlm_keeps_who_ran_after_mode(tmp_path):
    from tlm.experiments.sweep import run_sweep

    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"seed": [1, 2, 3]}}, sort_keys=False))
    out = tmp_path / "o"
    first = run_sweep(path, out, jobs=1)
    assert first.ok == 3
    rows = sorted(first.rows, key=lambda r: r["point"])
    # point 0 as an older tlm left it (its results.json without "ran"), points 1 and 2 not run yet
    folder = out / "points" / rows[0]["hash"]
    results = json.loads((folder / "results.json").read_text())
    del results["ran"]
    (folder / "results.json").write_text(storage.json_text(results, indent=2) + "\n")
    for r in rows[1:]:
        shutil.rmtree(out / "points" / r["hash"])
    again = run_sweep(path, out, jobs=1)
    assert (again.ok, again.skipped) == (2, 1)
    with open(out / "sweep.csv", newline="") as fh:
        reader = csv.DictReader(fh)
        head, got = list(reader.fieldnames or []), list(reader)
    assert head[head.index("mode") + 1:][:4] == [*RAN_COLUMNS, "cycles.vertex"], head
    assert [(r["worker"], r["host"], r["pid"]) for r in got] == [("", "", ""), *[("", HOST, str(os.getpid()))] * 2]
    assert list(again.table.columns) == head  # (the table as the CSV)
    jsonl = [json.loads(line) for line in (out / "sweep.jsonl").read_text().splitlines()]
    assert "worker" not in jsonl[0] and jsonl[1]["pid"] == os.getpid()


def test_a_worker_at_the_address_of_one_that_left_is_not_named_as_it():
    from tlm.experiments.executors_dask import WorkerWatch

    from .test_dask_worker_h288 import _Client

    address = "tcp://10.0.0.1:4000"
    named = {"host": "hostA", "tlm": "/new/tlm", "runner": True, "fingerprint": None, "error": None, "name": "w1"}
    client = _Client({address: named})
    watch = WorkerWatch(client, code="c0de", remote=True)
    assert watch.check() == [] and watch.where(address) == f"the Dask worker w1 ({address}) on host hostA"
    client.handlers["all"]((time.time(), {"action": "remove-worker", "worker": address, "processing-tasks": []}))
    # another worker at that address, given no name (and with an older tlm: a line on it)
    client.answers = {address: {"host": "hostA", "tlm": "/old/tlm", "runner": False, "fingerprint": None,
                                "error": None, "name": None}}
    lines = watch.check()
    assert len(lines) == 1 and lines[0].startswith(f"the Dask worker {address} on host hostA cannot run"), lines
    assert watch.where(address) == f"the Dask worker {address} on host hostA"


def test_an_error_json_the_sweep_writes_for_a_remote_worker_says_who_ran_the_point(tmp_path):
    """A remote worker's point whose error.json the sweep writes here (its
    worker could not: no shared folder) says who ran it, as the worker's own would, and so does a PathNotOnWorker
    of a results.json this machine does not see."""
    from tlm.experiments.sweep import _seen_here

    from .test_dask_worker_h288 import _task

    ran = {"worker": "w1", "host": "nodeB", "pid": 4242}
    failed = {"status": "failed", "ran": ran, "worker": "the Dask worker w1 (tcp://10.0.0.7:1) on host nodeB",
              "error": {"type": "ValueError", "message": "bad", "stage": "functional", "traceback": ""}}
    assert _seen_here(failed, _task(tmp_path, "f")) is failed
    assert json.loads((tmp_path / "points" / "f" / "error.json").read_text())["ran"] == ran
    unseen = {"status": "ok", "ran": ran, "worker": failed["worker"], "results": {"hash": "h", "ran": ran}}
    got = _seen_here(unseen, _task(tmp_path, "u"))
    assert got["status"] == "failed" and got["error"]["type"] == "PathNotOnWorker" and got["ran"] == ran
    assert json.loads((tmp_path / "points" / "u" / "error.json").read_text())["ran"] == ran
