"""h501: small simplifications, behaviour unchanged. A compute's saves read its process's start (``/proc``) once, a
forked child's its own; a damaged or unreadable partial is 0 rounds to ``Partial.others`` (no guard needed where
an interrupt's line reads it); the thread pools and the forked pool wait in one loop
(:func:`tlm.kernels.threads_forked.polled`); a study folder's tables are read in :mod:`tlm.report.study_tables`,
out of tlm/report/collect.py (which was at 696 of its 700 lines)."""

from __future__ import annotations

import json
import multiprocessing
import os
import subprocess
import sys
import textwrap
from concurrent.futures import Future
from pathlib import Path

import numpy as np
import pytest

import tlm.experiments.reference_resume as reference_resume
from tlm import cli_report
from tlm.errors import InputError, path_shown
from tlm.experiments.reference_cache import partial_info, partial_path
from tlm.experiments.reference_resume import MARK, Partial, Rounds
from tlm.kernels import threads, threads_forked
from tlm.storage_live import process_start

REPO = Path(__file__).resolve().parents[1]
PIXELS = 4
needs_proc = pytest.mark.skipif(not Path("/proc/self/stat").is_file(), reason="no /proc: no process start known")


def _rounds(k: int) -> Rounds:
    return Rounds(k, np.ones((PIXELS, 3)), np.zeros((PIXELS, 3)), [0.5] * (k - 1), [0.25] * (k - 1), float(k))


@needs_proc
def test_a_computes_saves_read_its_processs_start_once(cache, monkeypatch):
    reads: list[int] = []
    monkeypatch.setattr(reference_resume, "_STARTED", {}, raising=False)  # (as in a process that saved none yet)
    monkeypatch.setattr(reference_resume, "process_start", lambda pid: reads.append(pid) or process_start(pid))
    saved = Partial("ab" * 10, 2, PIXELS)
    saved.save(_rounds(1))
    saved.save(_rounds(2))  # (a small save: after every cycle)
    Partial("cd" * 10, 2, PIXELS).save(_rounds(1))  # (another compute of the same process)
    assert reads == [os.getpid()]
    for key in ("ab" * 10, "cd" * 10):
        assert partial_info(partial_path(key))["started"] == process_start(os.getpid())
    assert partial_info(partial_path("ab" * 10))["k"] == 2


# a process that saves a compute's rounds, then forks a child that saves more of them: the child's file names the
# child and its own start, not the parent's it was forked with (a child's rounds named by the parent's start are
# no live compute's: tlm.cache_admin.partial_computer)
FORKED_SAVE = """
import json, os, sys
import numpy as np
from tlm.experiments.reference_cache import partial_info, partial_path
from tlm.experiments.reference_resume import Partial, Rounds
from tlm.storage import process_tag
from tlm.storage_live import process_start

def rounds(k):
    return Rounds(k, np.ones((4, 3)), np.zeros((4, 3)), [0.5] * (k - 1), [0.25] * (k - 1), float(k))

key = "ef" * 10
Partial(key, 2, 4).save(rounds(1))
pid = os.fork()
if pid == 0:
    code = 1
    try:
        import tlm.experiments.reference_resume as resume
        inherited = dict(resume._STARTED)  # (h512: the parent's start, kept, would be taken by a process given its id)
        Partial(key, 2, 4).save(rounds(2))
        info = partial_info(partial_path(key))
        code = 4 if inherited else 0 if (info["k"], info["writer"], info["started"]) == (
            2, process_tag(), process_start(os.getpid())) else 3
    finally:
        os._exit(code)
_, status = os.waitpid(pid, 0)
print(json.dumps(os.waitstatus_to_exitcode(status)))
"""


@needs_proc
@pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="no fork here")
def test_a_forked_childs_save_names_its_own_start(cache):
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(FORKED_SAVE)], capture_output=True, text=True,
                          cwd=REPO, env={**os.environ, "PYTHONPATH": str(REPO), "TLM_CACHE": str(cache)}, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout.strip().splitlines()[-1]) == 0, proc.stdout  # (3: the parent's start, or none; 4: the
    # parent's read start inherited, the at-fork hook gone: h512)


def test_a_damaged_or_unreadable_partial_is_no_rounds_to_others_and_the_interrupts_line(cache):
    key = "12" * 10
    path = partial_path(key)
    path.parent.mkdir(parents=True)
    saved = Partial(key, 2, PIXELS)
    saved.rule, saved.saved = (2, 10, 1e-9), 6  # (its 6 rounds saved, then the file damaged or replaced)
    gone = (f"while computing the reference: its 6 rounds saved in {path_shown(path)} are gone (removed since); the "
            "same command computes it from round 1")

    def damage(how: str) -> None:
        if path.is_dir() and not path.is_symlink():
            path.rmdir()
        elif path.exists() or path.is_symlink():
            path.unlink()
        if how == "text":
            path.write_text("not an npz")
        elif how == "cut":
            Partial(key, 2, PIXELS).save(_rounds(3))
            data = path.read_bytes()
            path.write_bytes(data[: len(data) // 2])
        elif how == "folder":
            path.mkdir()
        elif how == "fifo":
            os.mkfifo(path)
        elif how == "dangling":
            path.symlink_to(path.parent / "nowhere")

    for how in ("text", "cut", "folder", "fifo", "dangling", "none"):
        if how == "fifo" and not hasattr(os, "mkfifo"):
            continue
        damage(how)
        assert (saved.kept(), saved.others()) == (0, 0), how
        e = KeyboardInterrupt()
        setattr(e, MARK, saved)
        assert cli_report._reference_kept(e) == gone, how


def test_the_pools_wait_in_one_loop(monkeypatch):
    waited: list[Future] = []
    polled = threads_forked.polled
    monkeypatch.setattr(threads_forked, "polled", lambda f, ended: waited.append(f) or polled(f, ended))
    done: Future = Future()
    done.set_result(7)
    assert threads.result(done) == 7 and threads_forked._outcome(None, done) == 7
    assert waited == [done, done]
    failed: Future = Future()
    failed.set_exception(TimeoutError("a disk's ETIMEDOUT"))  # (the call's own: raised as it came)
    with pytest.raises(TimeoutError, match="ETIMEDOUT"):
        threads_forked.polled(failed, lambda: pytest.fail("not waited on"))


def test_a_study_folders_tables_are_read_where_collect_reads_them(tmp_path):
    from tlm.report import collect, study_tables

    folder = tmp_path / "ex"
    folder.mkdir()
    row = {"case": "a", "category": "b", "expect": "c", "measured": "d", "passed": True, "seconds": 1.5}
    (folder / "extreme.jsonl").write_text(json.dumps(row) + "\n")
    assert study_tables.study_table(folder, "extreme") == ([row], {})
    assert study_tables.study_table(folder, "run") is None
    inputs = collect.read([folder])
    assert [(s.kind, s.rows, s.meta) for s in inputs.studies] == [("extreme", [row], {})]
    (folder / "extreme.jsonl").write_text(json.dumps(row))  # (its last row cut off: a damaged copy)
    with pytest.raises(InputError, match="is cut off") as e:
        study_tables.study_table(folder, "extreme")
    assert e.value.source == str(folder / "extreme.jsonl")
