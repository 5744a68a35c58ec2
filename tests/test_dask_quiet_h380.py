"""distributed's loggers that only narrate a connection closing ("Batched Comm Closed" at INFO, with its
traceback) are kept below WARNING for the whole life of a Dask sweep's client, from before it connects until it
has closed (h380): its event loop thread logged the closed connection to a lost scheduler as it happened, before
the sweep's one line, which silenced them only once it saw the client's status change. Their levels are put
back after the sweep (a notebook's session goes on)."""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import time
from contextlib import ExitStack, suppress
from pathlib import Path

import pytest
import yaml

import tlm.experiments.executors as executors
from tlm.experiments.sweep import run_sweep

pytest.importorskip("distributed")

NAMES = ["distributed", "distributed.batched", "distributed.client", "distributed.core", "distributed.comm",
         "distributed.comm.tcp", "distributed.scheduler"]


@pytest.fixture(autouse=True)
def _own_cache(cache):  # (tests/conftest.py)
    return cache


@pytest.fixture
def levels():
    """The levels of :data:`NAMES` as distributed's import leaves them, put back after the test."""
    import distributed  # noqa: F401  (its import sets its loggers' levels: before, as they are then)

    before = {n: logging.getLogger(n).level for n in NAMES}
    yield before
    for n, level in before.items():
        logging.getLogger(n).setLevel(level)


class Caught(logging.Handler):
    """Every record that reaches the logger it is added to."""

    def __init__(self) -> None:
        super().__init__(logging.NOTSET)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


def narration(name: str = "distributed.batched") -> Caught:
    """A record as distributed's event loop thread logs a closed connection, sent through ``name``: what of it
    reaches a handler on that logger."""
    caught = Caught()
    logger = logging.getLogger(name)
    logger.addHandler(caught)
    try:
        try:
            raise ConnectionResetError("the scheduler is gone")
        except ConnectionResetError:
            logger.info("Batched Comm Closed %r", "<TCP (closed) Client->Scheduler>", exc_info=True)
    finally:
        logger.removeHandler(caught)
    return caught


def hushed() -> dict:
    """Whether each narrating logger lets INFO through, and whether distributed.batched still lets a WARNING."""
    return {"info": {n: logging.getLogger(n).isEnabledFor(logging.INFO) for n in
                     ("distributed.batched", "distributed.core", "distributed.comm.tcp", "distributed.client")},
            "warning": logging.getLogger("distributed.batched").isEnabledFor(logging.WARNING),
            "caught": len(narration().records)}


QUIET = {"info": dict.fromkeys(("distributed.batched", "distributed.core", "distributed.comm.tcp",
                                "distributed.client"), False), "warning": True, "caught": 0}


def test_a_local_sweep_keeps_the_narration_of_a_closed_connection_silent_while_it_runs(tmp_path, monkeypatch,
                                                                                        levels):
    """``--dask local``: asked from the sweep's own check of its cluster (DaskPool.trouble, on the main thread
    while the point runs), distributed.batched let an INFO record through (the loggers were silenced only once
    the sweep saw its client's status change); its warnings still do. The levels are back after the sweep."""
    logging.getLogger("distributed").setLevel(logging.INFO)  # (as distributed's own config: INFO)
    before = {n: logging.getLogger(n).level for n in NAMES}
    seen = []
    trouble = executors.DaskPool.trouble

    def watched(self, cancelled):
        seen.append(hushed())
        return trouble(self, cancelled)

    monkeypatch.setattr(executors.DaskPool, "trouble", watched)
    path = tmp_path / "sweep.yaml"
    path.write_text(yaml.safe_dump({"base": {"scene": "cornell", "mode": "rcast", "resolution": [8, 8],
                                             "render": {"light_samples": 1, "spp": 1},
                                             "arch": {"frames": 1, "trace": False, "packet_size": 16}},
                                 "grid": {"arch.fifo_depth": [16]}}))
    result = run_sweep(path, tmp_path / "o", jobs=1, dask="local")
    assert result.ok == 1
    assert seen and all(s == QUIET for s in seen), seen
    assert {n: logging.getLogger(n).level for n in NAMES} == before  # (a notebook's session: as it was)
    assert len(narration().records) == 1  # (heard again)


def _scheduler(root: Path) -> tuple[subprocess.Popen, str]:
    """A ``dask scheduler`` process of its own (as tests/test_dask_cluster.py's Cluster starts one): it and its
    address."""
    root.mkdir(parents=True, exist_ok=True)
    file = root / "scheduler.json"
    with open(root / "log", "ab") as log:
        proc = subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                 "--port", "0", "--no-dashboard", "--scheduler-file", str(file)], cwd=root,
                                stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                start_new_session=True)
    deadline = time.monotonic() + 60
    while not (file.is_file() and file.stat().st_size):
        assert proc.poll() is None and time.monotonic() < deadline, (root / "log").read_text()
        time.sleep(0.1)
    time.sleep(0.2)  # (written whole)
    return proc, json.loads(file.read_text())["address"]


