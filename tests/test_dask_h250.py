"""Dask sweeps (h250): a point's one-off seconds count the first imports of the worker's checks before its render
(the first point of each worker is not charged its start-up as functional seconds); ``tlm sweep --dask tcp://...
--dry-run`` tries the scheduler's address as the sweep does; Dask's VersionMismatchWarning is not printed (tlm says
it in its own line); a remote worker's cache line names the worker; a ``KilledWorker`` is tlm's line."""

from __future__ import annotations

import concurrent.futures as cf
import socket
import sys
import threading
import time
import warnings
from pathlib import Path
from types import SimpleNamespace

import pytest

import tlm.experiments.sweep_point as sweep_point
from tlm.errors import InputError
from tlm.experiments.sweep_point import Task, run_point

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 16}}
WHERE = "the Dask worker tcp://10.0.0.7:4242 on host nodeB"


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def _task(tmp_path: Path, name: str = "p", code: str | None = None) -> Task:
    (tmp_path / "sweep.yaml").write_text("{}\n")  # (the marker a worker looks for above the point's folder)
    return Task("h", BASE, {}, str(tmp_path), "sweep.yaml", str(tmp_path / "points" / name), {}, code=code)


def test_the_first_imports_of_a_workers_checks_are_the_points_one_off(tmp_path, monkeypatch):
    # a worker's first point imports the kernels' modules and numba in worker_versions() (0.96 s on a cold
    # worker) before its render: that is one-off work, counted in one_off as the docs say, not functional alone
    assert run_point(_task(tmp_path, "warm"))["status"] == "ok"  # (everything else imported and compiled now)
    name = f"tlm_h250_slow_{time.time_ns()}"
    (tmp_path / f"{name}.py").write_text("import time\ntime.sleep(0.4)\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    real = sweep_point.worker_versions

    def slow_first_import():
        __import__(name)  # (a module imported for the first time, as numba is on a worker's first point)
        return real()

    monkeypatch.setattr(sweep_point, "worker_versions", slow_first_import)
    got = run_point(_task(tmp_path, "cold"))
    assert got["status"] == "ok", got
    seconds = got["results"]["host_seconds"]
    assert name in sys.modules
    assert seconds["functional"] >= 0.4  # (the checks are a part of the point's functional seconds)
    assert seconds["one_off"] >= 0.35, seconds  # (and their first import its one-off; the old code: ~0)


def _refused_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]  # (closed: nothing listens there now)


def test_a_dry_run_tries_the_dask_address_as_the_sweep_does(tmp_path):
    from tlm.experiments.sweep_plan import plan_sweep

    sweep = tmp_path / "sw.yaml"
    sweep.write_text("base: cornell\nset:\n  mode: rcast\n  resolution: [16, 16]\ngrid:\n  bsp.levels: [5, 6]\n")
    address = f"tcp://127.0.0.1:{_refused_port()}"
    started = time.monotonic()
    with pytest.raises(InputError) as e:
        plan_sweep(sweep, tmp_path / "out", dask=address)
    assert time.monotonic() - started < 5
    assert e.value.key == "--dask"
    assert str(e.value).startswith(f"--dask: nothing answers at {address!r}: no process listens on port")
    assert not (tmp_path / "out").exists()
    assert plan_sweep(sweep, tmp_path / "out", dask="local").points == 2  # (a local cluster: nothing to try)


def test_a_dry_run_refuses_a_dask_address_on_the_command_line(tmp_path, capsys):
    from tlm.cli import main

    sweep = tmp_path / "sw.yaml"
    sweep.write_text("base: cornell\nset:\n  mode: rcast\n  resolution: [16, 16]\ngrid:\n  bsp.levels: [5, 6]\n")
    address = f"tcp://127.0.0.1:{_refused_port()}"
    assert main(["sweep", str(sweep), "--out", str(tmp_path / "out"), "--dask", address, "--dry-run"]) == 2
    err = capsys.readouterr()
    assert f"tlm: error: --dask: nothing answers at {address!r}" in err.err
    assert "dry run" not in err.out


def test_dasks_version_mismatch_warning_is_not_printed_as_the_client_connects(monkeypatch):
    import distributed
    from distributed.versions import VersionMismatchWarning

    import tlm.experiments.executors as executors

    class Client:  # (warns from its loop's thread as it connects, as distributed's does)
        def __init__(self, address, timeout=None):
            t = threading.Thread(target=warnings.warn, args=(VersionMismatchWarning("Mismatched versions found\n"
                                                                                    "+---------+\n| numpy |"),))
            t.start()
            t.join()

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def get_executor(self, pure=False):
            return cf.ThreadPoolExecutor(1)

    monkeypatch.setattr(distributed, "Client", Client)
    monkeypatch.setattr(executors, "answers", lambda address: None)
    from contextlib import ExitStack

    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        with ExitStack() as stack:
            pool = executors.open_executor(stack, 2, "tcp://10.0.0.7:8786", 4)
            assert isinstance(pool.client, Client)
            pool.executor.shutdown()
        warnings.warn("another warning still shown", UserWarning, stacklevel=1)
    assert [str(w.message) for w in seen] == ["another warning still shown"]


def test_a_remote_workers_cache_line_names_the_worker(tmp_path, monkeypatch):
    line = ("cannot write tlm's scene cache /dev/null/cache/scenes (not a folder): each point parses its scene "
            "again; set TLM_CACHE to a writable folder")
    monkeypatch.setattr(sweep_point, "cache_warnings", lambda: [line])
    monkeypatch.setattr(sweep_point, "dask_worker_where", lambda: WHERE)
    monkeypatch.setattr(sweep_point, "_check_worker_sees", lambda task, where: None)
    monkeypatch.setattr(sweep_point, "_check_worker_inputs", lambda task, cfg, folder, where: None)
    got = run_point(_task(tmp_path, "remote", code="the sweep's code"))
    assert got["status"] == "ok", got
    assert f"{line} (on {WHERE})" in got["results"]["warnings"]
    assert line not in got["results"]["warnings"]
    from tlm.experiments.sweep import _cache_lines

    assert _cache_lines([got], []) == [f"{line} (on {WHERE})"]  # (the sweep says it once, naming the worker)
    # a worker of the sweep's own machine (a local pool's, a --dask local one's) has the sweep's TLM_CACHE: as is
    got = run_point(_task(tmp_path, "local"))
    assert line in got["results"]["warnings"]


def test_a_killed_worker_is_tlms_line_naming_the_worker_and_the_setting(tmp_path):
    from distributed.scheduler import KilledWorker

    from tlm.experiments.sweep import _record

    f: cf.Future = cf.Future()
    f.set_exception(KilledWorker("run_point-1f2e", SimpleNamespace(address="tcp://10.0.0.7:4242"), 3))
    task = _task(tmp_path, "killed")
    got = _record(f, task)
    assert got["status"] == "failed"
    error = got["error"]
    assert error["type"] == "KilledWorker"
    message = error["message"]
    assert "https://" not in message
    assert message.startswith("the Dask workers that held this point died 4 times, the last the Dask worker "
                              "tcp://10.0.0.7:4242: ")
    assert "distributed.scheduler.allowed-failures (3)" in message
    assert "only waited in the worker's queue" in message
    assert message.endswith("a rerun into the folder runs the point again")
    assert (Path(task.out) / "error.json").is_file()
    # another failure of the worker keeps its own message
    f = cf.Future()
    f.set_exception(EOFError("the worker's process ended"))
    assert _record(f, _task(tmp_path, "other"))["error"]["message"] == "the worker's process ended"
