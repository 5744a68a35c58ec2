"""The forked process pool of :func:`forked` (out of :mod:`tlm.kernels.threads`, which imports this
module and keeps its names importable from there: ``threads.forked``, ``threads.die_with_parent``).

:func:`forked` runs :func:`~tlm.kernels.threads.ordered`'s calls on forked worker processes. What
it reads of the thread pools (their lock, calls in flight and idle pools, the threads alive, the
fallback :func:`~tlm.kernels.threads.ordered`, the :func:`~tlm.kernels.threads.share` setting) is
looked up on :mod:`tlm.kernels.threads` at each call (``_pools``, handed over by that module as
it is imported: :func:`attach`; this one imports nothing of it, the layers' check sees no cycle),
so that what replaces one there (a test's stand-in) is what runs here too.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterable, Iterator
from types import ModuleType
from typing import TypeVar

T = TypeVar("T")
R = TypeVar("R")

_pools: ModuleType | None = None  # tlm.kernels.threads (:func:`attach`)


def attach(pools: ModuleType) -> None:
    """Called by :mod:`tlm.kernels.threads` at its import: where the thread pools' state is read."""
    global _pools
    _pools = pools


_FORKED: Callable | None = None  # what the forked workers of :func:`forked` call (set before the fork)
_FORKED_SHARE = 1  # their :func:`~tlm.kernels.threads.share` (the calls in flight: twice the processes)
_FORK_LOCK = threading.Lock()  # one forked pool at a time: its workers inherit _FORKED


def _forget_fork_lock() -> None:
    """In a forked child: the parent may have held the fork lock at the fork (:func:`forked` does)."""
    global _FORK_LOCK
    _FORK_LOCK = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_fork_lock)


def _compiler_lock():
    """numba's global compiler lock (held while a thread compiles a kernel or loads one from
    the cache), or a lock of none where numba is not imported (then no thread compiles)."""
    module = sys.modules.get("numba.core.compiler_lock")
    return contextlib.nullcontext() if module is None else module.global_compiler_lock


@contextlib.contextmanager
def _quiet():
    """Yield True with this process quiet enough to fork, else False (the caller runs threads).

    fork() copies only the calling thread: a lock another thread holds at that instant stays
    held forever in the child, which then hangs when it needs it (2026-11-27, a ``tlm run``
    and the test suite). So, in this order:

    * no call in flight on the thread pools (``_BUSY``: an :func:`~tlm.kernels.threads.ordered` or
      :func:`~tlm.kernels.threads.background` call may be loading a kernel, or a caller may still submit to the
      pool) and no other Python thread alive but the pools' (:func:`~tlm.kernels.threads._other_threads`: a
      user's, a notebook's, a progress bar's, another library's pool): else False. What such
      a thread holds cannot be known (nor whether it is about to submit to a pool); tlm's own
      bars start no monitor thread (:func:`tlm.progress._bar_class`);
    * then the idle pools are shut down and their threads joined, under ``_POOLS_LOCK`` so
      that none is made again meanwhile (they are made again on first use), and no thread
      but the caller is left (else False);
    * numba's global compiler lock held by this thread across the fork: a thread that the
      check cannot see (started by C code) may be compiling or loading a kernel; the fork
      waits for it. The children own the lock then (the forking thread is their only one,
      with the same id) and give it up first thing (:func:`_forked_init`), so they compile
      and load kernels as any process does.

    The libraries' native threads hold none of Python's locks: numpy's BLAS pool (OpenBLAS
    stops its threads around a fork itself), numba's threading layer (OpenMP or workqueue
    threads, started by a ``parallel=True`` kernel: the reference's, which no forked worker
    calls). The interpreter takes its import lock across a fork itself, and a module's own
    import lock is held only by a thread importing it: none runs."""
    with _pools._POOLS_LOCK:
        if _pools._BUSY or _pools._other_threads(pools=False):
            yield False
            return
        for pool in _pools._POOLS.values():
            pool.shutdown(wait=True)
        _pools._POOLS.clear()
        if _pools._other_threads():
            yield False
            return
        with _compiler_lock():
            yield True


PR_SET_PDEATHSIG = 1  # prctl option (<linux/prctl.h>): a signal for this process when its parent dies
# the signals whose Python handlers raise (the command line's: tlm.cli_signals.TAKEN)
_HELD_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))


