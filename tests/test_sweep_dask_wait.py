"""``tlm sweep --dask ADDR --dask-wait SECONDS``: how long a sweep waits while its Dask
scheduler has no worker (300 s before it was a setting: an hour for a batch queue's
workers, 30 s on a laptop)."""

from __future__ import annotations

import math
import time

import pytest

import tlm.experiments.executors as executors
from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments.sweep import run_sweep

from .test_dask_cluster import Cluster, sweep_file

pytest.importorskip("distributed")


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def test_a_short_dask_wait_stops_a_workerless_sweep_with_one_line_naming_it(tmp_path, capsys):
    """A real ``dask scheduler`` with no worker and ``--dask-wait 1``: one line naming the
    scheduler and the wait, exit status 1, in seconds (it waited 300 s, the only wait there was)."""
    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]})
    out = tmp_path / "o"
    c = Cluster(tmp_path / "cluster")
    try:
        c.scheduler()
        t0 = time.monotonic()
        rc = main(["sweep", str(path), "--out", str(out), "--dask", c.address, "--dask-wait", "1", "--no-report",
                   "--no-progress"])
        took = time.monotonic() - t0
    finally:
        c.close()
    err = capsys.readouterr().err
    assert rc == 1, err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith(f"tlm: error: the Dask scheduler {c.address} has had no worker for "), lines
    assert "(--dask-wait: 1 s)" in lines[0] and "0 of 2 points done" in lines[0], lines
    assert took < 60, took  # (the wait, the connection and the sweep's set-up; not 300 s)


def test_the_wait_is_asked_of_the_scheduler_within_it(tmp_path):
    """A wait shorter than WORKERS_POLL (5 s) is not overrun by the poll: the sweep asks the
    scheduler for its workers twice within the wait (it stopped only at the next poll, 5 s on)."""
    pool = executors.DaskPool.__new__(executors.DaskPool)
    asked: list[float] = []

    class Client:
        status = "running"

        def nthreads(self, callback_timeout=None):
            asked.append(time.monotonic())
            return {}

    pool.client, pool.address, pool.quiet = Client(), "tcp://x:1", executors._Quiet()
    pool.wait, pool.workerless_since, pool.asked = 1.0, None, -math.inf
    why = None
    deadline = time.monotonic() + 10
    try:
        while why is None and time.monotonic() < deadline:
            why = pool.trouble(cancelled=False)
            time.sleep(0.05)
    finally:  # (trouble silenced distributed's loggers: put back, as the sweep's stack does, for the
        pool.quiet.restore()  # tests after this one in the process, tests/test_dask_local_clean_exit.py's)
    assert why is not None and why.startswith("the Dask scheduler tcp://x:1 has had no worker for "), why
    assert why.endswith("(--dask-wait: 1 s)"), why
    assert asked[-1] - asked[0] < executors.WORKERS_POLL, asked


@pytest.mark.parametrize("value", ["-1", "0", "-3", "1e400", "nan", "inf", "-inf"])
def test_a_bad_wait_is_one_line_exit_2_and_nothing_written(tmp_path, capsys, value):
    """The value is echoed as typed (``-3``, not the ``-3.0`` it reads as)."""
    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]})
    out = tmp_path / "o"
    rc = main(["sweep", str(path), "--out", str(out), "--dask", "tcp://127.0.0.1:9", f"--dask-wait={value}",
               "--no-report"])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert len(err.strip().splitlines()) == 1 and err.startswith("tlm: error: --dask-wait: "), err
    assert "a finite number > 0" in err, err
    assert err.startswith(f"tlm: error: --dask-wait: {value} is not a wait: "), err
    assert not out.exists()


def test_a_wait_that_is_not_a_number_is_one_line_exit_2(tmp_path, capsys):
    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]})
    rc = main(["sweep", str(path), "--out", str(tmp_path / "o"), "--dask", "local", "--dask-wait", "soon"])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert "--dask-wait" in err and "'soon'" in err, err
    assert not (tmp_path / "o").exists()


def test_a_wait_without_dask_is_refused_not_dropped(tmp_path, capsys):
    """``--dask-wait`` on a local sweep would be read by nothing: refused, exit 2."""
    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]})
    rc = main(["sweep", str(path), "--out", str(tmp_path / "o"), "--jobs", "1", "--dask-wait", "30"])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1, err
    assert err.startswith("tlm: error: --dask-wait: 30: ") and "--dask" in err, err  # (as typed)
    assert not (tmp_path / "o").exists()


@pytest.mark.parametrize("value", [-5, 0, math.nan, math.inf, "30", True])
def test_the_api_refuses_a_bad_wait(tmp_path, value):
    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]})
    with pytest.raises(InputError, match=r"^--dask-wait: .* is not a wait: .*a finite number > 0$"):
        run_sweep(path, tmp_path / "o", dask="tcp://127.0.0.1:9", dask_wait=value)
    assert not (tmp_path / "o").exists()


def test_the_api_passes_the_wait_to_the_dask_pool(tmp_path, monkeypatch):
    """``dask_wait`` reaches the pool that checks the scheduler (as ``--dask-wait`` does)."""
    seen: list[float | None] = []

    def opened(stack, jobs, dask, points, dask_wait=None):
        seen.append(dask_wait)
        raise InputError("stop here", key="--dask")

    import tlm.experiments.sweep as sweep_mod

    monkeypatch.setattr(sweep_mod, "open_executor", opened)
    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]})
    with pytest.raises(InputError, match="stop here"):
        run_sweep(path, tmp_path / "o", dask="tcp://127.0.0.1:9", dask_wait=45)
    assert seen == [45.0]
