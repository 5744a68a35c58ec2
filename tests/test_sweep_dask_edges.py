"""A sweep's Dask edges: a dashboard's ``http://`` address refused by the form check (it is
not a scheduler's); a scheduler address where nothing answers said at once (a refused
connection), where distributed retried it for its whole timeout and said "Timed out"; a
port where something other than a Dask scheduler answers (a web server, which distributed's
connect waited for forever) said too; an interrupted ``--dask local`` sweep's workers ended
at once (each nanny closed with a short wait, then its worker killed), where closing the
cluster gave a busy worker up to 4 s to finish its point; and ``sweep.csv``'s ``scene`` as the
sweep gives it, not the absolute path the points' configs hold for the workers."""

from __future__ import annotations

import asyncio
import csv
import json
import socket
import threading
import time
from pathlib import Path

import pytest
import yaml

from tlm.cli import main
from tlm.errors import InputError
from tlm.experiments import executors
from tlm.experiments.executors import DaskPool
from tlm.experiments.sweep import run_sweep
from tlm.scenes.loader import scenes_dir

TINY = {"mode": "rcast", "resolution": [8, 8], "render": {"spp": 1, "light_samples": 1}, "arch": {"trace": False}}
QUIET = ["--no-progress", "--no-report"]


def _sweep(folder: Path, base: dict | str, **body) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "sw.yaml"
    path.write_text(yaml.safe_dump({"base": base, **body}, sort_keys=False))
    return path