def die_with_parent() -> None:
    """On Linux, have the kernel kill this process (SIGKILL) when the thread that forked it ends
    (``PR_SET_PDEATHSIG``): a parent killed, or ended by ``os._exit``, runs no shutdown that
    would tell its workers to stop. Elsewhere nothing (the callers check their parent too)."""
    if sys.platform.startswith("linux"):
        import ctypes

        with contextlib.suppress(OSError, AttributeError):
            ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)


def _forked_init(holds_compiler_lock: bool, parent: int) -> None:
    """A forked worker gives up numba's compiler lock that :func:`_quiet` held at the fork (its
    thread is the forking one, so it owns it), leaves Ctrl-C to the render that forked it
    (which ends the pool), and ends with the process ``parent`` that forked it.

    SIGINT, SIGTERM and SIGHUP came blocked from the fork (:class:`_HeldSignals`), so that none
    reached the handler the worker inherited (the command line's, which raises) before it
    is replaced here; they are unblocked after (a child's pending signals are none at the
    fork: nothing is lost). The end with ``parent``: a parent killed (SIGKILL, the out-of-memory
    killer) or ended by ``os._exit`` (the command line's second Ctrl-C, a sweep worker's
    watch on its own parent) runs no shutdown, and its workers would wait on their pipes for
    ever. On Linux the kernel kills the worker then (``PR_SET_PDEATHSIG``, as a sweep's
    workers do: :func:`tlm.experiments.executors_exit.exit_with`); a parent that died before
    that call is seen by its pid. The kernel sends the signal when the *thread* that forked
    ends, not the process: the forks happen in the thread that iterates :func:`forked`'s
    generator, which consumes the workers' results, so the workers serve no one once it is
    gone (a generator handed to another thread that way gets BrokenProcessPool, not a hang)."""
    if holds_compiler_lock:
        _compiler_lock().release()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    if hasattr(signal, "SIGHUP"):  # (a closed terminal's, sent to the whole group: the render ends the pool)
        signal.signal(signal.SIGHUP, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, _HELD_SIGNALS)
    die_with_parent()
    if os.getppid() != parent:  # (the parent died before the prctl: this process is an orphan already)
        os._exit(1)


class _HeldSignals:
    """SIGINT and SIGTERM held while :func:`forked` forks its workers, and given to their
    handlers once the forks are done.

    ``os.fork()`` runs Python's at-fork hooks (logging's, ...) in the parent, and CPython
    ignores an exception raised in one ("Exception ignored in ..."): a SIGINT or SIGTERM whose
    handler raises (``KeyboardInterrupt``: the command line turns SIGTERM into one) and runs
    inside a hook would be lost, and the interrupted run would finish and exit 0. So, in the
    main thread (where Python runs the handlers; elsewhere this does nothing):

    * each signal's Python handler is replaced by this object, which only notes the signal
      while the forks run: the kernel may deliver a signal to any thread that does not block
      it (OpenBLAS's, numba's native threads, which no mask of this thread covers), and its
      Python handler then runs in the main thread, inside a hook;
    * the signals are blocked in this thread, so that a forked child (which inherits the
      mask, with the handler it cannot yet have replaced) gets none before :func:`_forked_init`
      unblocks them, and no fork is interrupted;
    * :meth:`release` unblocks them (what came meanwhile is noted), puts the handlers back and
      raises each noted signal again (``signal.raise_signal``): its handler runs then, outside
      any hook. The caller releases inside the region that shuts the forked pool down, so that
      the KeyboardInterrupt that comes out of it ends the workers.

    A handler left in place (a second signal while the handlers are put back) puts the handlers
    back at the next signal and passes it on to the one it replaced."""

    def __init__(self) -> None:
        self.before: dict[int, Callable] = {}
        self.noted: list[int] = []
        self.holding = False
        self.mask: set | None = None  # the thread's mask before, while blocked

    def __call__(self, signum: int, frame) -> None:
        if self.holding:
            self.noted.append(signum)
            return
        for held, handler in self.before.items():  # (left in place by a signal while they were put back)
            if signal.getsignal(held) is self:
                signal.signal(held, handler)
        self.before[signum](signum, frame)

    def hold(self) -> None:
        if threading.current_thread() is not threading.main_thread() or not hasattr(signal, "pthread_sigmask"):
            return
        self.holding = True
        for signum in _HELD_SIGNALS:
            handler = signal.getsignal(signum)
            if callable(handler):  # (a Python handler: not the default action, not ignored)
                self.before[signum] = handler  # (before the swap: :meth:`release` puts back any it finds)
                signal.signal(signum, self)
        # (the handlers first: once swapped, no SIGINT or SIGTERM raises until release)
        self.mask = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD_SIGNALS)

    def release(self) -> None:
        """Unblock, put the handlers back, raise what came meanwhile; once (then nothing)."""
        try:
            if self.mask is not None:  # (the C call unblocks before any handler runs: this one, noting)
                signal.pthread_sigmask(signal.SIG_SETMASK, self.mask)
                self.mask = None
        finally:
            self.holding = False
            try:
                for signum, handler in self.before.items():
                    if signal.getsignal(signum) is self:
                        signal.signal(signum, handler)
            finally:
                noted, self.noted = self.noted, []
                first = None
                for signum in noted:  # (each, as it came: the command line's second signal ends the process)
                    try:
                        signal.raise_signal(signum)
                    except BaseException as e:
                        first = first or e
                if first is not None:
                    raise first


