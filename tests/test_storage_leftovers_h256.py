"""Storage and process leftovers (h256): a file put into an output folder under its lock (tlm.storage.write_into,
what a failed point's error.json beside kept results needs), a reader's folder lock that writes nothing and a
probe that cannot write remembered (tlm.storage_lock), tlm's wrapper of multiprocessing's spawn preparation beside
another library's (tlm.experiments.worker_start), and tlm.experiments.error_cost_clock loaded again while a clock
runs."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
import threading
import time
import types
from pathlib import Path

import pytest

from tlm import storage, storage_lock
from tlm.storage import atomic_folder, folder_lock

REPO = Path(__file__).resolve().parents[1]


def test_nothing_is_swapped_in_between_the_question_and_the_write(tmp_path):
    """A concurrent sweep of the same point swapping its good folder in while a failed point asks whether the
    folder holds finished results (and then writes error.json beside them): the swap waits for the lock until
    the file is written into the folder asked about, and the new folder does not carry it over. Without the
    lock the swap came in between and the stale error.json lay beside the new good results (h256)."""
    out = tmp_path / "points" / "abc"
    owned = ("results.json", "error.json")
    with atomic_folder(out, "results.json", owned) as tmp:
        (tmp / "results.json").write_text("old")
    swapped = threading.Event()

    def other_sweep():
        with atomic_folder(out, "results.json", owned) as tmp:
            (tmp / "results.json").write_text("new, good")
        swapped.set()

    other = threading.Thread(target=other_sweep)

    def finished(folder: Path) -> bool:
        here = (folder / "results.json").read_text() == "old"
        other.start()
        assert not swapped.wait(0.5), "the other sweep swapped its folder in while the question was asked"
        return here

    assert storage.write_into(out, "error.json", "{}\n", finished) is True
    other.join(timeout=30)
    assert swapped.is_set() and (out / "results.json").read_text() == "new, good"
    assert not (out / "error.json").exists()
    assert not any(p.name.startswith(".") for p in out.parent.iterdir())


def test_write_into_writes_nothing_where_keep_says_no_or_no_folder(tmp_path):
    (tmp_path / "a").mkdir()
    assert storage.write_into(tmp_path / "a", "f", "x", lambda folder: False) is False
    assert storage.write_into(tmp_path / "missing", "f", "x", lambda folder: True) is False
    assert list((tmp_path / "a").iterdir()) == [] and not (tmp_path / "missing").exists()
    assert storage.write_into(tmp_path / "a", "f", b"x", lambda folder: True) is True
    assert (tmp_path / "a" / "f").read_bytes() == b"x"


def mkdirs(monkeypatch, refuse: str | None = None) -> list[str]:
    """Every os.mkdir from now on (the names); those under a folder named ``refuse``: EROFS."""
    made: list[str] = []
    mkdir = os.mkdir

    def spy(path, *a, **kw):
        made.append(os.path.basename(path))
        if refuse is not None and os.path.basename(os.path.dirname(path)) == refuse:
            raise OSError(errno.EROFS, "Read-only file system", path)
        return mkdir(path, *a, **kw)

    monkeypatch.setattr(os, "mkdir", spy)
    return made


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="renameat2 is Linux's")
def test_a_reader_s_lock_writes_nothing_into_the_parent(tmp_path, monkeypatch, nothing_known):
    """A reader's folder_lock (probe=False: a report reading a results folder) of a missing folder made the
    probe's two folders in the parent; it asks only what this process knows: nothing (the 10 ms wait), then a
    writer's yes there (no wait)."""
    made = mkdirs(monkeypatch)
    slept: list[float] = []
    monkeypatch.setattr(time, "sleep", slept.append)
    with folder_lock(tmp_path / "missing", probe=False):
        pass
    assert made == [] and slept == [0.01] and storage_lock._EXCHANGES == {}
    if storage_lock.exchanges_in(tmp_path):  # (a writer's probe: a file system that exchanges)
        made.clear()
        with folder_lock(tmp_path / "missing", probe=False):
            pass
        assert made == [] and slept == [0.01]


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="renameat2 is Linux's")
def test_a_probe_that_cannot_write_is_remembered_for_its_file_system(tmp_path, monkeypatch, nothing_known):
    """A folder this process cannot write (a results folder shared read-only on a lab server): the probe was
    tried again at each ask; now once per file system for TRUST_S, then again. A folder there it can write (a
    writer's own) is probed as ever."""
    ro, rw = tmp_path / "ro", tmp_path / "rw"
    ro.mkdir()
    rw.mkdir()
    made = mkdirs(monkeypatch, refuse="ro")
    access = os.access
    monkeypatch.setattr(os, "access", lambda path, mode, **kw: Path(path) != ro and access(path, mode, **kw))
    assert [storage_lock.exchanges_in(ro) for _ in range(3)] == [False] * 3
    assert len(made) == 1 and storage_lock._EXCHANGES == {}
    storage_lock.exchanges_in(rw)
    assert len(made) == 3  # (the writable folder's two probe folders)
    storage_lock._EXCHANGES.clear()
    now = time.monotonic()
    monkeypatch.setattr(time, "monotonic", lambda: now + storage_lock.TRUST_S + 1)
    assert storage_lock.exchanges_in(ro) is False and len(made) == 4  # (asked again after a while)
    assert list(ro.iterdir()) == [] and list(rw.iterdir()) == []


