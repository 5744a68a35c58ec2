"""The compiled kernels on several threads, with the bits of one (``render.threads``).

The kernels of :mod:`tlm.kernels._jit` (traversal) and :mod:`tlm.kernels._jit_gather`
(the fixed-radius gather) are compiled with ``nogil=True``, so Python threads run them
on several cores at once. Every one of them computes each ray's or query's result from
that ray or query alone (random numbers are hashed per pixel, sample, photon and bounce,
never drawn per thread), so the work is cut into contiguous *chunks* of rays, photons or
gather points, the chunks run on a pool, and their outputs are joined in chunk order:
the per-ray values, counts and memory lists are those of one call on the whole array,
whatever the number of threads or where the cuts fall. Nothing is summed across chunks
in an order that depends on the threads (floating-point sums stay inside a ray or a
query, in the kernel's own order), and what is carried from one chunk to the next, the
cache pairs' state (:class:`~tlm.kernels.memory.Streams`), is charged afterwards in the
calling thread, chunk after chunk.

The number of threads is a setting of the calling thread (:func:`using`, which
:func:`tlm.experiments.run.render` enters with ``render.threads``); outside it, and inside
a pool's worker (no nesting), the kernels run on one thread.
"""

from __future__ import annotations

import contextlib
import contextvars
import itertools
import logging
import os
import sys
import threading
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path
from typing import TypeVar

from tlm.kernels import threads_forked
from tlm.kernels.threads_forked import _forked_init as _forked_init  # (the forked pool: kept importable from here)
from tlm.kernels.threads_forked import _HeldSignals as _HeldSignals
from tlm.kernels.threads_forked import die_with_parent as die_with_parent
from tlm.kernels.threads_forked import forked as forked

T = TypeVar("T")
R = TypeVar("R")

CHUNKS_PER_THREAD = 4  # chunks per thread: rays differ in cost, so a few each balance the load

_THREADS: contextvars.ContextVar[int] = contextvars.ContextVar("tlm_threads", default=1)
_SHARE: contextvars.ContextVar[int] = contextvars.ContextVar("tlm_share", default=1)
_POOLS: dict[int, ThreadPoolExecutor] = {}
_POOLS_LOCK = threading.Lock()
_BUSY = 0  # calls submitted to the pools that have not returned (nor been cancelled); under _POOLS_LOCK


CGROUP_ROOT = Path("/sys/fs/cgroup")  # where Linux mounts the control groups
SELF_CGROUP = Path("/proc/self/cgroup")  # this process's control groups


def available() -> int:
    """The CPUs this process may run on: its affinity mask (the CPU count where there is
    none), and no more than a CPU quota of its control groups allows (:func:`quota_cpus`:
    a container limited to 2 CPUs of a 64-core machine sees 64 CPUs in its mask, and 64
    threads there would wait their turns, each costing more CPU time, not less)."""
    try:
        cpus = max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # (no affinity on this platform)
        cpus = max(1, os.cpu_count() or 1)
    quota = quota_cpus()
    return cpus if quota is None else max(1, min(cpus, quota))


def _ancestors(path: str) -> list[str]:
    """``a/b/c`` -> ``["a/b/c", "a/b", "a", ""]``: a control group and those above it
    (only ``""``, the root as this process sees it, for a group outside its namespace's
    root, ``/../x``: no path leaves the mount)."""
    parts = [x for x in path.strip().split("/") if x]
    if any(x in (".", "..") for x in parts):
        return [""]
    return ["/".join(parts[:k]) for k in range(len(parts), -1, -1)]


