"""The sweep's dispatch loop takes each point as it finishes at a constant cost: it called
``cf.wait`` on every future in flight at every completion (and the local pool did as well
on its own futures), a cost per point that grew with the points (quadratic per sweep).
Counted here by the futures handed to ``cf.wait``, not timed."""

from __future__ import annotations

import concurrent.futures as cf
import json
from concurrent.futures import ThreadPoolExecutor

import pytest
import yaml

import tlm.experiments.sweep as sweep_mod
from tlm.experiments.executors import DaskPool, LocalPool
from tlm.experiments.sweep import run_sweep

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 16}}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


@pytest.fixture
def waited(monkeypatch) -> list[int]:
    """The number of futures of each ``cf.wait`` call (the sweep's and the executors')."""
    sizes: list[int] = []
    wait = cf.wait

    def counted(fs, *args, **kwargs):
        fs = list(fs)
        sizes.append(len(fs))
        return wait(fs, *args, **kwargs)

    monkeypatch.setattr(cf, "wait", counted)
    return sizes


def sweep_file(tmp_path, n: int):
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": list(range(1, n + 1))}}))
    return path


def test_a_sweep_in_process_hands_no_growing_list_of_futures_to_wait(tmp_path, waited):
    n = 12
    done = run_sweep(sweep_file(tmp_path, n), tmp_path / "o", jobs=1)
    assert (done.ok, done.failed) == (n, 0)
    assert sum(waited) <= n, waited  # (was 1 + 11 + 10 + ... + 1: every point still in flight, at each point)
    rows = [json.loads(line) for line in (tmp_path / "o" / "sweep.jsonl").read_text().splitlines()]
    assert [r["point"] for r in rows] == list(range(n))  # (rewritten in point order at the end)


def test_a_local_pool_waits_for_its_points_at_a_constant_cost_each(waited):
    """``LocalPool.run_next`` took each point with ``cf.wait`` on all the pool's futures in flight."""
    n = 40
    pool = LocalPool(2)
    try:
        futures = [pool.submit(abs, -i) for i in range(n)]
        while not all(f.done() for f in futures):
            pool.run_next()
        assert [f.result() for f in futures] == list(range(n))
        assert pool.settled == n and not pool.inflight
    finally:
        pool.shutdown(wait=True)
    assert sum(waited) <= n, waited


@pytest.mark.slow  # (worker processes that render the frame themselves)
def test_a_local_pool_sweep_keeps_its_rows_and_waits_at_a_constant_cost(tmp_path, waited):
    n = 8
    done = run_sweep(sweep_file(tmp_path, n), tmp_path / "o", jobs=2)
    assert (done.ok, done.failed) == (n, 0)
    assert sorted(r["point"] for r in done.rows) == list(range(n))
    assert sum(waited) <= n, waited


class _Client:
    """A Dask client's stand-in: points run on one thread; the scheduler always has a worker."""

    status = "running"

    def __init__(self) -> None:
        self.asked = 0
        self.pool = ThreadPoolExecutor(1)

    def get_executor(self, pure: bool = True):
        return self.pool

    def nthreads(self, callback_timeout=None):
        self.asked += 1
        return {"tcp://127.0.0.1:1": 1}


def test_a_dask_sweep_takes_its_points_as_they_finish_and_still_polls_the_cluster(tmp_path, monkeypatch, waited):
    """The Dask loop waits DASK_POLL at most for the next point, then asks the cluster for
    trouble, as before; it no longer hands every future in flight to ``cf.wait`` each time."""
    client = _Client()
    trouble: list[bool] = []
    pools: list[DaskPool] = []

    class Pool(DaskPool):
        def trouble(self, cancelled: bool):
            trouble.append(cancelled)
            return super().trouble(cancelled)

    def opened(stack, jobs, dask, points, *_):
        pools.append(Pool(client, "local", remote=False))
        return pools[0]

    monkeypatch.setattr(sweep_mod, "open_executor", opened)
    monkeypatch.setattr(sweep_mod, "DASK_POLL", 0.01)
    monkeypatch.setattr("tlm.experiments.executors.WORKERS_POLL", 0.0)
    n = 6
    done = run_sweep(sweep_file(tmp_path, n), tmp_path / "o", jobs=1, dask="local")
    assert (done.ok, done.failed) == (n, 0)
    assert sum(waited) <= n, waited
    assert len(trouble) > n and not any(trouble), trouble  # (polled while points ran: 0.01 s a poll)
    assert client.asked >= 1
