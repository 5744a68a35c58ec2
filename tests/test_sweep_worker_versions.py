"""A sweep point records the versions of the process that ran it (a remote Dask worker's, not
the submitting one's), and a Dask worker whose numpy, numba or Python (major.minor) differ from
the sweep's is refused: its points fail with one line naming the library and both versions, as a
worker of other tlm code does (``OtherCodeOnWorker``). Other kernels (``TLM_KERNELS``) are
recorded, not refused: both engines give the same bits."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import pytest
import yaml

import tlm.experiments.sweep_point as sweep_point
from tlm.experiments.dask_workers import OtherVersionsOnWorker, check_worker_versions, worker_versions
from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_point import Task, run_point

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 16}}
WHERE = "the Dask worker tcp://10.0.0.7:4242 on host nodeB"
SWEEPS = {"python": "3.11.7", "platform": "Linux", "tlm": "0.1.0", "numpy": "2.4.6", "scipy": "1.17.1",
          "numba": "0.68.1", "simpy": "4.1.2", "kernels": "numba"}


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


def test_a_worker_with_another_numpy_is_refused_naming_both_versions():
    check_worker_versions(SWEEPS, dict(SWEEPS), WHERE)  # the same: nothing said
    # what cannot change a point's bits passes: Python's patch level, scipy, simpy, the platform, the
    # kernels (the compiled and numpy engines give the same bits)
    check_worker_versions(SWEEPS, {**SWEEPS, "python": "3.11.9", "scipy": "1.0", "simpy": "4.0", "platform": "x",
                                   "kernels": "numpy"}, WHERE)
    check_worker_versions(None, {**SWEEPS, "numpy": "1.26.4"}, WHERE)  # (a task without the sweep's versions)
    with pytest.raises(OtherVersionsOnWorker) as e:
        check_worker_versions(SWEEPS, {**SWEEPS, "numpy": "1.26.4"}, WHERE)
    assert str(e.value) == (
        f"{WHERE} runs numpy 1.26.4 (the sweep's 2.4.6): its points could give other results than the sweep's; "
        "install the sweep's versions on the workers and restart them")
    with pytest.raises(OtherVersionsOnWorker, match=r"runs Python 3\.12 \(the sweep's 3\.11\) and numba 0\.60\.0 "
                                                    r"\(the sweep's 0\.68\.1\): "):
        check_worker_versions(SWEEPS, {**SWEEPS, "python": "3.12.1", "numba": "0.60.0"}, WHERE)
    with pytest.raises(OtherVersionsOnWorker, match=r"runs numba 0\.60\.0 \(the sweep's 0\.68\.1\)"):
        check_worker_versions(SWEEPS, {**SWEEPS, "numba": "0.60.0"}, WHERE)
    # a worker on the numpy kernels (numba not there, or TLM_KERNELS=numpy) runs the reference the compiled
    # kernels are checked against: its numba does not matter
    check_worker_versions(SWEEPS, {**SWEEPS, "numba": "not installed", "kernels": "numpy"}, WHERE)
    check_worker_versions(SWEEPS, {**SWEEPS, "numba": "0.60.0", "kernels": "numpy"}, WHERE)


def test_the_versions_of_a_worker_follow_its_tlm_kernels(monkeypatch):
    monkeypatch.setenv("TLM_KERNELS", "numpy")
    assert worker_versions()["kernels"] == "numpy"
    monkeypatch.setenv("TLM_KERNELS", "")
    from tlm.kernels.engine import engine

    assert worker_versions()["kernels"] == engine()


def _task(tmp_path: Path, provenance: dict, name: str = "p") -> Task:
    (tmp_path / "sweep.yaml").write_text("{}\n")  # (the marker a worker looks for above the point's folder)
    return Task("h", BASE, {}, str(tmp_path), "sweep.yaml", str(tmp_path / "points" / name), provenance)


def test_a_point_records_the_versions_of_the_process_that_ran_it(tmp_path):
    """The submitting process's versions were written into every point's results.json."""
    got = run_point(_task(tmp_path, {"versions": {**SWEEPS, "numpy": "0.0.submitter"}, "git_revision": None}))
    assert got["status"] == "ok", got
    results = json.loads((tmp_path / "points" / "p" / "results.json").read_text())
    assert results["versions"] == worker_versions() and results["versions"]["numpy"] != "0.0.submitter"
    assert results["git_revision"] is None  # (the rest of the sweep's provenance as it was)


def test_a_point_on_a_dask_worker_of_other_versions_fails_with_one_line(tmp_path, monkeypatch):
    """As a worker of other code, the point fails before it renders, its error.json written."""
    monkeypatch.setattr(sweep_point, "dask_worker_where", lambda: WHERE)
    here = worker_versions()
    sweeps = {**here, "numpy": "0.0.submitter"}
    got = run_point(_task(tmp_path, {"versions": sweeps}))
    assert got["status"] == "failed" and got["error"]["type"] == "OtherVersionsOnWorker"
    assert got["error"]["message"].startswith(f"{WHERE} runs numpy {here['numpy']} (the sweep's 0.0.submitter): ")
    assert "(on " not in got["error"]["message"]  # (it says where once)
    assert json.loads((tmp_path / "points" / "p" / "error.json").read_text())["type"] == "OtherVersionsOnWorker"


def test_a_cluster_whose_worker_runs_the_numpy_kernels_records_them(tmp_path, monkeypatch):
    """A Dask worker started with ``TLM_KERNELS=numpy`` (the sweep's: numba) runs the sweep's points
    (the same bits) and its points record its kernels: they recorded the sweep's."""
    pytest.importorskip("distributed")
    from distributed import LocalCluster

    from tlm.kernels.engine import numba_available

    if not numba_available():
        pytest.skip("numba does not import: the sweep's kernels are numpy's too")
    monkeypatch.setenv("TLM_KERNELS", "numba")
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"arch.fifo_depth": [1, 16]}}, sort_keys=False))
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address="127.0.0.1:0",
                      scheduler_kwargs={"dashboard": False}, silence_logs=logging.CRITICAL,
                      env={"TLM_KERNELS": "numpy"}) as cluster:
        done = run_sweep(path, tmp_path / "o", dask=cluster.scheduler_address)
    assert (done.ok, done.failed) == (2, 0), [row["error"] for row in done.rows]
    for row in done.rows:
        results = json.loads((tmp_path / "o" / "points" / row["hash"] / "results.json").read_text())
        assert results["versions"]["kernels"] == "numpy"