def _end_forked(pool) -> None:
    """Shut a forked pool whose first ``submit`` failed part way (a fork refused, EAGAIN; the
    manager thread not started), or whose manager thread ended (:func:`_outcome`): its shutdown
    tells no worker to stop, and multiprocessing would wait for the workers already forked at
    the interpreter's exit, for ever. So they are killed (what they run is given up) and
    reaped first. A manager thread whose start was refused ("can't start new thread") is not
    joined (that raised "cannot join thread before it is started" over the refusal)."""
    _kill(list((getattr(pool, "_processes", None) or {}).values()))
    manager = getattr(pool, "_executor_manager_thread", None)
    if manager is not None and manager.ident is None:  # (never started)
        pool._executor_manager_thread = None
    pool.shutdown(wait=True, cancel_futures=True)


def _kill(workers: list) -> None:
    """The forked ``workers`` not yet reaped killed (what they run is given up), then reaped.
    :func:`forked` calls it too where a pool's manager thread ended before a wait saw it (the
    caller stopped taking results first: its own error, Ctrl-C): the pool's shutdown, the
    manager's work, told no worker to stop, and the interpreter's exit would join them for ever."""
    for p in workers:
        with contextlib.suppress(Exception):
            if p.exitcode is None:
                p.kill()
    for p in workers:
        with contextlib.suppress(Exception):
            p.join()


def _manager_errors() -> None:
    """Have ``threading.excepthook`` keep what ends a forked pool's manager thread on its pool
    (``_tlm_lost``), for :func:`_outcome` to raise, instead of printing its traceback; other
    threads' errors go to the hook that was there. Put in front of it once (again where it was
    replaced since: a test runner's own, put back after each test)."""
    before = threading.excepthook
    if getattr(before, "_tlm_forked", False):
        return

    def hook(args) -> None:
        ref = getattr(args.thread, "executor_reference", None)  # (the manager's weak reference to its pool)
        lost = getattr(ref() if callable(ref) else None, "_tlm_lost", None)
        if isinstance(lost, list) and args.exc_value is not None:
            lost.append(args.exc_value)
            return
        before(args)

    hook._tlm_forked = True
    threading.excepthook = hook


def polled(future, ended: Callable[[], BaseException | None]):
    """``future.result()``, the wait checked every half second: where ``ended()`` gives an error (what would
    finish the call ended without finishing it, and was let go: its future never finishes), that error is
    raised rather than a wait for ever. The one wait of the pools' calls: :func:`_outcome` (the forked pool's)
    and :func:`~tlm.kernels.threads.result` (the thread pools')."""
    while True:
        try:
            return future.result(timeout=0.5)
        except TimeoutError:
            if future.done():  # (the call's own TimeoutError, a disk's ETIMEDOUT: raised as it came, not waited on)
                return future.result()
            lost = ended()
            if lost is not None:
                raise lost from None


def _outcome(pool, future):
    """``future.result()`` of a call on the forked ``pool``, or, where the pool's manager thread
    (which queues the calls for the workers and sets their outcomes) ended without finishing it,
    the error that ended that thread (a MemoryError, "can't start new thread" under ``ulimit -v``:
    the call's future never finishes), the workers killed and reaped first (no one else tells
    them to stop), rather than a wait for ever (:func:`polled`)."""
    return polled(future, lambda: _manager_ended(pool, future))


