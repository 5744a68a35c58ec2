"""Review of cf0ec1f (h351: Dask workers left out of a sweep). A point sent to the good workers only (Dask's
``workers=``, no other allowed) waited for ever where those workers all left: a good worker's nanny that restarts it
gives it another port, and Dask keeps the point for the gone address, the scheduler's workers (the restarted one, the
bad one) never zero, so --dask-wait never ended the wait (a real cluster: ``tlm sweep --dask-wait 20`` still waiting
190 s after the restart). Now such a point is sent again to the good workers there. And a worker of other code that
was alone when the sweep asked it is left out too once a good worker joins (its points went on to it)."""

from __future__ import annotations

import logging

import pytest

import tlm.experiments.executors as executors
import tlm.experiments.executors_dask as executors_dask

pytest.importorskip("distributed")

from tests.test_dask_health_h341 import _Client

OTHER = "0123456789abcdef"  # a code fingerprint that is not the sweep's


def _twice(x: int) -> int:
    return 2 * x


def test_a_point_whose_good_workers_all_left_is_sent_to_the_good_ones_there(monkeypatch):
    """The point was sent to a good worker that is gone (its address: no worker now, as after a nanny's restart at
    another port); the scheduler has the bad worker and a good one: the point ran there, not waited for ever."""
    from distributed import Client, LocalCluster

    monkeypatch.setattr(executors, "WORKERS_POLL", 0.0)
    real = executors_dask.worker_probe

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp://", host="127.0.0.1",
                      dashboard_address="127.0.0.1:0", scheduler_kwargs={"dashboard": False},
                      silence_logs=logging.CRITICAL) as cluster, Client(cluster) as client:
        bad, good = sorted(w.address for w in cluster.workers.values())

        def probe_factory():
            probe = real()

            def other(runner, dask_worker=None):
                seen = probe(runner, dask_worker)
                if dask_worker.address == bad:
                    seen["fingerprint"] = OTHER
                return seen

            return other

        monkeypatch.setattr(executors_dask, "worker_probe", probe_factory)
        pool = executors.DaskPool(client, cluster.scheduler_address, remote=True, wait=600)
        try:
            pool.watch.start(refuse=True)
            assert pool.watch.targets() == [good]
            gone = "tcp://127.0.0.1:1"  # (the good worker as it was when the point was sent: left since)
            pool.watch.alive = {bad, gone}
            f = pool.submit(_twice, 21)
            pool.asked = -float("inf")
            assert pool.trouble(cancelled=False) is None  # (the scheduler's workers asked: the point moved)
            assert f.result(timeout=30) == 42  # (it waited for ever: TimeoutError)
            assert getattr(pool.watch, "sent", None) == {}  # (nothing kept of it)
        finally:
            pool.shutdown(wait=False)
            pool.quiet.restore()


def test_a_worker_of_other_code_alone_at_first_is_left_out_once_a_good_one_joins():
    """Alone, its points go to it (and fail there with why, as before); the good one that joins got them all: the
    points still went to both."""
    from tlm.fingerprint import code_fingerprint

    seen = {"host": "hostA", "tlm": "/other/tlm", "runner": True, "fingerprint": OTHER, "error": None}
    client = _Client({"tcp://10.0.0.1:1": seen})
    pool = executors.DaskPool(client, "tcp://s:8786", remote=True)
    pool.watch.start(refuse=True)  # (it loads the points: not refused)
    assert pool.watch.targets() is None
    client.answers["tcp://10.0.0.2:2"] = {**seen, "host": "hostB", "tlm": "/new/tlm",
                                          "fingerprint": code_fingerprint()}
    assert pool.watch.seen(list(client.nthreads())) == (2, "has had no worker")
    assert pool.watch.targets() == ["tcp://10.0.0.2:2"]
    (line,) = pool.lost()
    assert line.startswith("the Dask worker tcp://10.0.0.1:1 on host hostA was left out of the sweep (it cannot run "
                           f"tlm's points: its tlm at /other/tlm runs other code (code fingerprint {OTHER}; "), line


def test_a_worker_the_probe_left_out_is_named_though_the_others_turned_out_bad_too():
    """The good worker's points failed for it (none good left: they fail there with why, as before); the worker of
    other code, to which no point went and which no row names, was left out unsaid (no line at all)."""
    from tlm.fingerprint import code_fingerprint

    other = {"host": "hostA", "tlm": "/other/tlm", "runner": True, "fingerprint": OTHER, "error": None}
    good = {**other, "host": "hostB", "tlm": "/new/tlm", "fingerprint": code_fingerprint()}
    pool = executors.DaskPool(_Client({"tcp://10.0.0.1:1": other, "tcp://10.0.0.2:2": good}), "tcp://s:8786",
                              remote=True)
    pool.watch.start(refuse=True)
    assert pool.watch.targets() == ["tcp://10.0.0.2:2"]
    record = {"status": "failed", "ran": {"worker": "tcp://10.0.0.2:2"},
              "error": {"type": "OtherInputsOnWorker", "message": "the Dask worker tcp://10.0.0.2:2 sees other inputs"}}
    assert pool.watch.send_again("p1", record) is False  # (none good left: the point fails there, with why)
    assert pool.watch.last == {"tcp://10.0.0.2:2"}
    (line,) = pool.lost()
    assert line.startswith("the Dask worker tcp://10.0.0.1:1 on host hostA was left out of the sweep (it cannot run "
                           "tlm's points: its tlm at /other/tlm runs other code"), line
    assert line.endswith("(none was sent to it)"), line


def test_a_point_sent_while_no_good_worker_is_there_waits_for_one_not_for_the_bad_one():
    """The good worker gone a moment (its nanny restarts it, at another port): a point sent then went to any worker,
    the one of other code too, and failed there for good (it is sent again only to a good worker)."""
    from tlm.fingerprint import code_fingerprint

    other = {"host": "hostA", "tlm": "/other/tlm", "runner": True, "fingerprint": OTHER, "error": None}
    good = {**other, "host": "hostB", "tlm": "/new/tlm", "fingerprint": code_fingerprint()}
    client = _Client({"tcp://10.0.0.1:1": other, "tcp://10.0.0.2:2": good})
    pool = executors.DaskPool(client, "tcp://s:8786", remote=True)
    pool.watch.start(refuse=True)
    assert pool.watch.targets() == ["tcp://10.0.0.2:2"]
    del client.answers["tcp://10.0.0.2:2"]  # (restarting)
    assert pool.watch.seen(list(client.nthreads())) == (0, "has had no worker that can run the sweep's points")
    assert pool.watch.targets() == ["tcp://10.0.0.2:2"]  # (None: any worker, the bad one too)
    client.answers["tcp://10.0.0.2:3"] = good  # (back, at another port)
    assert pool.watch.seen(list(client.nthreads())) == (2, "has had no worker")
    assert pool.watch.targets() == ["tcp://10.0.0.2:3"]
