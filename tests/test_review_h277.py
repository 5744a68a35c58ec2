"""Review of 316887d and 650c2ce (config and CLI leftovers; numba that cannot load), h277.

1. ``config.read_text`` read every file with ``f.read(MAX_TEXT_BYTES + 1)``, which allocates 64 MiB first:
   a 300-byte config under ``ulimit -v`` (the address space 40 MiB above what the process held) was out of
   memory. Now a regular file's size (and a byte more) at once, a pipe a MiB at a time.
2. A file of 64 MiB and one byte was ``too large ... (64 MiB, at most 64 MiB)``; now its size in bytes.
3. A numba that cannot load warned once per process: a sweep of 3 workers said it 4 times (a Dask cluster's
   of 2, 3 times). Now the sweep's process says it, its workers that fail alike do not.
4. Under ``ulimit -v``, a numba whose extension module could not be mapped (an ImportError) was taken as
   "not installed" (the kernels on numpy, unsaid, for the rest of the process); now out of memory, as the
   OSError of llvmlite's library is since 650c2ce.
"""

from __future__ import annotations

import builtins
import contextlib
import os
import subprocess
import sys
import threading
import tracemalloc
from pathlib import Path

import pytest

from tlm import config, errors
from tlm.errors import InputError
from tlm.kernels import engine

ROOT = Path(__file__).resolve().parents[1]
SAID_BY = "TLM_NUMBA_UNLOADABLE_SAID"  # (tlm.kernels.engine.SAID_BY, named here for a run on the old code)
LINE = ("numba is installed but cannot load (OSError: Could not find/load shared object file 'libllvmlite.so'): "
        "the kernels run on numpy (the same results, slower; TLM_KERNELS=numpy says so without numba)")


def test_a_small_file_is_read_without_asking_for_the_most_a_file_may_hold(tmp_path):
    small = tmp_path / "c.yaml"
    small.write_text("scene: cornell\n")
    tracemalloc.start()
    try:
        assert config.read_text(small) == "scene: cornell\n"
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 2**20  # (was 64 MiB: the buffer of f.read(MAX_TEXT_BYTES + 1), under ulimit -v a MemoryError)


def _piped(fifo: Path, n: int) -> threading.Thread:
    os.mkfifo(fifo)

    def write():
        with open(fifo, "wb") as f, contextlib.suppress(BrokenPipeError):
            f.write(b"a: 1\r\n" + b"#" * (n - 6))

    writer = threading.Thread(target=write, daemon=True)
    writer.start()
    return writer


def test_a_pipe_is_read_a_mib_at_a_time_to_the_limit_and_no_further(tmp_path, monkeypatch):
    writer = _piped(tmp_path / "p.yaml", 3 * 2**20)
    tracemalloc.start()
    try:
        text = config.read_text(tmp_path / "p.yaml")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    writer.join(10)
    assert len(text) == 3 * 2**20 - 1 and text.startswith("a: 1\n#")  # (CRLF read as Path.read_text reads it)
    assert peak < 16 * 2**20  # (was 64 MiB: f.read(MAX_TEXT_BYTES + 1)'s buffer, whatever the pipe held)
    monkeypatch.setattr(config, "MAX_TEXT_BYTES", 3 * 2**20)  # (the limit read in three reads of a MiB)
    writer = _piped(tmp_path / "q.yaml", 3 * 2**20)
    assert len(config.read_text(tmp_path / "q.yaml")) == 3 * 2**20 - 1
    writer.join(10)
    writer = _piped(tmp_path / "r.yaml", 3 * 2**20 + 1)
    with pytest.raises(InputError, match=r"too large .*\(more than 3 MiB\)"):
        config.read_text(tmp_path / "r.yaml")
    writer.join(10)


def test_a_file_a_byte_over_the_limit_says_its_size(tmp_path):
    big = tmp_path / "big.yaml"
    with open(big, "wb") as f:
        f.truncate(config.MAX_TEXT_BYTES + 1)  # (sparse: nothing written)
    with pytest.raises(InputError) as e:
        config.read_text(big)
    assert "(67,108,865 bytes, at most 64 MiB)" in str(e.value)  # (was "(64 MiB, at most 64 MiB)")