@pytest.fixture
def spawn_kept(monkeypatch):
    """multiprocessing.spawn's get_preparation_data put back after the test; __main__ a script on standard
    input (whose init_main_from_path tlm's wrapper takes out)."""
    from multiprocessing import spawn

    monkeypatch.setattr(spawn, "get_preparation_data", spawn.get_preparation_data)
    main = types.ModuleType("__main__")
    main.__file__, main.__spec__ = "<stdin>", None
    monkeypatch.setitem(sys.modules, "__main__", main)
    return spawn


def test_another_library_s_wrapper_left_over_tlm_s_is_no_recursion(spawn_kept):
    """A library's wrapper of spawn's preparation put over tlm's during a sweep and left there: the next
    sweep's wrapper wrapped it and it called tlm's old one through the shared slot, which called it back (a
    RecursionError at the first worker). The library's wrapper keeps working, and stays in place."""
    from tlm.experiments.worker_start import main_file_hidden

    spawn = spawn_kept
    own = spawn.get_preparation_data
    calls: list[str] = []
    with main_file_hidden():
        tlm_s = spawn.get_preparation_data

        def foreign(name):
            calls.append(name)
            return tlm_s(name)

        spawn.get_preparation_data = foreign
    assert spawn.get_preparation_data is foreign and "init_main_from_path" in foreign("a")
    with main_file_hidden():
        assert "init_main_from_path" not in spawn.get_preparation_data("b")
    assert spawn.get_preparation_data is foreign and calls == ["a", "b"]
    assert "init_main_from_path" in foreign("c")
    spawn.get_preparation_data = tlm_s  # (the library takes its own off: what it wrapped put back)
    with main_file_hidden():
        assert "init_main_from_path" not in spawn.get_preparation_data("d")
    assert spawn.get_preparation_data is own and calls == ["a", "b", "c"]


