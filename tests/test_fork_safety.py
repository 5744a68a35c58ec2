"""Forked workers (:func:`tlm.kernels.threads.forked`) fork only from a quiet process.

fork() copies only the calling thread: a lock another thread held at that instant stays held
in the child for ever (numba's compiler lock while a thread compiles or loads a kernel,
tqdm's in its monitor thread). ``forked`` forks only with no call in flight on the kernel
pools (which it shuts down), no other Python thread alive and numba's compiler lock held
across the fork; elsewhere it runs the items on threads, with the same results. The checks
that need a process with no other thread run in a fresh interpreter, with a timeout: the
hazard they check is a hang.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from tests.helpers_interrupt import running
from tlm.kernels import threads
from tlm.progress import progress_bar

ROOT = Path(__file__).resolve().parents[1]

needs_fork = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(), reason="no fork here")


def _script(tmp_path: Path, text: str, timeout: float = 120) -> str:
    """Run ``text`` in a fresh interpreter (the repository's working directory); its stdout.
    A hang fails the test (the timeout), it does not hang the suite; the script's process
    group is killed then, its hung workers with it."""
    script = tmp_path / "script.py"
    script.write_text(text)
    env = {k: v for k, v in os.environ.items() if k != "TLM_FORK_WORKERS"}
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, cwd=ROOT, env=env, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(f"hung for {timeout} s (a forked worker waiting on a lock held at the fork?): {out!r} {err!r}")
    assert proc.returncode == 0, out + err
    return out


_HELD_COMPILER_LOCK = """
import threading, time
import numba
from numba.core.compiler_lock import global_compiler_lock
from tlm.kernels import threads

held = threading.Event()

def hold():  # a thread compiling a kernel (or loading one from the cache) at the fork
    with global_compiler_lock:
        held.set()
        time.sleep(2.0)

def work(i):  # a kernel compiled in the worker: it needs the compiler lock
    return numba.njit(lambda x: x * 3 + 1)(i)

t = threading.Thread(target=hold)
t.start()
held.wait()
print(list(threads.forked(work, range(5), 2)))
t.join()
"""


@needs_fork
def test_a_thread_holding_numba_s_compiler_lock_does_not_hang_the_workers(tmp_path):
    """A thread holds numba's compiler lock when ``forked`` is called and the workers compile
    a kernel: a worker forked then would wait for the lock for ever (the thread that holds it
    is not in the child); ``forked`` runs the items on threads instead, which wait for the
    thread to end its compile."""
    assert _script(tmp_path, _HELD_COMPILER_LOCK, timeout=60).split() == ["[1,", "4,", "7,", "10,", "13]"]


_QUIET_FORK = """
import os, threading
import numba
from numba.core.compiler_lock import global_compiler_lock
from tlm.kernels import threads
from tlm.progress import progress_bar

parent = os.getpid()
at_fork = []  # (numba's compiler lock held by the forking thread, the other threads alive)
os.register_at_fork(before=lambda: at_fork.append((global_compiler_lock.is_locked(), threading.active_count())))

def work(i):  # a kernel compiled in the worker, which holds the compiler lock no more
    return os.getpid() != parent, global_compiler_lock.is_locked(), numba.njit(lambda x: x * 3 + 1)(i)

with progress_bar(False, total=1) as bar:  # (tqdm starts a monitor thread with its first bar but for tlm's)
    bar.update()
with threads.using(3):
    assert list(threads.ordered(lambda i: i, range(9))) == list(range(9))  # (the pool's threads, idle now)
    assert threading.active_count() == 4
    print(list(threads.forked(work, range(5), 2)))
    print(at_fork)
    print(threading.active_count())
    assert list(threads.ordered(lambda i: i + 1, range(9))) == list(range(1, 10))  # (a pool made again)
"""


@needs_fork
def test_workers_are_forked_from_a_quiet_process_and_compile_kernels(tmp_path):
    """A quiet process (tlm's progress bars start no monitor thread; the kernels' idle pools
    are shut down before the fork, and made again after): each worker is forked by a thread
    that holds numba's compiler lock, with no other thread alive, gives the lock up, and
    compiles a kernel of its own."""
    got, at_fork, after = _script(tmp_path, _QUIET_FORK).splitlines()
    assert got == str([(True, False, 3 * i + 1) for i in range(5)])
    assert at_fork == str([(True, 1), (True, 1)])
    assert after == "1"  # (the forked pool's own threads ended with it)


def test_a_live_thread_or_a_call_in_flight_keeps_the_items_on_threads():
    """Another Python thread alive (a user's, a notebook's), or a call still running on the
    kernels' pool (:func:`~tlm.kernels.threads.background`): nothing is forked, the items run
    on threads of this process, in order."""
    parent = os.getpid()
    release = threading.Event()
    user = threading.Thread(target=release.wait, name="a-user-thread")
    user.start()
    try:
        assert list(threads.forked(lambda i: (i, os.getpid()), range(5), 2)) == [(i, parent) for i in range(5)]
    finally:
        release.set()
        user.join()
    release.clear()
    with threads.using(2):
        job = threads.background(release.wait)
        try:
            assert list(threads.forked(lambda i: (i, os.getpid()), range(5), 2)) == [(i, parent) for i in range(5)]
        finally:
            release.set()
        assert job.result() is True


def test_tlm_s_progress_bars_start_no_monitor_thread():
    """tqdm starts a monitor thread with its first bar, drawn or not, and keeps it while the
    process lives (it takes tqdm's lock every few seconds): tlm's bars start none."""
    before = set(threading.enumerate())
    with progress_bar(False, total=2) as bar:
        bar.update()
        assert [t.name for t in set(threading.enumerate()) - before] == []


_DEFAULT_FORKS = """
import os, sys
import numpy as np
from tlm.arch.costs import load_programs
from tlm.arch.model import simulate
from tlm.config import config_from_dict
from tlm.experiments.run import render
from tlm.kernels import bsp, emission, estimate, photons, threads, traverse
from tlm.render import batches

forks = []
os.register_at_fork(before=lambda: forks.append(1))
# small chunks and batches (tests/test_threads.py's small_chunks), so that a small image is cut
traverse.JIT_MIN_CHUNK, estimate.GATHER_MIN_CHUNK, estimate.QUERY_BLOCK = 37, 23, 301
photons.PHOTON_MIN_CHUNK, emission.CONE_CHUNK, batches.MIN_BATCH_RAYS, bsp.GROUP_MIN_ELEMENTS = 700, 3000, 16, 40
threads.available = lambda: 3  # 3 "CPUs" ...
threads.DEFAULT_MAX_THREADS = 2  # ... past the threads' maximum
raw = {"scene": "cornell-water", "mode": "refract", "resolution": [24, 20], "photons": {"count": 5000},
       "render": {"spp": 1, "batch_rays": 200, "threads": None}, "arch": {"frames": 2, "trace": False}}
out = {}
for setting in ("0", "", "1"):
    os.environ["TLM_FORK_WORKERS"] = setting
    before = len(forks)
    res = render(config_from_dict(raw))
    tm = simulate(res.functional(), load_programs(), res.cfg.arch)
    out[setting] = (res, tm)
    print(setting or "unset", res.cfg.render.threads, len(forks) - before)
(ra, ta) = out["0"]
for setting in ("", "1"):
    rb, tb = out[setting]
    assert ra.radiance.keys() == rb.radiance.keys()
    for name in ra.radiance:
        assert ra.radiance[name].tobytes() == rb.radiance[name].tobytes(), name
    assert ra.work.keys() == rb.work.keys()
    for name in ra.work:
        assert ra.work[name].keys() == rb.work[name].keys()
        for k in ra.work[name]:
            assert ra.work[name][k].dtype == rb.work[name][k].dtype
            assert ra.work[name][k].tobytes() == rb.work[name][k].tobytes(), (name, k)
    assert ta.cycles == tb.cycles
print("same")
"""


@needs_fork
def test_past_the_threads_maximum_a_render_forks_by_default_with_the_bits_of_threads(tmp_path):
    """``TLM_FORK_WORKERS`` unset: a render on more threads than DEFAULT_MAX_THREADS (here 3
    CPUs over a maximum of 2, ``render.threads: null``) runs its batches and photon chunks on
    forked workers, ``0`` on threads, ``1`` forked too; images, work and cycles byte-identical."""
    lines = _script(tmp_path, _DEFAULT_FORKS, timeout=300).splitlines()
    assert lines[-1] == "same"
    got = {setting: (n, int(forks)) for setting, n, forks in (line.split() for line in lines[:-1])}
    assert got["0"] == ("None", 0)
    assert got["unset"] == ("None", 3)  # (a pool of 3 workers for the batches; refract traces no photons)
    assert got["unset"] == got["1"]


_SIGNAL_AT_FORK = """
import _thread, multiprocessing, os, signal, sys, time
from tlm.kernels import threads

signal.signal(signal.SIGINT, signal.default_int_handler)  # (a runner started in a shell's background passes SIGINT on
# ignored, and Python leaves it so: as an interactive Python has it)

# (a thread no Python check sees, OpenBLAS's or numba's; where there is none, the main thread gets the signal)
native = _thread.start_new_thread(time.sleep, (60,)) if sys.argv[1] == "thread" else None
sent = []

def hook():  # an at-fork hook (logging has some): a handler that raises inside one is ignored by CPython
    if not sent:
        sent.append(1)
        if native is None:
            os.kill(os.getpid(), signal.SIGINT)
        else:  # (delivered to a thread that does not block it; Python runs the handler in the main thread)
            signal.pthread_kill(native, signal.SIGINT)
        for _ in range(100000):  # (the handler runs here, inside the hook)
            pass

os.register_at_fork(after_in_parent=hook)
try:
    with threads.using(2):
        print("returned", list(threads.forked(lambda i: i, range(4), 2)))
except KeyboardInterrupt:
    print("KeyboardInterrupt")
print(len(multiprocessing.active_children()), sorted(signal.pthread_sigmask(signal.SIG_BLOCK, [])),
      signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""


@needs_fork
@pytest.mark.parametrize("to", ["process", "thread"])
def test_a_ctrl_c_while_the_workers_are_forked_is_not_lost(tmp_path, to):
    """A Ctrl-C (or the command line's SIGTERM, which raises as it does) whose handler runs in an
    at-fork hook while the workers are forked: CPython ignores an exception raised in a hook, so
    the run went on and ended as if nothing came. Now the signal is held across the forks and
    raised after them: the KeyboardInterrupt comes out of ``forked``, which ends its workers, and
    the signal mask and handler are as before. Sent to the process (the main thread blocks it)
    or to a native thread (which no mask of the main thread covers)."""
    script = tmp_path / "script.py"
    script.write_text(_SIGNAL_AT_FORK)
    env = {k: v for k, v in os.environ.items() if k != "TLM_FORK_WORKERS"}
    done = subprocess.run([sys.executable, str(script), to], capture_output=True, text=True, cwd=ROOT, env=env,
                          timeout=120, start_new_session=True)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.splitlines() == ["KeyboardInterrupt", "0 [] True"], done.stdout + done.stderr


_KILLED_PARENT = """
import multiprocessing, os, sys, time
from tlm.kernels import threads

def work(i):
    time.sleep(0 if i == 0 else 600)
    return i

with threads.using(2):
    done = threads.forked(work, range(5), 2)
    next(done)
    with open(sys.argv[1] + ".tmp", "w") as f:
        f.write(" ".join(str(p.pid) for p in multiprocessing.active_children()))
    os.replace(sys.argv[1] + ".tmp", sys.argv[1])
    time.sleep(600)
"""


@needs_fork
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="PR_SET_PDEATHSIG is Linux's")
def test_the_workers_end_with_a_killed_parent(tmp_path):
    """The process that forked the workers killed (SIGKILL, the out-of-memory killer; or ended by
    ``os._exit``, the command line's second Ctrl-C): no shutdown runs, and its workers waited on
    their pipes for ever, each holding a copy of its memory. They end with it now."""
    script, pids_file = tmp_path / "script.py", tmp_path / "pids"
    script.write_text(_KILLED_PARENT)
    env = {k: v for k, v in os.environ.items() if k != "TLM_FORK_WORKERS"}
    proc = subprocess.Popen([sys.executable, str(script), str(pids_file)], cwd=ROOT, env=env,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    pids: list[int] = []
    try:
        deadline = time.monotonic() + 120
        while not pids_file.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert pids_file.exists(), f"no workers forked (exit status {proc.poll()})"
        pids = [int(p) for p in pids_file.read_text().split()]
        assert len(pids) == 2
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait()
        deadline = time.monotonic() + 10
        while any(running(p) for p in pids) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert [p for p in pids if running(p)] == []
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)  # (the workers left behind, in the script's group)
        proc.wait()


def test_a_worker_whose_parent_is_gone_ends_at_once(tmp_path):
    """A worker whose parent died before it asked the kernel to end with it (its parent pid is not
    the forking process's) ends at once; one whose parent lives goes on."""
    script = tmp_path / "script.py"
    script.write_text("import os\nfrom tlm.kernels import threads\n"
                      "threads._forked_init(False, os.getppid())\nprint('kept', flush=True)\n"
                      "threads._forked_init(False, -1)\nprint('still here')\n")
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert (done.returncode, done.stdout, done.stderr) == (1, "kept\n", "")


_FORK_REFUSED = """
import errno, multiprocessing, signal
import multiprocessing.popen_fork as popen_fork
from tlm.kernels import threads

signal.signal(signal.SIGINT, signal.default_int_handler)  # (a runner started in a shell's background passes SIGINT on
# ignored, and Python leaves it so: as an interactive Python has it)

real, launched = popen_fork.Popen._launch, []

def launch(self, process_obj):  # the second fork refused (EAGAIN: too many processes)
    launched.append(1)
    if len(launched) == 2:
        raise OSError(errno.EAGAIN, "fork refused")
    return real(self, process_obj)

popen_fork.Popen._launch = launch
try:
    list(threads.forked(lambda i: i, range(6), 3))
except OSError as e:
    print("refused:", e.strerror)
print(len(multiprocessing.active_children()), sorted(signal.pthread_sigmask(signal.SIG_BLOCK, [])),
      signal.getsignal(signal.SIGINT) is signal.default_int_handler)
"""


@needs_fork
def test_a_fork_refused_part_way_leaves_no_worker_and_no_hang(tmp_path):
    """The second of three forks refused: the error comes out of ``forked``, the worker already
    forked is ended (the pool's shutdown alone told it nothing, and multiprocessing waited for it
    at the interpreter's exit, for ever), and the signals are as before."""
    assert _script(tmp_path, _FORK_REFUSED, timeout=60).splitlines() == ["refused: fork refused", "0 [] True"]


def test_a_refused_submit_is_not_counted_as_a_call_in_flight():
    """A submit refused (a pool shut down: "cannot schedule new futures after shutdown") leaves
    no call counted in flight: one left counted kept every later ``forked`` on threads."""
    pool = ThreadPoolExecutor(1)
    pool.shutdown()
    before = threads._BUSY
    with pytest.raises(RuntimeError, match="after shutdown"):
        threads._submit(pool, print)
    assert before == threads._BUSY


_ORDERED_ACROSS_A_FORK = """
import os, time
from tlm.kernels import threads

with threads.using(4):
    later = threads.ordered(lambda x: x + 1, range(40))
    first = next(later)
    while threads._BUSY:  # (its window's calls done: the process is quiet)
        time.sleep(0.01)
    print(set(threads.forked(lambda i: os.getpid(), range(4), 2)) - {os.getpid()} != set())
    print([first, *later] == list(range(1, 41)), threads._BUSY)
    print(set(threads.forked(lambda i: os.getpid(), range(4), 2)) - {os.getpid()} != set())
"""


@needs_fork
def test_an_ordered_call_resumed_after_a_fork_goes_on(tmp_path):
    """An :func:`ordered` generator paused while the same thread forks (which shuts the idle pools
    down) goes on, on a pool made again, rather than failing with "cannot schedule new futures
    after shutdown" and leaving a call counted in flight for good."""
    assert _script(tmp_path, _ORDERED_ACROSS_A_FORK, timeout=60).split() == ["True", "True", "0", "True"]


def test_a_stand_in_handler_left_in_place_puts_the_handlers_back_at_the_next_signal():
    """A signal while :class:`threads._HeldSignals` puts the handlers back can leave the stand-in
    installed (a notebook would keep it for life): the next signal puts every handler back before it
    is passed on."""
    import signal

    got = []

    def handler(signum, frame):
        got.append(signum)

    before = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        stand_in = threads._HeldSignals()
        stand_in.before = {signal.SIGINT: handler, signal.SIGTERM: handler}
        signal.signal(signal.SIGINT, stand_in)
        signal.signal(signal.SIGTERM, stand_in)
        signal.raise_signal(signal.SIGTERM)
        assert got == [signal.SIGTERM]
        assert signal.getsignal(signal.SIGINT) is handler and signal.getsignal(signal.SIGTERM) is handler
    finally:
        for s, h in before.items():
            signal.signal(s, h)
