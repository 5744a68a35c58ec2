"""``tlm sweep --dask tcp://...`` on a real cluster: a ``dask scheduler`` and ``dask worker``
processes of their own, started from other working folders with caches of their own (as
another machine's), on 127.0.0.1."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
from contextlib import ExitStack, suppress
from pathlib import Path

import pytest
import yaml

import tlm.experiments.executors as executors
import tlm.experiments.sweep as sweep_mod
import tlm.fingerprint as fingerprint
from tlm.errors import EnvironmentFailure
from tlm.experiments.sweep import run_sweep
from tlm.experiments.sweep_rows import RAN_COLUMNS

pytest.importorskip("distributed")

BASE = {"scene": "cornell", "mode": "rcast", "resolution": [16, 16], "render": {"light_samples": 1, "spp": 1},
        "arch": {"frames": 2, "trace": False, "packet_size": 16}}
HOST = ("seconds.functional", "seconds.simulate", "seconds.one_off", "seconds.write")
DASK = [sys.executable, "-m", "distributed.cli.dask_scheduler"]
WORKER = [sys.executable, "-m", "distributed.cli.dask_worker"]


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py) this process's cache: the client's, not the workers'
    return cache


class Cluster:
    """A scheduler and its workers, each a process group of its own started in ``root``'s
    node folders with its own HOME and TLM_CACHE."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.procs: list[subprocess.Popen] = []
        self.address = ""

    def _env(self, node: Path) -> dict[str, str]:
        env = {k: v for k, v in os.environ.items() if not k.startswith("TLM_")}
        env.update(HOME=str(node / "home"), XDG_CACHE_HOME=str(node / "xdg"), TLM_CACHE=str(node / "cache"),
                   PYTHONUNBUFFERED="1")
        return env

    def _start(self, argv: list[str], node: Path) -> subprocess.Popen:
        node.mkdir(parents=True, exist_ok=True)
        log = open(node / "log", "ab")  # noqa: SIM115 (kept open by the process)
        proc = subprocess.Popen(argv, cwd=node, env=self._env(node), stdout=log, stderr=subprocess.STDOUT,
                                stdin=subprocess.DEVNULL, start_new_session=True)
        log.close()
        self.procs.append(proc)
        return proc

    def scheduler(self) -> subprocess.Popen:
        file = self.root / "scheduler.json"
        proc = self._start([*DASK, "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                            "--scheduler-file", str(file)], self.root / "nodeA")
        deadline = time.monotonic() + 60
        while not (file.is_file() and file.stat().st_size):
            assert proc.poll() is None and time.monotonic() < deadline, (self.root / "nodeA" / "log").read_text()
            time.sleep(0.1)
        time.sleep(0.2)  # (written whole)
        self.address = json.loads(file.read_text())["address"]
        return proc

    def workers(self, n: int, node: str = "nodeB") -> subprocess.Popen:
        from distributed import Client

        with Client(self.address, timeout=30) as client:
            before = len(client.nthreads())
            proc = self._start([*WORKER, self.address, "--nworkers", str(n), "--nthreads", "1", "--no-dashboard"],
                               self.root / node)
            client.wait_for_workers(before + n, timeout=90)
        return proc

    def kill(self, proc: subprocess.Popen) -> None:
        with suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)

    def close(self) -> None:
        for proc in reversed(self.procs):
            if proc.poll() is None:
                self.kill(proc)


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    """One scheduler and two worker processes (``--nworkers 2 --nthreads 1``) for the module."""
    c = Cluster(tmp_path_factory.mktemp("cluster"))
    try:
        c.scheduler()
        c.workers(2)
        yield c
    finally:
        c.close()


def sweep_file(folder: Path, base: dict = BASE, **body) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": base, **body}, sort_keys=False))
    return path


def csv_rows(out: Path) -> list[dict]:
    import pandas as pd

    table = pd.read_csv(out / "sweep.csv", dtype={"hash": str})
    table = table.drop(columns=[*HOST, "functional_cached", *(c for c in RAN_COLUMNS if c in table)])  # (and who
    # ran each point: a worker of the cluster, or the sweep's own process)
    return table.astype(object).where(table.notna(), None).to_dict("records")  # (NaN != NaN)


@pytest.mark.slow
def test_a_relative_out_is_the_sweeps_folder_and_the_rows_are_those_of_jobs_1(cluster, tmp_path, monkeypatch):
    """The workers run in folders of their own: a relative ``--out`` is the sweep's, not theirs
    (the point folders went to the workers' working folder, and the sweep's stayed empty)."""
    client = tmp_path / "client"
    (client / "scenes").mkdir(parents=True)
    from tlm.cli import main

    monkeypatch.chdir(client)
    assert main(["scene", "export", "cornell-box", "scenes/box.yaml"]) == 0
    path = sweep_file(client, grid={"scene": ["cornell", "scenes/box.yaml"], "arch.fifo_depth": [1, 16]})
    remote = run_sweep(path, Path("rel"), dask=cluster.address)
    run_sweep(path, Path("one"), jobs=1)
    assert (remote.ok, remote.failed) == (4, 0)
    for row in remote.rows:
        assert (client / "rel" / "points" / row["hash"] / "results.json").is_file(), row
    assert not list(cluster.root.glob("node*/rel")), "a worker wrote the points into its own working folder"
    assert csv_rows(client / "rel") == csv_rows(client / "one")


@pytest.mark.slow
def test_a_frame_in_this_machines_cache_is_rendered_once_by_the_workers(cluster, tmp_path):
    """This machine's cache holds the frame, the workers' do not: one worker renders it and the
    others wait for it (every point of the group sent at once, each worker rendered it)."""
    path = sweep_file(tmp_path, base={**BASE, "resolution": [24, 24]}, grid={"arch.fifo_depth": [1, 4, 16, 64]})
    run_sweep(path, tmp_path / "here", jobs=1)  # fills this process's cache
    from distributed import Client

    with Client(cluster.address, timeout=30) as client:  # the workers' caches emptied
        client.run(lambda: shutil.rmtree(os.environ["TLM_CACHE"], ignore_errors=True))
    done = run_sweep(path, tmp_path / "there", dask=cluster.address)
    assert done.ok == 4
    assert [r["functional_cached"] for r in done.rows].count(False) == 1, done.rows


@pytest.mark.slow
def test_a_point_whose_worker_cannot_read_its_scene_names_the_path_and_the_host(cluster, tmp_path, monkeypatch):
    """The scene file is there when the sweep is loaded, and gone (as on a machine without the
    sweep's disk) when the workers run its points."""
    from tlm.cli import main

    folder = tmp_path / "only_here"
    folder.mkdir()
    assert main(["scene", "export", "cornell-box", str(folder / "box.yaml")]) == 0
    path = sweep_file(tmp_path, base={**BASE, "scene": "only_here/box.yaml"}, grid={"arch.fifo_depth": [1, 16]})
    opened = sweep_mod.open_executor

    def open_then_hide(*args):
        pool = opened(*args)
        shutil.rmtree(folder)  # (after the sweep loaded it, before a worker reads it)
        return pool

    monkeypatch.setattr(sweep_mod, "open_executor", open_then_hide)
    done = run_sweep(path, tmp_path / "o", dask=cluster.address)
    assert done.failed == 2
    scene = str(folder / "box.yaml")
    for row in done.rows:
        assert scene in row["error"] and "on the Dask worker tcp://127.0.0.1:" in row["error"], row["error"]
        assert f"on host {socket.gethostname()}" in row["error"], row["error"]
        err = json.loads((tmp_path / "o" / "points" / row["hash"] / "error.json").read_text())
        assert scene in err["message"]


@pytest.mark.slow
def test_a_worker_with_other_tlm_code_fails_its_points_with_why(cluster, tmp_path):
    """A worker whose tlm is another version would file its cycles under this code's hashes."""
    from distributed import Client

    def other_code():
        import tlm.fingerprint as fp

        fp.code_fingerprint()
        before, fp._CODE = fp._CODE, "0123456789abcdef"
        return before

    def put_back(code):
        import tlm.fingerprint as fp

        fp._CODE = code

    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]})
    with Client(cluster.address, timeout=30) as client:
        before = client.run(other_code)
        try:
            done = run_sweep(path, tmp_path / "o", dask=cluster.address)
        finally:
            for address, code in before.items():
                client.run(put_back, code, workers=[address])
    assert done.failed == 2
    for row in done.rows:
        assert row["error"].startswith("OtherCodeOnWorker: the Dask worker tcp://127.0.0.1:"), row["error"]
        assert "0123456789abcdef" in row["error"] and fingerprint.code_fingerprint() in row["error"]


