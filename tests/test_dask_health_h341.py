"""A Dask cluster with some bad workers (h341): a worker that cannot run the sweep's points (another tlm code, found
by the probe before any point is sent, which now compares the code fingerprint of a worker that has the point
runner too; or one whose points fail for it: ``PathNotOnWorker``, ``OtherCodeOnWorker``, ``OtherInputsOnWorker``,
``OtherVersionsOnWorker``) is left out while a good worker remains, and the points that failed there for it run
again, once, on the good ones; one line per bad worker says which, why, and that its points went to the others.
With no good worker, as before: the points fail there with why. ``OtherInputsOnWorker`` names the first of the
sweep's input files that differs where the worker reads it."""

from __future__ import annotations

import logging

import pytest
import yaml

import tlm.experiments.executors as executors
import tlm.experiments.executors_dask as executors_dask
import tlm.experiments.sweep_point as sweep_point
from tlm.experiments.sweep import run_sweep

pytest.importorskip("distributed")

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 16}}
OTHER = "0123456789abcdef"  # a code fingerprint that is not the sweep's


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


@pytest.fixture
def cluster():
    """A scheduler and two workers of one thread each, in this process (threads: the sweep's own tlm), over TCP."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=False, protocol="tcp://", host="127.0.0.1",
                      dashboard_address="127.0.0.1:0",
                      scheduler_kwargs={"dashboard": False}, silence_logs=logging.CRITICAL) as c:
        yield c


def _sweep(tmp_path, n: int = 4):
    """``n`` points of as many frames: the sweep sends them all at once (one per functional key)."""
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": BASE, "grid": {"seed": list(range(1, n + 1))}}, sort_keys=False))
    return path


def _addresses(c) -> list[str]:
    return sorted(w.address for w in c.workers.values())


def _probe_says_other_code(monkeypatch, bad: set[str]) -> None:
    """The probe of each worker in ``bad`` answers another code fingerprint (a worker of another tlm's code)."""
    real = executors_dask.worker_probe

    def probe_factory():
        probe = real()

        def other(runner, dask_worker=None):
            seen = probe(runner, dask_worker)
            if dask_worker.address in bad:
                seen["fingerprint"] = OTHER
            return seen

        return other

    monkeypatch.setattr(executors_dask, "worker_probe", probe_factory)


def _points_fail_on(monkeypatch, bad: set[str], kind=sweep_point.OtherInputsOnWorker, why="sees other inputs") -> None:
    """A point run on a worker in ``bad`` fails as on a worker that reads other inputs (``kind``, ``why``)."""
    real = sweep_point._check_worker_sees

    def sees(task, where):
        if any(f"{a} " in f"{where} " for a in bad):
            raise kind(f"{where} {why} (stand-in)")
        return real(task, where)

    monkeypatch.setattr(sweep_point, "_check_worker_sees", sees)


def _submitted(monkeypatch) -> list:
    """The ``workers`` each point was submitted with (``Client.submit``'s: None, any worker)."""
    from distributed import Client

    sent: list = []
    submit = Client.submit

    def spy(self, *args, **kwargs):
        sent.append((kwargs.get("workers"), kwargs.get("allow_other_workers")))
        return submit(self, *args, **kwargs)

    monkeypatch.setattr(Client, "submit", spy)
    return sent


def test_the_probe_says_the_code_fingerprint_of_a_worker_that_has_the_runner():
    """It said it only for a worker without the point runner: one of other code that has it passed the probe."""
    from tlm.fingerprint import code_fingerprint

    seen = executors_dask.worker_probe()(executors_dask.RUNNER)
    assert seen["runner"] is True and seen["fingerprint"] == code_fingerprint(), seen
    assert executors_dask.other_code(seen, code_fingerprint()) is None
    why = executors_dask.other_code({**seen, "fingerprint": OTHER}, code_fingerprint())
    assert why is not None and why.startswith(f"its tlm at {seen['tlm']} runs other code (code fingerprint {OTHER}; "
                                              f"the sweep's {code_fingerprint()}): install the sweep's tlm"), why
    assert executors_dask.cannot_run({**seen, "fingerprint": OTHER}) is None  # (it loads the points: not refused)


def test_a_worker_the_probe_finds_of_other_code_is_left_out_and_named_once(tmp_path, cluster, monkeypatch):
    """Its points failed there (OtherCodeOnWorker), though the other worker could run them; with both of other code,
    as before: the probe refuses nothing (they load the points) and each point fails there with why."""
    bad, good = _addresses(cluster)
    _probe_says_other_code(monkeypatch, {bad})
    _points_fail_on(monkeypatch, {bad}, sweep_point.OtherCodeOnWorker, "runs other tlm code")
    sent = _submitted(monkeypatch)
    warned: list[str] = []
    done = run_sweep(_sweep(tmp_path), tmp_path / "o", dask=cluster.scheduler_address, warn=warned.append)
    assert (done.ok, done.failed) == (4, 0), [r.get("error") for r in done.rows]
    assert {r["worker"] for r in done.rows} == {good}, done.rows
    assert sent == [([good], False)] * 4, sent  # (none sent to it)
    lines = [w for w in warned if bad in w]
    assert len(lines) == 1, warned
    assert lines[0].startswith(f"the Dask worker {bad} on host ") and " was left out of the sweep (it cannot run " \
        "tlm's points: its tlm at " in lines[0], lines[0]
    assert f"(code fingerprint {OTHER}; the sweep's " in lines[0], lines[0]
    assert lines[0].endswith("its points went to the other workers (none was sent to it)"), lines[0]
    assert good not in " ".join(warned), warned

    _probe_says_other_code(monkeypatch, {bad, good})  # (none good)
    _points_fail_on(monkeypatch, {bad, good}, sweep_point.OtherCodeOnWorker, "runs other tlm code")
    warned.clear()
    done = run_sweep(_sweep(tmp_path, 2), tmp_path / "o2", dask=cluster.scheduler_address, warn=warned.append)
    assert (done.ok, done.failed) == (0, 2)
    assert all(r["error"].startswith("OtherCodeOnWorker: the Dask worker tcp://127.0.0.1:") for r in done.rows), \
        done.rows
    assert not [w for w in warned if "left out" in w], warned


def test_points_that_failed_for_their_worker_run_again_on_the_good_one(tmp_path, cluster, monkeypatch):
    """They were recorded failed; with both workers bad, as before: each point fails there with why (the one sent
    again too), and no line says a worker was left out."""
    bad, good = _addresses(cluster)
    _points_fail_on(monkeypatch, {bad})
    sent = _submitted(monkeypatch)
    warned: list[str] = []
    done = run_sweep(_sweep(tmp_path), tmp_path / "o", dask=cluster.scheduler_address, warn=warned.append)
    assert (done.ok, done.failed) == (4, 0), [r.get("error") for r in done.rows]
    assert {r["worker"] for r in done.rows} == {good}, done.rows
    assert ([good], False) in sent and (None, None) in sent, sent  # (the first sent to any worker)
    for r in done.rows:  # (the error.json the bad worker wrote: replaced by the point's results)
        assert not (tmp_path / "o" / "points" / r["hash"] / "error.json").exists()
    lines = [w for w in warned if bad in w]
    assert len(lines) == 1, warned  # (one line for the worker, not one per point)
    assert lines[0].startswith(f"the Dask worker {bad} on host ") and " was left out of the sweep " \
        f"(OtherInputsOnWorker: the Dask worker {bad} on host " in lines[0], lines[0]
    assert "sees other inputs (stand-in)); its points went to the other workers (" in lines[0]
    assert lines[0].endswith(" of them run again there)") and "(0 of" not in lines[0], lines[0]
    again = run_sweep(_sweep(tmp_path), tmp_path / "o", dask=cluster.scheduler_address)  # (all done: none to run)
    assert (again.ok, again.skipped) == (0, 4)

    _points_fail_on(monkeypatch, {bad, good})  # (none good)
    warned.clear()
    done = run_sweep(_sweep(tmp_path, 2), tmp_path / "o2", dask=cluster.scheduler_address, warn=warned.append)
    assert (done.ok, done.failed) == (0, 2)
    assert all(r["error"].startswith("OtherInputsOnWorker: the Dask worker tcp://127.0.0.1:") for r in done.rows), \
        done.rows
    assert not [w for w in warned if "left out" in w], warned


class _Client:
    """A client of a scheduler whose workers answer the probe with ``answers``."""

    status = "running"

    def __init__(self, answers: dict) -> None:
        self.answers = answers

    def get_executor(self, pure=False):
        return self

    def run(self, fn, *args, workers=None, on_error="raise", callback_timeout=None):
        return {a: s for a, s in self.answers.items() if workers is None or a in workers}

    def nthreads(self, callback_timeout=None):
        return dict.fromkeys(self.answers, 1)


GOOD = {"host": "hostA", "tlm": "/new/tlm", "runner": True, "fingerprint": None, "error": None}
OLD = {"host": "hostB", "tlm": "/old/tlm", "runner": False, "fingerprint": "0e55f6ed1c4ae811", "error": None}


def test_a_worker_that_cannot_load_the_points_beside_a_good_one_is_left_out_not_refused():
    """The probe's worker of an older tlm refused the whole sweep though another could run it."""
    from tlm.experiments.executors_dask import WorkerCannotRun

    pool = executors.DaskPool(_Client({"tcp://10.0.0.1:1": GOOD, "tcp://10.0.0.2:2": OLD}), "tcp://s:8786",
                              remote=True)
    pool.watch.start(refuse=True)
    assert pool.watch.targets() == ["tcp://10.0.0.1:1"]
    (line,) = pool.lost()
    assert line.startswith("the Dask worker tcp://10.0.0.2:2 on host hostB was left out of the sweep (it cannot run "
                           "tlm's points: its tlm at /old/tlm (code fingerprint 0e55f6ed1c4ae811; "), line
    assert pool.trouble(cancelled=False) is None  # (a good worker: none to wait for)
    alone = executors.DaskPool(_Client({"tcp://10.0.0.2:2": OLD}), "tcp://s:8786", remote=True)
    with pytest.raises(WorkerCannotRun, match=r"^the Dask worker tcp://10\.0\.0\.2:2 on host hostB cannot run tlm's "):
        alone.watch.start(refuse=True)  # (none good: refused, as before)
    assert alone.watch.targets() is None and alone.lost() == []


def test_a_sweep_waits_no_longer_than_its_wait_for_a_good_worker(monkeypatch):
    """The good workers gone, the points sent to them alone would wait for ever beside the bad one that is there."""
    monkeypatch.setattr(executors, "WORKERS_POLL", 0.0)
    client = _Client({"tcp://10.0.0.1:1": GOOD, "tcp://10.0.0.2:2": OLD})
    pool = executors.DaskPool(client, "tcp://s:8786", remote=True, wait=0.01)
    pool.watch.start(refuse=True)
    del client.answers["tcp://10.0.0.1:1"]
    try:
        why = None
        for _ in range(100):
            pool.asked = -float("inf")
            why = pool.trouble(cancelled=False)
            if why is not None:
                break
            import time

            time.sleep(0.01)
    finally:
        pool.quiet.restore()
    assert why is not None and why.startswith("the Dask scheduler tcp://s:8786 has had no worker that can run the "
                                              "sweep's points for "), why
    assert "tcp://10.0.0.2:2 on host hostB was left out of the sweep" in why, why


def test_other_inputs_on_a_worker_name_the_file_that_differs(tmp_path, monkeypatch):
    """The line said only that the scene file or its meshes differ: now the first of the sweep's input files that
    differs where the worker reads it."""
    import shutil

    from tlm.config import config_from_dict
    from tlm.experiments.frames import render_key
    from tlm.fingerprint import code_fingerprint
    from tlm.scenes.loader import scenes_dir

    where = "the Dask worker tcp://10.0.0.7:4242 on host nodeB"
    scene = tmp_path / "box.yaml"
    shutil.copy(scenes_dir() / "cornell.yaml", scene)
    config = {**BASE, "scene": "box.yaml"}
    (tmp_path / "sweep.yaml").write_text("{}\n")  # (the marker a worker looks for above the point's folder)
    seen: dict[str, str] = {}
    files = sweep_point.scene_checks(config, tmp_path, "sweep.yaml", seen)
    assert str(scene) in files and list(seen.values()) == [files]
    key = render_key(config_from_dict(config, "sweep.yaml"), tmp_path, "sweep.yaml")
    text = scene.read_text()
    assert "params: {}" in text
    scene.write_text(text.replace("params: {}", "params: {wall_div: 2}"))  # (as the worker's disk holds it)
    monkeypatch.setattr(sweep_point, "dask_worker_where", lambda: where)
    task = sweep_point.Task("h", config, {}, str(tmp_path), "sweep.yaml", str(tmp_path / "points" / "p"), {},
                            code=code_fingerprint(), functional=key, scene_files=files)
    got = sweep_point.run_point(task)
    assert got["status"] == "failed" and got["error"]["type"] == "OtherInputsOnWorker", got
    message = got["error"]["message"]
    assert message.startswith(f"{where} sees other inputs for this point (its frame key "), message
    assert f"; its scene file {scene}): the sweep's input file {scene} differs there; the workers must see " in message
    assert "more of the sweep's input files" not in message, message


def test_the_line_on_other_inputs_counts_the_other_files_and_names_another_scene_file(tmp_path):
    """A scene file and the one its ``extends:`` names both differ: the first, and how many more; none of the sweep's
    files differs but the worker's scene file is another (a built-in one of its own install): the sweep's named."""
    base = tmp_path / "base.yaml"
    top = tmp_path / "top.yaml"
    base.write_text("extends: cornell\nmaterials: {glass: {type: dielectric, ior: 1.4}}\n")
    top.write_text("extends: base.yaml\nmaterials: {glass: {type: dielectric, ior: 1.3}}\n")
    files = sweep_point.scene_checks({**BASE, "scene": "top.yaml"}, tmp_path, "sweep.yaml", {})
    assert sweep_point._which_differ(files, str(top)) == "the scene file or its meshes differ there"  # (the same)
    top.write_text(top.read_text().replace("1.3", "1.2"))
    base.write_text(base.read_text().replace("1.4", "1.1"))
    assert sweep_point._which_differ(files, str(top)) == (
        f"the sweep's input file {top} differs there (and 1 more of the sweep's input files)")
    top.write_text(top.read_text().replace("1.2", "1.3"))
    base.write_text(base.read_text().replace("1.1", "1.4"))
    assert sweep_point._which_differ(files, "/elsewhere/top.yaml") == f"the sweep read the scene file {top}"