def _kill(proc: subprocess.Popen) -> None:
    with suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.wait(timeout=30)


def test_a_remote_sweeps_client_connects_and_lives_hushed_and_closes_silent_once_its_scheduler_is_lost(
        tmp_path, monkeypatch, levels):
    """``--dask tcp://...``: hushed from before the client connects (its connection's own narration) until it has
    closed; a scheduler lost under the connected client (killed -9) before the sweep asked: no record of the
    closed connection, nor of the reconnection its close cancels (distributed.client, at ERROR, with a
    traceback), reaches a handler; the levels are back after."""
    logging.getLogger("distributed").setLevel(logging.INFO)
    before = {n: logging.getLogger(n).level for n in NAMES}
    at_connect = []
    connect = executors._client

    def connecting(*args, **kwargs):
        at_connect.append(hushed())
        return connect(*args, **kwargs)

    monkeypatch.setattr(executors, "_client", connecting)
    proc, address = _scheduler(tmp_path / "scheduler")
    caught = {n: Caught() for n in ("distributed", "distributed.batched", "distributed.client")}
    try:
        with ExitStack() as stack:
            pool = executors.open_executor(stack, 1, address, 1)
            assert at_connect == [QUIET]
            assert hushed() == QUIET
            for n, handler in caught.items():
                logging.getLogger(n).addHandler(handler)
            _kill(proc)
            deadline = time.monotonic() + 30
            while pool.client.status == "running":  # (lost: the sweep has not asked, nothing silenced all yet)
                assert time.monotonic() < deadline, "the client never saw its scheduler go"
                time.sleep(0.01)
            time.sleep(0.2)  # (the event loop's own narration of it, where any)
    finally:
        for n, handler in caught.items():
            logging.getLogger(n).removeHandler(handler)
        _kill(proc)
    got = [(r.name, r.levelname, r.getMessage()) for h in caught.values() for r in h.records]
    assert not got, got
    assert {n: logging.getLogger(n).level for n in NAMES} == before


def test_hushed_levels_keep_warnings_and_a_users_own_and_come_back_after_a_signals_grace(levels):
    """Only what would let INFO through is raised, to WARNING: a logger the user set above it, or whose parent
    is, is left; a child set below is raised and put back. Silenced by a signal (its grace), the levels put back
    are those before the hush, not WARNING; a sweep hushed within the grace keeps the levels before it too."""
    logging.getLogger("distributed").setLevel(logging.ERROR)
    logging.getLogger("distributed.batched").setLevel(logging.NOTSET)
    logging.getLogger("distributed.core").setLevel(logging.INFO)
    logging.getLogger("distributed.comm").setLevel(logging.NOTSET)
    logging.getLogger("distributed.comm.tcp").setLevel(logging.DEBUG)
    logging.getLogger("distributed.client").setLevel(logging.CRITICAL)
    before = {n: logging.getLogger(n).level for n in NAMES}
    quiet = executors._Quiet()
    quiet.hush()
    got = {n: logging.getLogger(n).level for n in NAMES}
    assert got == {**before, "distributed.core": logging.WARNING, "distributed.comm.tcp": logging.WARNING}
    assert not logging.getLogger("distributed.batched").isEnabledFor(logging.WARNING)  # (the user's ERROR, kept)
    quiet.restore()
    assert {n: logging.getLogger(n).level for n in NAMES} == before

    logging.getLogger("distributed").setLevel(logging.INFO)
    before = {n: logging.getLogger(n).level for n in NAMES}
    quiet = executors._Quiet()
    quiet.hush()
    assert logging.getLogger("distributed.batched").level == logging.WARNING
    quiet.now()  # (the sweep said its scheduler is lost)
    assert not logging.getLogger("distributed.batched").isEnabledFor(logging.CRITICAL)
    quiet.after(KeyboardInterrupt)  # (left silenced QUIET_GRACE seconds)
    later = executors._Quiet()
    later.hush()  # (a sweep within the grace)
    assert logging.getLogger("distributed.batched").level == logging.WARNING
    assert later.levels["distributed.batched"] == logging.NOTSET and later.levels["distributed.core"] == logging.INFO
    later.restore()
    executors._put_back_left()  # (the grace's timer)
    assert {n: logging.getLogger(n).level for n in NAMES} == before
