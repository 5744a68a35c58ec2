"""Review of 1a2b12a (h283): a Dask worker that a nanny restarts at the same address (``dask worker
--worker-port``, ``client.restart_workers``) was never asked again what tlm it has: the address stayed
checked, so a worker restarted with an older tlm was neither named as it joined nor, once it left holding
points, said to be unable to run them (and a worker refused before its restart kept that reason)."""

from __future__ import annotations

import time

import pytest

pytest.importorskip("distributed")

GOOD = {"host": "hostA", "tlm": "/new/tlm", "runner": True, "fingerprint": None, "error": None}
OLD = {"host": "hostA", "tlm": "/old/tlm", "runner": False, "fingerprint": "0e55f6ed1c4ae811", "error": None}
ADDRESS = "tcp://10.0.0.1:28802"


class _Client:
    status = "running"

    def __init__(self, answer: dict) -> None:
        self.answer = answer
        self.handlers: dict = {}
        self.asked: list = []

    def subscribe_topic(self, topic, handler):
        self.handlers[topic] = handler

    def unsubscribe_topic(self, topic):
        self.handlers.pop(topic, None)

    def run(self, fn, *args, workers=None, on_error="raise", callback_timeout=None):
        self.asked.append(workers)
        return {ADDRESS: self.answer}


def _removed(client, keys=()):
    client.handlers["all"]((time.time(), {"action": "remove-worker", "worker": ADDRESS,
                                          "processing-tasks": set(keys)}))


def test_a_worker_restarted_at_the_same_address_is_asked_again():
    from tlm.experiments.executors_dask import WorkerWatch

    client = _Client(GOOD)
    watch = WorkerWatch(client, code="0123456789abcdef")
    assert watch.check() == []
    key = watch.key(test_a_worker_restarted_at_the_same_address_is_asked_again)
    _removed(client, [key])  # (its nanny restarts it: the same address, now an older tlm)
    client.answer = OLD
    lines = watch.check([ADDRESS])
    assert len(client.asked) == 2, client.asked
    assert lines == [f"the Dask worker {ADDRESS} on host hostA cannot run tlm's points: its tlm at /old/tlm (code "
                     "fingerprint 0e55f6ed1c4ae811; the sweep's 0123456789abcdef) has no "
                     "tlm.experiments.sweep_point (it is older than the sweep's)"], lines
    key2 = watch.key(test_a_worker_restarted_at_the_same_address_is_asked_again)
    _removed(client, [key2])
    lost = watch.lost()
    assert lost[0] == f"the Dask worker {ADDRESS} on host hostA left the cluster while it held 1 of the sweep's " \
                      "points (why is in its own log)", lost  # (the first: it had been asked, and could run them)
    assert lost[1].endswith("held 1 of the sweep's points (it cannot run tlm's points: its tlm at /old/tlm (code "
                            "fingerprint 0e55f6ed1c4ae811; the sweep's 0123456789abcdef) has no "
                            "tlm.experiments.sweep_point (it is older than the sweep's))"), lost
    assert len(lost) == 2, lost


def test_a_refused_worker_restarted_with_the_sweeps_tlm_loses_the_old_reason():
    from tlm.experiments.executors_dask import WorkerWatch

    client = _Client(OLD)
    watch = WorkerWatch(client, code="0123456789abcdef")
    assert len(watch.check()) == 1
    _removed(client)
    client.answer = GOOD
    assert watch.check([ADDRESS]) == [] and len(client.asked) == 2
    key = watch.key(test_a_refused_worker_restarted_with_the_sweeps_tlm_loses_the_old_reason)
    _removed(client, [key])
    assert watch.lost() == [f"the Dask worker {ADDRESS} on host hostA left the cluster while it held 1 of the "
                            "sweep's points (why is in its own log)"]


def test_other_events_of_a_shared_scheduler_are_not_kept():
    """The "all" topic carries every client's gathers, scatters and runs: a long sweep on a busy scheduler kept
    each until it ended."""
    from tlm.experiments.executors_dask import WorkerWatch

    client = _Client(GOOD)
    watch = WorkerWatch(client)
    for _ in range(1000):
        client.handlers["all"]((time.time(), {"action": "gather", "count": 3}))
    _removed(client, ["another-client's-task"])
    assert len(watch.events) <= 1, len(watch.events)
    assert watch.lost() == []