def quota_cpus(root: Path | None = None, self_cgroup: Path | None = None) -> int | None:
    """The CPUs a CPU quota of this process's control groups allows, rounded up (1.5 CPUs:
    2), the smallest along its groups' paths; None where no quota is set or none can be
    read (not Linux, no control groups). cgroup v2: ``cpu.max`` (``"<quota> <period>"``,
    ``max``: none); v1: ``cpu.cfs_quota_us`` over ``cpu.cfs_period_us`` (-1: none). The
    groups are read from ``self_cgroup`` (default :data:`SELF_CGROUP`) under ``root``
    (default :data:`CGROUP_ROOT`, where Linux mounts them; a controller mounted elsewhere is
    not read); a container sees its own group as the root."""
    root = CGROUP_ROOT if root is None else Path(root)
    self_cgroup = SELF_CGROUP if self_cgroup is None else Path(self_cgroup)
    try:
        lines = self_cgroup.read_text().splitlines()
    except (OSError, UnicodeDecodeError):
        lines = []
    v2 = [""]  # (the root's own files: read even where the process's groups are not known)
    v1 = {("cpu", ""), ("cpu,cpuacct", "")}
    for line in lines:
        parts = line.split(":", 2)
        if len(parts) != 3:
            continue
        _, controllers, path = parts
        if controllers == "":
            v2 += _ancestors(path)
        elif "cpu" in controllers.split(","):
            for mount in {controllers, "cpu", "cpu,cpuacct"}:
                v1 |= {(mount, a) for a in _ancestors(path)}
    limits = []
    for group in dict.fromkeys(v2):
        fields = _read(root / group / "cpu.max").split()
        if len(fields) == 2 and fields[0] != "max":
            limits.append(_cpus(fields[0], fields[1]))
    for mount, group in sorted(v1):
        limits.append(_cpus(_read(root / mount / group / "cpu.cfs_quota_us"),
                            _read(root / mount / group / "cpu.cfs_period_us")))
    limits = [n for n in limits if n is not None]
    return min(limits) if limits else None


def _read(path: Path) -> str:
    """A control-group file's text, stripped; empty where it cannot be read."""
    try:
        return path.read_text().strip()
    except (OSError, UnicodeDecodeError):
        return ""