def test_a_scheduler_without_workers_stops_the_sweep_in_bounded_time(tmp_path, monkeypatch):
    """No worker ever comes: the sweep waited forever."""
    monkeypatch.setattr(executors, "NO_WORKERS_WAIT", 2.0)
    monkeypatch.setattr(executors, "WORKERS_POLL", 0.2)
    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]})
    c = Cluster(tmp_path / "cluster")
    got: list[BaseException | None] = []

    def sweep():
        try:
            run_sweep(path, tmp_path / "o", dask=c.address)
            got.append(None)
        except BaseException as e:  # (the test reads it)
            got.append(e)

    try:
        c.scheduler()
        thread = threading.Thread(target=sweep, daemon=True)
        thread.start()
        thread.join(timeout=60)
        assert not thread.is_alive(), "the sweep still waits for a worker"
    finally:
        c.close()
    assert isinstance(got[0], EnvironmentFailure), got
    assert f"the Dask scheduler {c.address} has had no worker for" in str(got[0])
    assert "0 of 2 points done" in str(got[0])


@pytest.mark.slow
def test_a_lost_scheduler_is_one_line_exit_1_and_the_points_done_are_kept(tmp_path, monkeypatch):
    """``dask scheduler`` killed while points run: one line naming it (not a page of the
    client's traceback), exit status 1, no point recorded as failed with an empty
    ``CancelledError``, and a rerun with another scheduler finishes the sweep."""
    path = sweep_file(tmp_path, base={**BASE, "resolution": [96, 96], "arch": {**BASE["arch"], "packet_size": 1}},
                      grid={"arch.fifo_depth": [1, 4, 16, 64, 256, 1024]})
    out = tmp_path / "o"
    with ExitStack() as stack:
        c = Cluster(tmp_path / "cluster")
        stack.callback(c.close)
        scheduler = c.scheduler()
        c.workers(1)
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        sweep = subprocess.Popen([sys.executable, "-m", "tlm", "sweep", str(path), "--out", str(out),
                                  "--dask", c.address, "--no-report"], cwd=tmp_path, env=env,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        stack.callback(lambda: sweep.poll() is None and sweep.kill())
        deadline = time.monotonic() + 120
        while not ((out / "sweep.jsonl").is_file() and (out / "sweep.jsonl").read_text().count("\n") >= 1):
            assert sweep.poll() is None, sweep.communicate()
            assert time.monotonic() < deadline, "no point finished"
            time.sleep(0.1)
        c.kill(scheduler)
        stdout, stderr = sweep.communicate(timeout=120)
    assert sweep.returncode == 1, (stdout, stderr)
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"tlm: error: lost the Dask scheduler {c.address}"), stderr
    assert "points done, kept in" in lines[0]
    points = out / "points"
    assert not list(points.glob("*/error.json")), "a point was recorded as failed"
    assert not [p for p in points.iterdir() if p.name.startswith(".")], "half-written folders"
    rows = [json.loads(line) for line in (out / "sweep.jsonl").read_text().splitlines()]
    assert rows and all(r["status"] == "ok" for r in rows)
    kept = {p.name for p in points.iterdir()}

    # the rerun, with the code the sweep's process hashed (a tree edited since would key new points)
    code = json.loads((points / rows[0]["hash"] / "results.json").read_text())["code_fingerprint"]
    monkeypatch.setattr(fingerprint, "_CODE", code)
    again = run_sweep(path, out, jobs=1)  # the points done are kept, the others run
    assert again.ok + again.skipped == 6 and again.failed == 0
    assert again.skipped >= len(kept) >= 1



