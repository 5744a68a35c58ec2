"""Review of the Dask oversubscription line (h382), and its follow-up: a point's line names its points at once as
what they are (the task slots of its machine's workers, or all the sweep runs where those are fewer); a point of one
kernel thread (a null count's there too) says nothing; the lines the workers write are the ones ``machine_lines``
reads back; and a remote Dask point's line of a given ``render.threads`` past its machine's CPUs alone (which the
sweep does not say as it starts) is said by the sweep once per machine as it ends, as the oversubscription line."""

from __future__ import annotations

import dataclasses
import time
from types import SimpleNamespace

import pytest
import yaml

from tlm.config import config_from_dict
from tlm.experiments import dask_workers, sweep_point
from tlm.kernels import threads


@pytest.fixture
def worker(monkeypatch):
    """A Dask worker at 10.0.0.5 whose machine's workers have 32 task slots (what the scheduler said, kept)."""
    w = SimpleNamespace(address="tcp://10.0.0.5:4001", state=SimpleNamespace(nthreads=2))
    monkeypatch.setattr(dask_workers, "_dask_worker", lambda: w)
    monkeypatch.setattr(dask_workers, "_SLOTS", {w.address: (time.monotonic(), 32)})
    return w


def test_points_at_once_capped_by_the_sweep_are_not_called_the_task_slots(worker, monkeypatch):
    monkeypatch.setattr(threads, "available", lambda: 32)
    (line,) = dask_workers.dask_oversubscribed(16, running=4)  # (was: "4 points at once (the task slots of ...)")
    assert "with 4 points at once (all the sweep runs, of its Dask workers' 32 task slots) oversubscribes" in line
    (full,) = dask_workers.dask_oversubscribed(16, running=32)  # (as many as the slots: the slots)
    assert "with 32 points at once (the task slots of its Dask workers) oversubscribes" in full
    # (both read back, as the workers wrote them: the one of more kernel threads for the machine)
    assert dask_workers.machine_lines([line, full]) == [full]
    assert dask_workers.machine_lines([line]) == [line]


def test_one_thread_where_the_slots_alone_are_past_the_cpus_says_nothing(worker, monkeypatch):
    """32 slots on 16 CPUs: a null point gets one thread there (shared_threads) and says nothing; one that gives
    render.threads = 1 runs the same and says nothing either (its line told it to leave the count null: no
    change). Two threads: twice the null's, said."""
    monkeypatch.setattr(threads, "available", lambda: 16)
    assert threads.shared_threads(32) == 1
    assert dask_workers.dask_oversubscribed(1) == []
    (line,) = dask_workers.dask_oversubscribed(2)
    assert line.startswith("render.threads = 2 on host 10.0.0.5 with 32 points at once"), line


REMOTE = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "threads": 64}}


def _remote_lines(asked: int, where: str) -> list[str]:
    """A remote Dask point's _threads_lines (task.code: a remote worker's), on a machine of 32 CPUs."""
    config = {**REMOTE, "render": {**REMOTE["render"], "threads": asked}}
    task = sweep_point.Task("h", config, {}, ".", "sw.yaml", "/x", {}, code="c0de")
    return sweep_point._threads_lines(task, config_from_dict(config), where)


def test_a_remote_workers_line_of_a_count_past_its_cpus_alone_is_said_once_per_machine(monkeypatch):
    monkeypatch.setattr(threads, "available", lambda: 32)
    (a,) = _remote_lines(48, "the Dask worker w1-0 (tcp://10.0.0.7:4000) on host node7")
    (b,) = _remote_lines(64, "the Dask worker w1-1 (tcp://10.0.0.7:4001) on host node7")  # (same machine, more)
    # (a name of spaces and parentheses, an IPv6 address: the host is the line's last words)
    (c,) = _remote_lines(40, "the Dask worker my w (x) (tcp://[fe80::1]:4000) on host node8.example")
    local = "render.threads = 64 is more than the 32 CPUs available to this process (its affinity mask, ...)"
    assert dask_workers.machine_lines([a, local, b, c, a, None]) == [b, c]  # (was: [])
    assert dask_workers.machine_lines([local]) == []  # (a local worker's: the sweep said it as it started)


def test_a_sweep_says_a_remote_workers_line_once_as_it_ends(tmp_path, monkeypatch):
    """Two points on one remote worker, as run_point records them (its _threads_lines as a remote worker's: no
    Dask here, the sweep runs them in its own process): the sweep's warn gets the line once, and its
    Outcome.warnings holds it (the CLI's count of the points' warnings then leaves it out)."""
    from tlm.experiments.sweep import run_sweep

    monkeypatch.setattr(threads, "available", lambda: 1)
    where = "the Dask worker w7 (tcp://10.0.0.7:4000) on host node7"
    own = sweep_point._threads_lines
    monkeypatch.setattr(sweep_point, "_threads_lines",
                        lambda task, cfg, _: own(dataclasses.replace(task, code="c0de"), cfg, where))
    base = {**REMOTE, "render": {"spp": 1, "threads": 2}, "arch": {"trace": False}}
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump({"base": base, "grid": {"seed": [0, 1]}}, sort_keys=False))
    warned: list[str] = []
    done = run_sweep(path, tmp_path / "o", jobs=1, warn=warned.append)
    assert done.ok == 2
    said = [w for w in warned if w.endswith(f"(on {where})")]
    assert len(said) == 1 and said[0].startswith("render.threads = 2 is more than the 1 CPU available"), warned
    assert said[0] in done.warnings