def _box(path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text((scenes_dir() / "cornell.yaml").read_text())
    return path


def _free_port() -> int:
    """A port nothing listens on (bound, then closed)."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.parametrize("dask", ["http://127.0.0.1:8787", "HTTPS://sched.example.org:8787/status"])
def test_a_dashboards_address_is_refused_by_the_form_check(tmp_path, capsys, dask):
    """Checked even where every point is done (no scheduler reached: it was taken, exit 0)."""
    path = _sweep(tmp_path, {"scene": "cornell", **TINY}, grid={"seed": [0]})
    out = tmp_path / "o"
    assert run_sweep(path, out, jobs=1).ok == 1
    capsys.readouterr()
    assert main(["sweep", str(path), "--out", str(out), "--dask", dask, *QUIET]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--dask: {dask!r} is the address of a Dask dashboard" in err, err
    assert "tcp://HOST:8786" in err and "'dask scheduler' printed" in err


def test_a_refused_scheduler_address_is_said_at_once(tmp_path, capsys):
    """Nothing listens on the port: one line, exit 2, no output folder, in well under
    distributed's 10 s of retries ("Timed out trying to connect ... after 10 s", before)."""
    path = _sweep(tmp_path, {"scene": "cornell", **TINY}, grid={"seed": [0]})
    port = _free_port()
    t0 = time.monotonic()
    assert main(["sweep", str(path), "--out", str(tmp_path / "o"), "--dask", f"tcp://127.0.0.1:{port}", *QUIET]) == 2
    took = time.monotonic() - t0
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"nothing answers at 'tcp://127.0.0.1:{port}'" in err, err
    assert "connection refused" in err and "Timed out" not in err
    assert took < 8, took
    assert not (tmp_path / "o").exists()


def test_a_host_that_does_not_answer_is_said_after_the_timeout(monkeypatch):
    def dropped(address, timeout=None):
        raise TimeoutError("timed out")

    monkeypatch.setattr(executors.socket, "create_connection", dropped)
    with pytest.raises(InputError, match=r"--dask: no answer from 'tcp://10\.1\.2\.3:8786' within 10 s \(a host "
                                         r"that is down or not there, or a firewall that drops the connection\)"):
        executors.answers("tcp://10.1.2.3:8786")


def test_a_transport_not_over_tcp_is_left_to_dask(monkeypatch):
    def never(*a, **k):
        raise AssertionError("no connection for this transport")

    monkeypatch.setattr(executors.socket, "create_connection", never)
    for address in ["ucx://127.0.0.1:1", "ucxx://127.0.0.1:1", "inproc://10.0.0.1/123/1", "nowhere"]:
        executors.answers(address)


def test_a_port_where_something_else_answers_is_not_taken_for_a_scheduler():
    """A listener that says nothing (a web server waits for a request: distributed's connect
    waited for it forever) and one whose first bytes are no Dask message's size (read as one,
    distributed tried to allocate exabytes: an internal MemoryError)."""
    with socket.socket() as quiet:
        quiet.bind(("127.0.0.1", 0))
        quiet.listen()
        address = f"tcp://127.0.0.1:{quiet.getsockname()[1]}"
        with pytest.raises(InputError, match=r"answers, but not as a Dask scheduler \(it said nothing"):
            executors.answers(address, timeout=0.3)

    with socket.socket() as web:
        web.bind(("127.0.0.1", 0))
        web.listen()

        def serve():
            conn, _ = web.accept()
            with conn:
                conn.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n")
                time.sleep(0.5)

        server = threading.Thread(target=serve, daemon=True)
        server.start()
        with pytest.raises(InputError, match=r"not as a Dask scheduler \(its first bytes are b'HTTP/1\.1'"):
            executors.answers(f"tcp://127.0.0.1:{web.getsockname()[1]}", timeout=5)
        server.join(5)


def test_a_scheduler_that_writes_its_handshake_is_taken():
    """What a Dask scheduler writes first: the size of its handshake message, 8 bytes little-endian."""
    with socket.socket() as sched:
        sched.bind(("127.0.0.1", 0))
        sched.listen()

        def serve():
            conn, _ = sched.accept()
            with conn:
                conn.sendall((58).to_bytes(8, "little") + b"\x01" * 16)
                time.sleep(0.5)

        server = threading.Thread(target=serve, daemon=True)
        server.start()
        executors.answers(f"tcp://127.0.0.1:{sched.getsockname()[1]}", timeout=5)
        server.join(5)


class _Nanny:
    def __init__(self, log: list) -> None:
        self.log = log

    async def close(self, timeout: float = 5, reason: str = "nanny-close") -> str:
        self.log.append((timeout, reason))
        return "OK"


class _Cluster:
    def __init__(self, n: int) -> None:
        self.log: list = []
        self.workers = {i: _Nanny(self.log) for i in range(n)}

    def sync(self, func, *args, **kwargs):
        return asyncio.run(func(*args, **kwargs))


class _Client:
    status = "running"

    def get_executor(self, pure=False):
        return self

    def shutdown(self, wait=True):
        pass


def test_an_interrupted_local_clusters_workers_are_ended_with_a_short_wait():
    """Each nanny of a ``--dask local`` cluster is closed with :data:`executors.STOP_WAIT` (its worker
    killed after it), not the cluster's close's wait for a busy worker's point; a remote cluster's
    workers are not the sweep's to end."""
    cluster = _Cluster(2)
    DaskPool(_Client(), "local", remote=False, cluster=cluster).stop()
    assert cluster.log == [(executors.STOP_WAIT, "tlm-sweep-stopped")] * 2 and executors.STOP_WAIT <= 0.5
    DaskPool(_Client(), "tcp://h:8786", remote=True).stop()  # (no cluster: nothing to end)


def test_the_csv_names_the_scene_as_the_sweep_gives_it(tmp_path):
    """The base's scene file by its path from the sweep file's folder, a scene factor's value as
    written (it was overwritten by the absolute path, its factor column too); the point's own
    config keeps the absolute path, for the workers."""
    _box(tmp_path / "scenes" / "box.yaml")
    _box(tmp_path / "s" / "mine.yaml")
    (tmp_path / "base").mkdir()
    (tmp_path / "base" / "base.yaml").write_text(yaml.safe_dump({"scene": "../scenes/box.yaml", **TINY}))
    path = _sweep(tmp_path / "s", "../base/base.yaml", grid={"seed": [0]})
    done = run_sweep(path, tmp_path / "o1", jobs=1)
    assert done.ok == 1 and list(done.table["scene"]) == ["../scenes/box.yaml"]
    with open(tmp_path / "o1" / "sweep.csv", newline="") as f:
        assert [r["scene"] for r in csv.DictReader(f)] == ["../scenes/box.yaml"]
    rows = [json.loads(line) for line in (tmp_path / "o1" / "sweep.jsonl").read_text().splitlines()]
    assert [r["scene"] for r in rows] == ["../scenes/box.yaml"]
    resolved = yaml.safe_load(next((tmp_path / "o1" / "points").glob("*/config.resolved.yaml")).read_text())
    assert resolved["scene"] == str(tmp_path / "scenes" / "box.yaml")  # (absolute, for any worker)

    path = _sweep(tmp_path / "s", "../base/base.yaml", grid={"scene": ["mine.yaml", "cornell"]})
    done = run_sweep(path, tmp_path / "o2", jobs=1)
    assert done.ok == 2
    with open(tmp_path / "o2" / "sweep.csv", newline="") as f:
        assert [r["scene"] for r in csv.DictReader(f)] == ["mine.yaml", "cornell"]

    path = _sweep(tmp_path / "s", "../base/base.yaml", set={"scene": "mine.yaml"}, grid={"seed": [0]})
    assert list(run_sweep(path, tmp_path / "o3", jobs=1).table["scene"]) == ["mine.yaml"]