@contextlib.contextmanager
def _numba_raising(monkeypatch, error):
    real = builtins.__import__

    def failing(name, *args, **kwargs):
        if name == "numba":
            raise error
        return real(name, *args, **kwargs)

    cached = engine.numba_available.cache_info().currsize
    monkeypatch.delenv("TLM_KERNELS", raising=False)
    monkeypatch.delenv(SAID_BY, raising=False)  # (put back as it was: unset)
    monkeypatch.setattr(builtins, "__import__", failing)
    engine.numba_available.cache_clear()
    try:
        yield
    finally:
        monkeypatch.setattr(builtins, "__import__", real)
        engine.numba_available.cache_clear()
        if cached:
            engine.numba_available()


def test_a_worker_whose_numba_fails_as_its_sweeps_does_not_say_it_again(monkeypatch, capsys):
    with _numba_raising(monkeypatch, OSError("Could not find/load shared object file 'libllvmlite.so'")):
        monkeypatch.setenv(SAID_BY, f"{os.getppid()} {LINE}")  # (as a worker finds it)
        assert engine.engine() == "numpy"
        assert capsys.readouterr().err == ""
        engine.numba_available.cache_clear()  # (the process that said it says it again)
        monkeypatch.setenv(SAID_BY, f"{os.getpid()} {LINE}")
        assert engine.engine() == "numpy"
        assert capsys.readouterr().err == f"tlm: warning: {LINE}\n"
        engine.numba_available.cache_clear()  # (another cause said by another process: said here too)
        monkeypatch.setenv(SAID_BY, f"{os.getppid()} {LINE.replace('libllvmlite', 'other')}")
        assert engine.engine() == "numpy"
        assert capsys.readouterr().err == f"tlm: warning: {LINE}\n"
        assert os.environ[SAID_BY] == f"{os.getpid()} {LINE}" and engine.SAID_BY == SAID_BY


def test_a_sweeps_workers_do_not_repeat_the_numba_warning(tmp_path):
    fake = tmp_path / "fake" / "numba"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise OSError(\"Could not find/load shared object file 'libllvmlite.so'\")\n")
    (tmp_path / "s.yaml").write_text(f"base: {ROOT / 'configs' / 'cornell.yaml'}\nset:\n  mode: rcast\n"
                                     "  resolution: [8, 8]\n  render.light_samples: 1\n  render.spp: 1\n"
                                     "  arch.trace: false\ngrid:\n  seed: [1, 2, 3]\n")
    env = {k: v for k, v in os.environ.items() if k not in ("TLM_KERNELS", SAID_BY)}
    env.update(PYTHONPATH=os.pathsep.join([str(tmp_path / "fake"), str(ROOT)]), TLM_CACHE=str(tmp_path / "cache"))
    done = subprocess.run([sys.executable, "-m", "tlm", "sweep", "s.yaml", "--out", "o", "--jobs", "3", "--no-report",
                           "--no-progress"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("numba is installed but cannot load") == 1, done.stderr  # (was 4: each worker's)
    assert "3 points: 3 ok" in done.stdout + done.stderr


def test_a_numba_extension_not_mapped_under_ulimit_v_is_out_of_memory(monkeypatch):
    monkeypatch.setattr(errors, "address_space_limit", lambda: 400 * 2**20)
    unmapped = ImportError(f"numba/_helperlib.so: {errors.UNMAPPED}")
    with _numba_raising(monkeypatch, unmapped), pytest.raises(ImportError):
        engine.numba_available()  # (was False: numba "not installed", numpy's kernels for the process)
    assert errors.memory_problem(unmapped).startswith("out of memory: numba/_helperlib.so: failed to map")
    with _numba_raising(monkeypatch, ImportError("No module named 'numba'")):
        assert engine.numba_available() is False  # (not installed: numpy, unsaid, as ever)
