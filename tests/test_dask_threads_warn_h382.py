"""A Dask point that gives ``render.threads`` says when that count, times the points that run at once on its
worker's machine (the task slots of the workers there, as ``dask_worker_threads`` counts them: one question to the
scheduler), oversubscribes the machine's CPUs: it runs as asked, its ``results.json`` warning names the machine,
render.threads, the points at once and the CPUs, the sweep says it once per machine at its end, and ``tlm report``
shows it. A null ``render.threads`` (sized to fit) and a point outside Dask say nothing."""

from __future__ import annotations

import time
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml

from tlm.experiments import dask_workers
from tlm.kernels import threads


@pytest.fixture
def worker(monkeypatch):
    """A Dask worker of 2 threads at 10.0.0.5, whose machine's workers run 32 points at once on 32 CPUs (what the
    scheduler said, kept); the scheduler is not asked again."""
    w = SimpleNamespace(address="tcp://10.0.0.5:4001", state=SimpleNamespace(nthreads=2))
    monkeypatch.setattr(dask_workers, "_dask_worker", lambda: w)
    monkeypatch.setattr(dask_workers, "_SLOTS", {w.address: (time.monotonic(), 32)})
    monkeypatch.setattr(threads, "available", lambda: 32)
    return w


def test_a_given_count_past_the_machines_cpus_is_said_naming_the_machine(worker):
    (line,) = dask_workers.dask_oversubscribed(16)
    assert line.startswith("render.threads = 16 on host 10.0.0.5 with 32 points at once (the task slots of its Dask "
                           "workers) oversubscribes its 32 CPUs available (512 kernel threads): "), line
    assert "dask worker --nthreads" in line and "leave render.threads null" in line and "\n" not in line
    assert "lower --jobs" in dask_workers.dask_oversubscribed(16, local=True)[0]  # (--dask local: its --jobs)
    (line,) = dask_workers.dask_oversubscribed(16, running=4)  # (a sweep of 4 points runs no more at once)
    assert "with 4 points at once" in line and "(64 kernel threads)" in line, line


@pytest.mark.parametrize("asked, running", [(None, 0), (1, 0), (64, 0), (16, 2), (16, 1)])
def test_no_line_where_the_count_fits_is_null_or_is_said_alone(worker, asked, running):
    """Null: sized to fit; 1 x 32 = 32 fits; 64 alone past 32 CPUs: threads_warning's line says it (as the local
    --jobs line leaves it to sweep_threads_line); 2 points x 16 fit; one point at a time."""
    assert dask_workers.dask_oversubscribed(asked, running) == []


def test_outside_dask_nothing_is_said(monkeypatch):
    monkeypatch.setattr(threads, "available", lambda: 1)
    assert dask_workers.dask_oversubscribed(16) == []  # (not in a worker: the sweep's own --jobs line)


def test_the_slots_are_the_ones_dask_worker_threads_counts_asked_once(monkeypatch):
    w = SimpleNamespace(address="tcp://10.0.0.7:4001", state=SimpleNamespace(nthreads=4))
    monkeypatch.setattr(dask_workers, "_dask_worker", lambda: w)
    monkeypatch.setattr(dask_workers, "_SLOTS", {})
    monkeypatch.setattr(threads, "available", lambda: 8)
    asked = []

    class Client:
        def scheduler_info(self, n_workers=None):
            asked.append(n_workers)
            return {"workers": {w.address: {"host": "10.0.0.7", "nthreads": 4},
                                "tcp://10.0.0.7:4002": {"host": "10.0.0.7", "nthreads": 4},
                                "tcp://10.0.0.8:4001": {"host": "10.0.0.8", "nthreads": 64}}}

    import distributed

    monkeypatch.setattr(distributed, "get_client", lambda timeout=None: Client())
    assert dask_workers.dask_worker_threads() == 1  # (8 CPUs over 8 slots on this machine)
    (line,) = dask_workers.dask_oversubscribed(2)
    assert "render.threads = 2 on host 10.0.0.7 with 8 points at once" in line and "(16 kernel threads)" in line
    assert asked == [-1]  # (one question: what it said, kept)


def test_the_sweep_says_it_once_per_machine():
    def line(t, host, n, cpus=8):
        return (f"render.threads = {t} on host {host} with {n} points at once (the task slots of its Dask workers) "
                f"oversubscribes its {cpus} CPUs available ({t * n} kernel threads): ...")

    lines = [line(2, "a", 8), "another warning", line(2, "a", 8), line(4, "b", 4), line(4, "a", 8), line(2, "b", 4)]
    assert dask_workers.machine_lines(lines) == [line(4, "a", 8), line(4, "b", 4)]
    assert dask_workers.machine_lines(["render.threads = 9 is more than the 8 CPUs available", None]) == []


def test_a_dask_local_sweep_of_two_workers_says_it_and_the_report_shows_it(tmp_path, capsys, monkeypatch):
    """--dask local --jobs 2, each point render.threads 2 on a machine of 2 CPUs (available() pinned in the
    workers by TLM's own reading of it: the test machine's CPUs, at least 2 here): 4 kernel threads on 2 CPUs."""
    pytest.importorskip("distributed")
    from tlm.cli import main

    cpus = threads.available()
    asked = max(1, cpus // 2 + 1)  # (past the CPUs at 2 points at once, no more than them alone)
    if asked > cpus:
        pytest.skip("one CPU: a count past it is threads_warning's alone")
    tiny = {"scene": "cornell", "mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "threads": asked},
            "arch": {"trace": False}}
    path = tmp_path / "sw.yaml"
    path.write_text(yaml.safe_dump({"base": tiny, "grid": {"seed": [0, 1]}}, sort_keys=False))
    out = tmp_path / "o"
    assert main(["sweep", str(path), "--out", str(out), "--dask", "local", "--jobs", "2", "--no-progress"]) == 0
    err = capsys.readouterr().err
    start = f"render.threads = {asked} on host 127.0.0.1 with 2 points at once"
    assert err.count(start) == 1, err  # (two points, one machine: said once)
    assert "lower --jobs" in err
    import json

    for point in (out / "points").iterdir():
        warned = json.loads((point / "results.json").read_text())["warnings"]
        assert any(w.startswith(start) for w in warned), warned
    page = Path(out / "report" / "report.html").read_text(encoding="utf-8")
    assert start in page