@pytest.mark.slow
def test_a_point_written_where_this_machine_does_not_see_it_fails_with_the_path(cluster, tmp_path):
    """The worker wrote the point's folder on a disk this machine does not see: the row said
    ok, and the sweep's folder held no point."""
    from distributed import Client

    def patch_workers(patch: bool) -> None:  # (nested: sent to the workers by value)
        import shutil

        from tlm.experiments import sweep_point

        def write_elsewhere(task):  # the point's folder lands on "the worker's own disk"
            record = sweep_point._original_run_point(task)
            shutil.move(task.out, f"{task.out}.on-the-workers-disk")
            return record

        if patch:
            sweep_point._original_run_point = sweep_point.run_point
            sweep_point.run_point = write_elsewhere
        else:
            sweep_point.run_point = sweep_point._original_run_point

    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]})
    with Client(cluster.address, timeout=30) as client:
        client.run(patch_workers, True)
        try:
            done = run_sweep(path, tmp_path / "o", dask=cluster.address)
        finally:
            client.run(patch_workers, False)
    assert done.failed == 2
    for row in done.rows:
        folder = str(tmp_path / "o" / "points" / row["hash"])
        assert row["error"].startswith("PathNotOnWorker: the Dask worker tcp://127.0.0.1:"), row["error"]
        assert f"wrote {folder}, which this machine does not see" in row["error"]
        assert (Path(folder) / "error.json").is_file()