def _cpus(quota: str, period: str) -> int | None:
    """``ceil(quota / period)`` of two integers' texts, both > 0; None otherwise (no quota,
    or a file not there or not understood: never a guess)."""
    try:
        q, t = int(quota), int(period)
    except ValueError:
        return None
    return -(-q // t) if q > 0 and t > 0 else None


def current() -> int:
    """The threads the kernels called from this thread use (1 outside :func:`using`)."""
    return _THREADS.get()


def share() -> int:
    """How many calls of :func:`ordered` may be in flight beside this one (1 outside a
    worker): a call that bounds its memory by a budget (``render.batch_rays``) takes this
    part of it, so the calls in flight together hold about one budget."""
    return _SHARE.get()


# The most threads the batches run on as threads by default: they share the interpreter lock,
# and past about 8 more threads render slower, not faster. On a 16-core machine
# (benchmarks/README.md, "16 cores", 2026-11-29) cornell_pmap 320x320 ran 4.97x one thread's
# speed on 8 threads and 3.13x on 16 (3.91x and 2.43x before the glue was compiled); the
# conference room 5.10x and 4.02x. Forked workers share no lock and take every CPU (9.99x on
# 16): a render on more threads than this runs its batches and photon chunks on forked workers
# (:func:`can_fork`), and ``render.threads: null`` takes every CPU where it may fork.
DEFAULT_MAX_THREADS = 8


def default_threads(cpus: int | None = None) -> int:
    """The threads of ``render.threads: null``: ``cpus`` (default the CPUs available,
    :func:`available`; a sweep's worker passes its share of them), at most
    :data:`DEFAULT_MAX_THREADS` unless the batches will run on forked workers: this
    process's own CPUs where :func:`can_fork` and no thread but this module's pools runs
    beside the caller (else :func:`forked` would fall back to threads, and more than
    :data:`DEFAULT_MAX_THREADS` threads render slower); a share of them for another process
    (a sweep's worker, whose threads and daemon flag this one cannot see: a Dask worker is a
    daemon) only where asked (``TLM_FORK_WORKERS=1``)."""
    if cpus is None:
        n = available()
        fork = can_fork(n) and not _other_threads(pools=False)
    else:
        n = max(1, int(cpus))
        fork = fork_workers() is True and can_fork(n)
    return n if fork else min(n, DEFAULT_MAX_THREADS)


def shared_threads(slots: int | None = None) -> int:
    """The threads of ``render.threads: null`` where ``slots`` points run at once on this machine (a sweep's
    local workers, or the task slots of the Dask workers on one machine): the CPUs available
    (:func:`available`) over them, at least one (:func:`default_threads`' own limits); None: this
    process's own answer, :func:`default_threads`. The one reading of a null ``render.threads``: a sweep's
    share (:func:`~tlm.experiments.executors.kernel_threads`) and a Dask worker's
    (:func:`~tlm.experiments.dask_workers.dask_worker_threads`) are this one."""
    if slots is None:
        return default_threads()
    return default_threads(available() // max(1, int(slots)))


@contextlib.contextmanager
def using(n: int | None):
    """Run the kernels called inside the block on ``n`` threads (None: :func:`default_threads`).
    ``TLM_FORK_WORKERS`` is checked here (:func:`fork_workers`), so a bad value is refused
    at one thread too, where it is not read."""
    fork_workers()
    n = default_threads() if n is None else int(n)
    if n < 1:
        raise ValueError(f"threads (={n}) must be >= 1")
    token = _THREADS.set(n)
    try:
        yield n
    finally:
        _THREADS.reset(token)


def _forget_pools() -> None:
    """In a forked child: the parent's pools' threads are not there, so start afresh (the
    lock too: the parent may have held it at the fork, :func:`forked` does; the fork lock is
    :mod:`~tlm.kernels.threads_forked`'s own)."""
    global _POOLS_LOCK, _BUSY
    _POOLS.clear()
    _POOLS_LOCK = threading.Lock()
    _BUSY = 0


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_pools)


def _pool(n: int) -> ThreadPoolExecutor:
    with _POOLS_LOCK:
        pool = _POOLS.get(n)
        if pool is not None and not all(t.is_alive() for t in list(getattr(pool, "_threads", ()))):
            _drop(pool)  # (it lost a thread, and :func:`_lost` could not let it go)
            pool = None
        if pool is None:
            pool = _POOLS[n] = ThreadPoolExecutor(max_workers=n, thread_name_prefix=f"{_POOL_THREADS}{n}")
            if _LOST_FILTER not in _FUTURES_LOG.filters:
                _FUTURES_LOG.addFilter(_LOST_FILTER)
        return pool


def _lost(record: logging.LogRecord) -> bool:
    """concurrent.futures' records of a pool's thread with an error (its traceback, printed on
    stderr): not printed. "Exception in worker" (the thread ends: its call's outcome could not be
    set, a MemoryError under ``ulimit -v``): the error is kept on the thread that ends, for
    :func:`result` to raise to a wait on that thread's call or on its pool (never another
    pool's), and the pool is let go (:func:`_drop`; or by the next :func:`_pool` where the lock
    is held: never waited for here, :func:`~tlm.kernels.threads_forked._quiet` holds it while it
    joins the pools' threads, this one too): what nobody waits for goes with the pool and its
    calls (its frames hold arrays), not kept for ever. Others' records pass."""
    if (record.threadName or "").startswith(_POOL_THREADS) and record.exc_info and record.exc_info[1] is not None:
        if record.msg == "Exception in worker":
            me = threading.current_thread()  # (the filter runs in the thread that logs: the one that ends)
            with contextlib.suppress(Exception):
                me._tlm_lost = record.exc_info[1]
                if _POOLS_LOCK.acquire(blocking=False):
                    try:
                        for pool in [p for p in _POOLS.values() if me in getattr(p, "_threads", ())]:
                            _drop(pool)
                    finally:
                        _POOLS_LOCK.release()
        return False
    return True


_FUTURES_LOG = logging.getLogger("concurrent.futures")
_LOST_FILTER = _lost


def _drop(pool: ThreadPoolExecutor) -> None:
    """A pool that lost a thread taken out of the pools (under ``_POOLS_LOCK``), and shut down
    without a wait (the calls it holds still run on its threads left): a later call gets live
    threads, not a queue none reads."""
    for n in [n for n, p in _POOLS.items() if p is pool]:
        del _POOLS[n]
    with contextlib.suppress(Exception):
        pool.shutdown(wait=False)


def result(future: Future):
    """``future.result()`` of a call submitted to the pools, or, where the worker thread running it
    ended without setting its outcome (concurrent.futures ends a worker whose call's outcome could
    not be set: a MemoryError under ``ulimit -v``), the error that ended it, rather than a wait for
    ever; where no thread ran it and its pool's have all ended, what ended one of them. The wait
    is checked every half second (:func:`~tlm.kernels.threads_forked.polled`, the forked pool's too)."""
    return threads_forked.polled(future, lambda: _worker_ended(future))


def _worker_ended(future: Future) -> BaseException | None:
    """What ended the worker thread running ``future``'s call, or, where none ran it, every thread of its pool
    (:func:`_lost` keeps it on the thread), the call cancelled and its pool let go (:func:`_drop`); None while a
    thread that may finish it lives, or the call finished."""
    ran, pool = getattr(future, "_tlm_thread", ()), getattr(future, "_tlm_pool", None)
    workers = () if ran or pool is None else set(getattr(pool, "_threads", ()))  # (none left to run it)
    if not ((ran and not ran[0].is_alive()) or (workers and not any(t.is_alive() for t in workers))) \
            or future.done():
        return None
    future.cancel()
    with _POOLS_LOCK:
        _drop(pool)
    lost = [e for t in (ran or sorted(workers, key=lambda t: t.name))
            if (e := getattr(t, "_tlm_lost", None)) is not None]
    return lost[0] if lost else RuntimeError("the kernel threads ended without finishing a call")


_POOL_THREADS = "tlm-kernel-"  # the start of the pools' threads' names


def _submit(pool: ThreadPoolExecutor, fn: Callable, *args) -> Future:
    """``pool.submit(fn, *args)``, counted in ``_BUSY`` until the call returns or is
    cancelled: :func:`forked` forks only while no call is in flight on the pools."""
    global _BUSY
    with _POOLS_LOCK:
        _BUSY += 1
        ran: list[threading.Thread] = []  # (the worker thread that runs it: result)
        try:
            future = pool.submit(_counted, ran, fn, *args)
        except BaseException:  # (refused, "cannot schedule new futures after shutdown": no call in flight)
            _BUSY -= 1
            raise
    future._tlm_thread, future._tlm_pool = ran, pool
    future.add_done_callback(_uncount_cancelled)
    return future


def _counted(ran: list, fn: Callable, *args):
    global _BUSY
    ran.append(threading.current_thread())
    try:
        return fn(*args)
    finally:  # (before the future is done: a caller that took every result sees no call in flight)
        with _POOLS_LOCK:
            _BUSY -= 1


def _uncount_cancelled(future: Future) -> None:
    global _BUSY
    if future.cancelled():  # (never ran, so _counted never took it off)
        with _POOLS_LOCK:
            _BUSY -= 1


def spans(n_items: int, min_chunk: int, threads: int | None = None) -> list[tuple[int, int]]:
    """Contiguous ``(start, stop)`` chunks covering ``range(n_items)`` in order: about
    :data:`CHUNKS_PER_THREAD` per thread, none shorter than ``min_chunk`` items (the
    kernels' per-call cost), one chunk when the work is small or there is one thread."""
    threads = current() if threads is None else threads
    if threads <= 1 or n_items <= min_chunk:
        return [(0, n_items)]
    count = max(1, min(threads * CHUNKS_PER_THREAD, n_items // max(1, min_chunk)))
    cuts = [n_items * k // count for k in range(count + 1)]
    return [(a, b) for a, b in itertools.pairwise(cuts) if b > a]


def ordered(fn: Callable[[T], R], items: Iterable[T], threads: int | None = None,
            weights: Iterable[float] | None = None) -> Iterator[R]:
    """``fn(item)`` of every item, yielded in the items' order, computed on ``threads`` workers.

    At most twice ``threads`` calls are in flight (submitted, not yet taken), so what the
    caller does with a result (charging cache pairs, copying into the output) overlaps
    the next chunks' work while memory stays bounded (:func:`share` says so to the calls).
    With ``weights`` (one per item, > 0: what a call holds, say its eye rays) the window
    holds calls of at most twice ``threads`` times the largest weight in all instead, so
    light items (the render's last pieces) keep the workers busy behind a heavy one that
    the caller waits for. One thread: plain calls, in order. The workers run with one
    thread each, so kernels they call do not split again.
    """
    threads = current() if threads is None else threads
    items = list(items)
    if threads <= 1 or len(items) <= 1:
        for item in items:
            yield fn(item)
        return
    window = 2 * threads
    weight = [1.0] * len(items) if weights is None else [float(w) for w in weights]
    if len(weight) != len(items) or not all(w > 0 for w in weight):
        raise ValueError(f"weights must be one number > 0 per item: {len(weight)} for {len(items)} items, "
                         f"the smallest {min(weight, default=0.0)}")
    limit = window * max(weight)  # (equal weights: ``window`` calls)
    pending: list[tuple[Future, float]] = []
    held = 0.0
    nxt = 0
    one = contextvars.copy_context()
    one.run(_THREADS.set, 1)
    one.run(_SHARE.set, _SHARE.get() * min(window, len(items)))  # (the calls of full weight in flight)
    try:
        while nxt < len(items) or pending:
            while nxt < len(items) and (not pending or held + weight[nxt] <= limit):
                # (the pool looked up per call: a :func:`forked` call between two shuts it down)
                pending.append((_submit(_pool(threads), one.copy().run, fn, items[nxt]), weight[nxt]))
                held += weight[nxt]
                nxt += 1
            future, w = pending.pop(0)
            held -= w
            yield result(future)
    finally:  # an error, Ctrl-C or a caller that stops: what has not started never runs
        for f, _ in pending:
            f.cancel()


def background(fn: Callable[[], R]) -> Future:
    """``fn()`` started on a worker of the pool (its kernels on one thread), while the
    caller goes on (with the other workers, for its own :func:`ordered` calls); the caller
    takes the result, or the error, from the future's ``result()`` before it needs it.
    On one thread, ``fn()`` is called now and the future holds its outcome."""
    n = current()
    if n <= 1:
        done: Future = Future()
        try:
            done.set_result(fn())
        except Exception as e:  # (raised again by result(), where the caller takes it)
            done.set_exception(e)
        return done
    one = contextvars.copy_context()
    one.run(_THREADS.set, 1)
    one.run(_SHARE.set, _SHARE.get() * 2)  # (a budget is shared with the caller's own calls)
    return _submit(_pool(n), one.run, fn)


# Threads that may run beside a fork, by name: a sweep worker's watch on its parent
# (tlm.experiments.executors_exit.watch_parent) waits in select() or sleep() and then calls
# os._exit, holding no lock a forked worker could need.
_QUIET_THREADS = frozenset({"tlm-watch-sweep"})


def fork_workers() -> bool | None:
    """``TLM_FORK_WORKERS``: ``1`` forked workers wherever the batches run at once, ``0``
    threads always, empty or unset None (forked workers past :data:`DEFAULT_MAX_THREADS`
    threads: :func:`can_fork`); any other value (``yes``, ``true``, ``2``) is an
    :class:`~tlm.errors.InputError` naming the variable (exit status 2), never taken as off."""
    raw = os.environ.get("TLM_FORK_WORKERS", "")
    if raw.strip() not in ("", "0", "1"):
        from tlm.errors import InputError

        raise InputError(f"{raw!r} is not 0 or 1 (1: forked worker processes; 0: threads; empty or unset: "
                         f"forked worker processes past {DEFAULT_MAX_THREADS} threads)",
                         source="environment", key="TLM_FORK_WORKERS")
    return None if raw.strip() == "" else raw.strip() == "1"


def can_fork(n: int | None = None) -> bool:
    """Whether the batches and photon chunks of a render on ``n`` threads (default
    :func:`current`) run on forked worker processes (:func:`forked`): with
    ``TLM_FORK_WORKERS=1`` always (the callers run them at once only on more than one
    thread), with it empty or unset past :data:`DEFAULT_MAX_THREADS` threads (more threads
    than that render slower: the interpreter lock), with ``0`` never; and only where fork
    exists (not on Windows, nor macOS's default) and this process is no daemon (a Dask
    worker may not have children). :func:`forked` itself forks only from a quiet process,
    and falls back to threads (the same bits) where it is not."""
    import multiprocessing

    asked = fork_workers()
    if asked is False or (asked is None and (current() if n is None else n) <= DEFAULT_MAX_THREADS):
        return False
    return "fork" in multiprocessing.get_all_start_methods() and not multiprocessing.current_process().daemon


def _other_threads(pools: bool = True) -> list[str]:
    """The names of the Python threads alive beside the calling one, less :data:`_QUIET_THREADS`
    (and, with ``pools=False``, less this module's pools' workers, which :func:`forked` ends)."""
    me = threading.current_thread()
    return [t.name for t in threading.enumerate()
            if t is not me and t.name not in _QUIET_THREADS and (pools or not t.name.startswith(_POOL_THREADS))]


def chunked(fn: Callable[[int, int], R], n_items: int, min_chunk: int) -> list[R]:
    """``fn(start, stop)`` of the :func:`spans` of ``n_items``, the results in chunk order."""
    return list(ordered(lambda s: fn(*s), spans(n_items, min_chunk)))


threads_forked.attach(sys.modules[__name__])  # (the forked pool reads this module's pools and settings)