def test_wrappers_under_and_over_tlm_s_keep_working(spawn_kept):
    """A library's wrapper put in before the sweeps (under tlm's), and another's put over tlm's during one and
    left there: each later sweep's workers are prepared through all of them (it was a RecursionError), the
    change tlm makes only while a sweep runs; the one under is put back where tlm's is the outermost as the
    sweep ends."""
    from tlm.experiments.worker_start import main_file_hidden

    spawn = spawn_kept
    own = spawn.get_preparation_data
    calls: list[str] = []

    def under(name):
        calls.append(f"under {name}")
        return own(name)

    spawn.get_preparation_data = under
    with main_file_hidden():
        assert "init_main_from_path" not in spawn.get_preparation_data("a")
    assert spawn.get_preparation_data is under
    with main_file_hidden():
        below = spawn.get_preparation_data

        def over(name):
            calls.append(f"over {name}")
            return below(name)

        spawn.get_preparation_data = over
    for name in ("b", "c"):
        with main_file_hidden():
            assert "init_main_from_path" not in spawn.get_preparation_data(name)
        assert spawn.get_preparation_data is over and "init_main_from_path" in over(name)
    assert calls == ["under a", "over b", "under b", "over b", "under b", "over c", "under c", "over c", "under c"]


RELOAD = """
import builtins, importlib, sys, time
import tlm.experiments.error_cost_clock as ecc
real = builtins.__import__
clock = ecc.CompileClock()
with clock.running():
    importlib.reload(ecc)
    import email.mime.text  # (a first import, through the hook of the first load)
    with ecc.CompileClock().running():
        import xml.dom.minidom
assert builtins.__import__ is real, builtins.__import__
other = ecc.CompileClock()
with other.running():
    t0 = time.perf_counter()
    import json.tool
    t1 = time.perf_counter()
    assert builtins.__import__ is not real
assert builtins.__import__ is real and other.within(t0, t1) > 0
print("ok")
"""


def test_the_clock_s_module_loaded_again_while_a_clock_runs(tmp_path):
    """importlib.reload (IPython's %autoreload) of tlm.experiments.error_cost_clock while a clock ran set the
    'import statement as it was' to the hook itself: every import after it a RecursionError. Now the state is
    kept, the import statement is put back as the clock stops, and a later clock times first imports."""
    script = tmp_path / "reload.py"
    script.write_text(RELOAD)
    done = subprocess.run([sys.executable, str(script)], cwd=REPO, capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(REPO)})
    assert done.returncode == 0 and done.stdout.strip() == "ok", done.stderr[-2000:]



def test_a_failed_point_s_error_json_never_lands_beside_a_sweep_s_new_results(tmp_path, monkeypatch):
    """(Append to tests/test_storage_leftovers_h256.py once /tmp/h256/sweep_point.patch is applied.) write_error
    asked whether the folder held finished results, then wrote error.json: a concurrent sweep of the same point
    that swapped its good folder in between got the stale error.json beside its new results. Now the swap waits
    until the file is written into the folder asked about, and the new folder does not carry it over."""
    from types import SimpleNamespace

    from tlm.experiments import sweep_point

    out = tmp_path / "points" / "abc123"

    def results(tag: str) -> str:
        return storage.json_text({"tlm": sweep_point.POINT_FORMAT, "hash": out.name, "tag": tag,
                                  **{k: {} for k in ("cycles", "timing", "functional", "host_seconds")}})

    with atomic_folder(out, "results.json", sweep_point.POINT_FILES) as tmp:
        (tmp / "results.json").write_text(results("old"))
    swapped = threading.Event()

    def other_sweep():
        with atomic_folder(out, "results.json", sweep_point.POINT_FILES) as tmp:
            (tmp / "results.json").write_text(results("new"))
        swapped.set()

    other = threading.Thread(target=other_sweep)
    real = sweep_point.finished

    def finished_then_swapped(folder):
        got = real(folder)
        other.start()
        swapped.wait(0.5)  # (without the lock: swapped in here)
        return got

    monkeypatch.setattr(sweep_point, "finished", finished_then_swapped)
    sweep_point.write_error(SimpleNamespace(hash=out.name, factors={}, out=str(out), config={}), {"message": "boom"})
    other.join(timeout=30)
    assert swapped.is_set() and '"tag": "new"' in (out / "results.json").read_text()
    assert not (out / "error.json").exists()