@pytest.mark.slow
def test_a_worker_whose_builtin_scene_differs_refuses_the_point(cluster, tmp_path):
    """The code fingerprint leaves out scenes/: a worker whose built-in cornell.yaml differs (same
    tlm code) rendered its own scene, and the sweep filed its cycles, "ok", under this machine's
    point hash. Now it refuses the point, naming both frame keys and its scene file."""
    from distributed import Client

    from tlm.experiments.sweep_file import load_sweep
    from tlm.scenes.loader import scenes_dir

    other = tmp_path / "workers_scenes"
    shutil.copytree(scenes_dir(), other)
    text = (other / "cornell.yaml").read_text()
    assert "params: {}" in text
    (other / "cornell.yaml").write_text(text.replace("params: {}", "params: {wall_div: 2}"))

    def scenes_at(folder):  # (nested: sent to the workers by value) their install's scenes/, or None: tlm's
        from pathlib import Path

        import tlm.scenes.loader as loader

        if folder is None:
            loader.scenes_dir = loader._tlm_scenes_dir
        else:
            loader._tlm_scenes_dir = loader.scenes_dir
            loader.scenes_dir = lambda: Path(folder)

    path = sweep_file(tmp_path, grid={"arch.fifo_depth": [1, 16]})
    mine = load_sweep(path).points[0].functional
    with Client(cluster.address, timeout=30) as client:
        client.run(scenes_at, str(other))
        try:
            done = run_sweep(path, tmp_path / "o", dask=cluster.address)
        finally:
            client.run(scenes_at, None)
    assert (done.ok, done.failed) == (0, 2)
    for row in done.rows:
        assert row["error"].startswith("OtherInputsOnWorker: the Dask worker tcp://127.0.0.1:"), row["error"]
        assert f"the sweep's {mine}; its scene file {other / 'cornell.yaml'})" in row["error"], row["error"]
        assert not (tmp_path / "o" / "points" / row["hash"] / "results.json").exists()
    again = run_sweep(path, tmp_path / "o", dask=cluster.address)  # (the workers' own scenes/ again)
    assert (again.ok, again.failed) == (2, 0)
    for row in again.rows:
        results = json.loads((tmp_path / "o" / "points" / row["hash"] / "results.json").read_text())
        assert results["functional"]["key"] == mine


@pytest.mark.slow
def test_a_worker_that_reads_another_programs_table_refuses_the_point(cluster, tmp_path, monkeypatch):
    """The table at the sweep's path holds other text where the workers read it (a disk of their
    own; here: edited after the sweep read it): its cycles would be filed under the hash of the
    table the sweep read."""
    from tlm.arch.costs import DEFAULT_PATH
    from tlm.config import text_digest

    table = tmp_path / "table.yaml"
    shutil.copy(DEFAULT_PATH, table)
    read = table.read_text()
    path = sweep_file(tmp_path, base={**BASE, "arch": {**BASE["arch"], "programs": "table.yaml"}},
                      grid={"arch.fifo_depth": [1, 16]})
    opened = sweep_mod.open_executor

    def open_then_edit(*args):
        pool = opened(*args)
        table.write_text(read + "\n# the workers' copy\n")  # (after the sweep read it, before a worker does)
        return pool

    monkeypatch.setattr(sweep_mod, "open_executor", open_then_edit)
    done = run_sweep(path, tmp_path / "o", dask=cluster.address)
    assert (done.ok, done.failed) == (0, 2)
    theirs, ours = text_digest(table.read_text())[:16], text_digest(read)[:16]
    for row in done.rows:
        assert row["error"].startswith("OtherInputsOnWorker: the Dask worker tcp://127.0.0.1:"), row["error"]
        assert f"reads another programs table at {table} (its text's sha256 {theirs}, the sweep's {ours})" \
            in row["error"], row["error"]
