"""The last read of this stop (h361) on the Dask workers left out of a sweep:

* an error of tlm's own in the check of the scheduler's workers (``WorkerWatch.seen``: its probe, a point moved) was
  taken for the scheduler's silence ("has not answered (RuntimeError: ...)" after --dask-wait): it now goes on;
* a worker left out that leaves and comes back at its address answering well (restarted, mended) is asked afresh
  and takes points again (it stayed out, ``bad`` never cleared); the line on it is kept;
* a worker left out for a failed point that had run again already is said to have had "none of them run again
  there", not "none was sent to it".
"""

from __future__ import annotations

import pytest

import tlm.experiments.executors as executors

pytest.importorskip("distributed")

from tests.test_dask_health_h341 import GOOD, OLD, _Client


def test_an_error_in_the_check_of_the_workers_is_not_a_silent_scheduler(monkeypatch):
    monkeypatch.setattr(executors, "WORKERS_POLL", 0.0)
    pool = executors.DaskPool(_Client({"tcp://10.0.0.1:1": GOOD}), "tcp://s:8786", remote=True, wait=0.01)

    def broken(workers):
        raise RuntimeError("a defect of tlm's own")

    monkeypatch.setattr(pool.watch, "seen", broken)
    pool.asked = -float("inf")
    try:
        with pytest.raises(RuntimeError, match="a defect of tlm's own"):
            pool.trouble(cancelled=False)
    finally:
        pool.quiet.restore()


def test_a_worker_left_out_that_comes_back_answering_well_takes_points_again():
    good, bad = "tcp://10.0.0.1:1", "tcp://10.0.0.2:2"
    client = _Client({good: GOOD, bad: OLD})
    pool = executors.DaskPool(client, "tcp://s:8786", remote=True)
    pool.watch.start(refuse=True)
    assert pool.watch.targets() == [good]
    pool.watch._event((0.0, {"action": "remove-worker", "worker": bad}))  # (its nanny restarts it, mended)
    client.answers[bad] = {**GOOD, "host": "hostB"}
    pool.watch.check(list(client.answers))
    assert pool.watch.good() == [good, bad] and pool.watch.targets() is None  # (none left out: every worker)
    (line,) = pool.lost()
    assert "tcp://10.0.0.2:2 on host hostB was left out of the sweep" in line, line


def test_a_worker_left_out_for_a_point_run_again_already_says_none_of_them_ran_again():
    good, bad = "tcp://10.0.0.1:1", "tcp://10.0.0.2:2"
    pool = executors.DaskPool(_Client({good: GOOD, bad: {**GOOD, "host": "hostB"}}), "tcp://s:8786", remote=True)
    pool.watch.start(refuse=True)
    pool.watch.again.add("p")  # (the point ran again once already: here it fails for its worker a second time)
    record = {"status": "failed", "error": {"type": "OtherInputsOnWorker", "message": "its inputs differ"},
              "ran": {"worker": bad}}
    assert pool.watch.send_again("p", record) is False
    (line,) = pool.lost()
    assert line.endswith("its points went to the other workers (none of them run again there)"), line