def _manager_ended(pool, future) -> BaseException | None:
    """What ended the manager thread of the forked ``pool`` before ``future``'s call finished, its workers
    killed and reaped (:func:`_end_forked`); None while it lives (or there is none yet), or the call finished."""
    manager = getattr(pool, "_executor_manager_thread", None)
    if manager is None or manager.is_alive() or future.done():
        return None
    _end_forked(pool)
    return (getattr(pool, "_tlm_lost", None) or [RuntimeError(
        "the forked workers' manager thread ended without finishing a call")])[0]


def _call_forked(item):
    token = _pools._SHARE.set(_FORKED_SHARE)
    try:
        with _pools.using(1):  # (a worker's kernels do not split again)
            return _FORKED(item)
    finally:
        _pools._SHARE.reset(token)


def forked(fn: Callable[[T], R], items: Iterable[T], processes: int) -> Iterator[R]:
    """:func:`~tlm.kernels.threads.ordered` on ``processes`` forked worker processes instead of threads: no
    interpreter lock is shared, so the Python and numpy between the kernels run at once
    too. The workers are forked when the call starts, so ``fn`` (any callable: it is not
    pickled) and what it reads (a frame, its BSP, photon maps) are the caller's, page for
    page; the items and results are pickled. At most twice ``processes`` calls are in
    flight. Only where :func:`~tlm.kernels.threads.can_fork`. A worker that dies (killed, out of memory) fails
    the call with :class:`~concurrent.futures.process.BrokenProcessPool`, never a hang, and
    so does the pool's manager thread that ends (:func:`_outcome`: the error that ended it; its
    workers killed, there or where the caller stopped taking results first); the workers end
    with this process (:func:`_forked_init`).

    The workers are forked only from a quiet process (:func:`_quiet`: no call in flight on
    the pools, which are shut down, no other Python thread, numba's compiler lock held),
    with SIGINT and SIGTERM held across the forks (:class:`_HeldSignals`); where it is not
    quiet, or another thread's forked pool is running, the items run on ``processes``
    threads (:func:`~tlm.kernels.threads.ordered`), with the same results.

    The workers and this module's fork lock are held until the generator ends: a caller
    that may stop taking results early closes it (``contextlib.closing``). A generator left
    unclosed ends them when it is collected, which a traceback kept (a notebook's
    ``sys.last_traceback``, whose frames hold it) delays: later calls then run on threads."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    global _FORKED, _FORKED_SHARE
    items = list(items)
    if not items or not _FORK_LOCK.acquire(blocking=False):  # (another thread forks: not quiet)
        yield from _pools.ordered(fn, items, processes)
        return
    held = _HeldSignals()
    try:
        _FORKED, _FORKED_SHARE = fn, _pools._SHARE.get() * min(2 * processes, len(items))
        pool = None
        pending = []
        with _quiet() as quiet:
            if quiet:
                holds = not isinstance(_compiler_lock(), contextlib.nullcontext)
                pool = ProcessPoolExecutor(processes, mp_context=multiprocessing.get_context("fork"),
                                           initializer=_forked_init, initargs=(holds, os.getpid()))
                pool._tlm_lost = []  # (what ends its manager thread: _manager_errors, _outcome)
                _manager_errors()
                # (with fork the first submit forks every worker, then starts the pool's
                # manager thread: all the forks happen here, in the quiet process)
                try:
                    held.hold()
                    pending.append(pool.submit(_call_forked, items[0]))
                except BaseException:  # (a fork refused, EAGAIN: no half-made pool left behind)
                    _end_forked(pool)
                    raise
        if pool is None:
            _FORKED, _FORKED_SHARE = None, 1
            yield from _pools.ordered(fn, items, processes)
            return
        manager = getattr(pool, "_executor_manager_thread", None)  # (the first submit's, and its workers)
        workers = list((getattr(pool, "_processes", None) or {}).values())
        try:
            with pool:
                nxt = 1
                try:
                    held.release()  # (a signal held across the forks raises here: the pool is shut down)
                    while nxt < len(items) or pending:
                        while nxt < len(items) and len(pending) < 2 * processes:
                            pending.append(pool.submit(_call_forked, items[nxt]))
                            nxt += 1
                        yield _outcome(pool, pending.pop(0))
                finally:
                    for f in pending:
                        f.cancel()
        finally:  # (a manager thread that ended before a wait saw it, the caller having stopped taking
            # results first, told no worker to stop: those left are killed; a shutdown's manager joined all)
            if manager is not None and not manager.is_alive():
                _kill(workers)
    finally:
        try:
            held.release()  # (where the forks failed; else done already)
        finally:
            _FORKED, _FORKED_SHARE = None, 1
            _FORK_LOCK.release()
