"""A Dask sweep's events on its workers kept in its folder and shown by ``tlm report`` (h366): a worker left out
of the sweep, why, and the points sent again from it (where each ran then), one re-admitted, one that left the
cluster while it held points were said on stderr only; ``workers.json`` now keeps them (written whole, after those
of the sweeps run into the folder before), and the report's warnings block lists them. And a point whose results
its worker wrote on a disk this machine does not see (``PathNotOnWorker`` found here, after the point) is sent
again to the good workers, as a point that failed there for its worker is."""

from __future__ import annotations

import json
import logging
import shutil
from types import SimpleNamespace

import pytest

import tlm.experiments.executors as executors
import tlm.experiments.sweep as sweep_mod
from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_rows import WORKERS_FILE, keep_worker_events
from tlm.report.collect import read
from tlm.report.warnings import warnings_html, worker_events

pytest.importorskip("distributed")

from tests.test_dask_health_h341 import GOOD, OLD, _addresses, _Client, _points_fail_on, _sweep


@pytest.fixture
def cluster():
    """A scheduler and two workers of one thread each, in this process (as tests/test_dask_health_h341.py's)."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp://", host="127.0.0.1",
                      dashboard_address="127.0.0.1:0", scheduler_kwargs={"dashboard": False},
                      silence_logs=logging.CRITICAL) as c:
        yield c


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _events(out) -> list[dict]:
    body = json.loads((out / WORKERS_FILE).read_text(encoding="utf-8"))
    assert body["tlm"] == "sweep-workers/1", body
    return body["events"]


def test_a_worker_left_out_and_its_points_sent_again_are_kept_and_reported(tmp_path, cluster, monkeypatch):
    bad, good = _addresses(cluster)
    _points_fail_on(monkeypatch, {bad})
    out = tmp_path / "o"
    done = run_sweep(_sweep(tmp_path), out, dask=cluster.scheduler_address, warn=lambda line: None)
    assert (done.ok, done.failed) == (4, 0), [r.get("error") for r in done.rows]
    (event,) = _events(out)
    assert event["event"] == "left-out" and event["worker"] == bad, event
    assert event["why"].startswith(f"OtherInputsOnWorker: the Dask worker {bad} on host "), event
    assert event["line"].startswith(f"the Dask worker {bad} on host ") and "was left out" in event["line"], event
    assert event["sent_again"], event  # (the points that failed there ran again on the good worker)
    hashes = {r["hash"] for r in done.rows}
    for sent in event["sent_again"]:
        assert sent["hash"] in hashes and sent["ran_on"] == good and sent["status"] == "ok", sent
    assert isinstance(event["when"], str) and event["when"].endswith("+00:00"), event
    assert not [p for p in out.iterdir() if ".tmp" in p.name], list(out.iterdir())  # (no temporary left)

    html = warnings_html(read([out]))
    assert "Dask workers." in html and bad in html and "OtherInputsOnWorker" in html, html
    assert "sent again: #" in html and f"ran again on {good}" in html, html

    again = run_sweep(_sweep(tmp_path), out, dask=cluster.scheduler_address)  # (all done: nothing happened)
    assert again.skipped == 4 and len(_events(out)) == 1  # (the first sweep's events kept)


def test_a_point_whose_results_this_machine_does_not_see_is_sent_again(tmp_path, cluster, monkeypatch):
    """Its worker wrote its folder on the worker's own disk (here: removed before the sweep looks), a
    ``PathNotOnWorker`` found only here: the point failed, where a good worker could run it."""
    bad, good = _addresses(cluster)
    real = sweep_mod._seen_here

    def unshared(record, task):
        if (record.get("ran") or {}).get("worker") == bad and record["status"] == "ok":
            shutil.rmtree(task.out)  # (the worker's disk, not this machine's)
        return real(record, task)

    monkeypatch.setattr(sweep_mod, "_seen_here", unshared)
    out = tmp_path / "o"
    done = run_sweep(_sweep(tmp_path), out, dask=cluster.scheduler_address, warn=lambda line: None)
    assert (done.ok, done.failed) == (4, 0), [r.get("error") for r in done.rows]
    assert {r["worker"] for r in done.rows} == {good}, done.rows
    for r in done.rows:
        assert (out / "points" / r["hash"] / "results.json").is_file()
        assert not (out / "points" / r["hash"] / "error.json").exists()
    events = _events(out)
    assert [(e["event"], e["worker"]) for e in events] == [("left-out", bad)], events
    assert events[0]["why"].startswith("PathNotOnWorker: "), events[0]
    assert all(s["ran_on"] == good for s in events[0]["sent_again"]), events[0]


def test_the_events_of_a_re_admitted_worker_and_of_one_lost_holding_points(tmp_path):
    good, bad = "tcp://10.0.0.1:1", "tcp://10.0.0.2:2"
    client = _Client({good: GOOD, bad: OLD})
    pool = executors.DaskPool(client, "tcp://s:8786", remote=True)
    pool.watch.start(refuse=True)
    pool.watch._event((0.0, {"action": "remove-worker", "worker": bad}))  # (its nanny restarts it, mended)
    client.answers[bad] = {**GOOD, "host": "hostB"}
    pool.watch.check(list(client.answers))
    key = pool.watch.key(print)
    pool.watch._event((1.0, {"action": "remove-worker", "worker": good, "processing-tasks": [key]}))
    events = pool.watch.worker_events({})
    assert [(e["event"], e["worker"]) for e in events] == [("left-out", bad), ("re-admitted", bad),
                                                            ("left-cluster", good)], events
    assert events[0]["host"] == "hostB" and "its tlm at /old/tlm" in events[0]["why"], events[0]
    assert events[1]["line"].startswith(f"the Dask worker {bad} on host hostB, left out of the sweep, came back"), \
        events
    assert events[2]["points_held"] == 1 and "left the cluster while it held 1 of the sweep's points" in \
        events[2]["line"], events[2]
    assert pool.watch.worker_events({}) == events  # (asked again: the same, none twice)


def test_the_events_of_each_sweep_into_the_folder_are_kept_and_a_damaged_file_is_said(tmp_path):
    out = tmp_path / "sw"
    out.mkdir()
    keep_worker_events(out, [])
    assert not (out / WORKERS_FILE).exists()  # (none: no file)
    keep_worker_events(out, [{"event": "left-out", "worker": "tcp://h:1", "why": "w", "line": "first"}])
    keep_worker_events(out, [{"event": "left-cluster", "worker": "tcp://h:2", "line": "second"}])
    assert [e["line"] for e in _events(out)] == ["first", "second"]

    inputs = SimpleNamespace(sweeps=[SimpleNamespace(path=out, label="sw", rows=[])])
    assert [line for line, _ in worker_events(inputs)] == ["first", "second"]
    (out / WORKERS_FILE).write_text('{"tlm": "sweep-workers/1", "events": [', encoding="utf-8")  # (cut off)
    ((line, whose),) = worker_events(inputs)
    assert line.startswith(f"{out / WORKERS_FILE} could not be read (") and whose == "the sweep sw", line
    keep_worker_events(out, [{"event": "left-out", "worker": "tcp://h:3", "line": "third"}])  # (replaced)
    assert [e["line"] for e in _events(out)] == ["third"]
