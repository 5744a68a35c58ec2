"""Executors of a sweep's points: in this process, a local process pool, or Dask.

:func:`open_executor` gives the executor ``tlm sweep`` asks for: ``--jobs 1`` runs the
points in the tlm process itself (:class:`InProcess`, for a debugger); otherwise a
local pool of worker processes (:class:`LocalPool`), forked from a fresh server
process, that end with the sweep's process and outlive the death of one of their own;
or a Dask cluster (``--dask local`` starts a ``LocalCluster``, ``--dask tcp://HOST:PORT``
connects to a scheduler, once :func:`answers` found one there), through a :class:`DaskPool` that
ends a local cluster's workers at once when the sweep is interrupted and says when the cluster itself
fails the sweep (its scheduler lost, no worker for ``--dask-wait`` seconds, by default
:data:`NO_WORKERS_WAIT`). All are ``concurrent.futures`` executors: the sweep submits a
point and reads its future. What runs on a Dask worker itself: :mod:`tlm.experiments.dask_workers`;
the check of a scheduler's address (:func:`answers`) and :class:`SweepStopped`:
:mod:`tlm.experiments.executors_dask` (both importable from here too).
"""

from __future__ import annotations

import asyncio
import concurrent.futures as cf
import gc
import itertools
import logging
import os
import queue
import signal
import socket as socket  # (kept: executors.socket, the module answers connects with, is what tests patch)
import threading
import time
from collections import deque
from concurrent.futures.process import BrokenProcessPool
from contextlib import ExitStack, suppress
from dataclasses import dataclass, field
from typing import Any

from tlm.errors import InputError, interrupted_by
from tlm.experiments.executors_dask import CONNECT_TIMEOUT, WorkerWatch, answers
from tlm.experiments.executors_dask import SweepStopped as SweepStopped  # (kept importable from here: the sweep)
from tlm.experiments.executors_dask import host_kept as _host_kept  # (kept importable from here: tests)
from tlm.experiments.executors_dask import local_preloads as _local_preloads
from tlm.experiments.executors_dask import pre_spawn_env as _pre_spawn_env
from tlm.experiments.executors_dask import quiet_client as _client
from tlm.experiments.executors_exit import PARENT_POLL as PARENT_POLL  # (these: kept importable from here)
from tlm.experiments.executors_exit import alive as _alive  # noqa: F401
from tlm.experiments.executors_exit import exit_with as _exit_with
from tlm.experiments.executors_exit import release_semaphores as release_semaphores
from tlm.experiments.executors_exit import watch_parent as _watch_parent  # noqa: F401
from tlm.experiments.executors_quiet import QUIET_GRACE as QUIET_GRACE  # (these: kept importable from here)
from tlm.experiments.executors_quiet import Quiet as _Quiet
from tlm.experiments.executors_quiet import put_back_left as _put_back_left  # noqa: F401 (tests call it from here)
from tlm.experiments.worker_start import OWN_PROCESS as OWN_PROCESS  # (these: kept importable from here)
from tlm.experiments.worker_start import TLM_PRELOAD as TLM_PRELOAD
from tlm.experiments.worker_start import UNGUARDED_EXIT as UNGUARDED_EXIT
from tlm.experiments.worker_start import WORKERS_IGNORE as WORKERS_IGNORE
from tlm.experiments.worker_start import check_guarded as _check_guarded  # (read here: what a test replaces)
from tlm.experiments.worker_start import leave_if_bootstrapping as leave_if_bootstrapping
from tlm.experiments.worker_start import main_file_hidden, mp_context, tlm_preloaded
from tlm.experiments.worker_start import main_script as main_script
from tlm.experiments.worker_start import sigint_ignored as _sigint_ignored  # (tests import it from here)
from tlm.experiments.worker_start import unguarded_error as unguarded_error
from tlm.progress import interrupts_deferred

DASK_POLL = 1.0  # seconds between a sweep's checks of its Dask scheduler while it waits for points
NO_WORKERS_WAIT = 300.0  # seconds a sweep waits while its Dask scheduler has no worker, then stops (--dask-wait)
WORKERS_POLL = 5.0  # seconds between the sweep's questions to the scheduler about its workers (at most: a
# shorter wait asks twice within it)
ASK_TIMEOUT = 30.0  # seconds the scheduler gets to answer one
STOP_WAIT = 0.5  # seconds an interrupted sweep's --dask local workers get to close before they are killed
MAX_DEATHS = 2  # a point whose worker process died this often, the last time running it alone, fails
MAX_BLIND = 3  # a local pool broken this often in a row with no point started: the points it held fail
BROKEN_WAIT = 60  # seconds a broken local pool gets to fail the points it holds
STOP_JOIN = 5  # seconds an interrupted local pool's manager thread gets to end (its workers killed: at once)


class InProcess(cf.Executor):
    """``--jobs 1``: points run one at a time in this process (for debugging, and for a
    debugger's breakpoints); :meth:`run_next` runs the oldest submitted one."""

    def __init__(self) -> None:
        self.queue: deque[tuple[cf.Future, Any, tuple]] = deque()

    def submit(self, fn, /, *args, **kwargs):
        f: cf.Future = cf.Future()
        self.queue.append((f, fn, args))
        return f

    def run_next(self) -> None:
        f, fn, args = self.queue.popleft()
        try:
            f.set_result(fn(*args))
        except Exception as e:  # KeyboardInterrupt goes through: the sweep stops
            if (stop := interrupted_by(e)) is not None:  # (also where a kernel wrapped it)
                raise stop from e
            f.set_exception(e)

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self.queue.clear()


class WorkerDied(RuntimeError):
    """A point's worker process died while running it (a crash, a kill, ``os._exit``)."""


@dataclass(eq=False)
class _Job:
    """A point submitted to a :class:`LocalPool`: its future, its call and how its workers ended."""

    future: cf.Future  # the sweep's: set once the point finished, or failed for good
    fn: Any
    args: tuple
    kwargs: dict
    token: int  # names the point to :func:`_run_started`
    deaths: int = 0  # times its worker process died while running it
    ends: list[str] = field(default_factory=list)  # how those workers ended


def take_finished(finished: queue.SimpleQueue, timeout: float | None = None) -> list[cf.Future]:
    """The futures in ``finished`` (a queue their done-callbacks feed), in the order they
    finished: waiting for the first up to ``timeout`` seconds (None: until one comes; none in
    that time: an empty list), then every other one already there. A constant cost per future,
    where ``cf.wait`` on every future in flight costs a time proportional to them."""
    try:
        done = [finished.get(timeout=timeout)]
    except queue.Empty:
        return []
    while True:
        try:
            done.append(finished.get_nowait())
        except queue.Empty:
            return done


class LocalPool(cf.Executor):
    """A process pool that outlives the death of a worker process.

    A worker that dies (a crash, an OOM kill, ``os._exit``) breaks a
    ProcessPoolExecutor: every point it holds fails with BrokenProcessPool. This pool
    then replaces it. The points that had not started run again as before. Those that
    had started (a worker says so before running a point) may be the culprit: each runs
    again alone, one at a time, so that a death is charged to the one point running. A
    death counts against a point unless its worker was ended by the broken pool
    (SIGTERM) while another point ran beside it; a point whose worker died
    ``MAX_DEATHS`` times, the last time running it alone, fails with
    :class:`WorkerDied`. ``MAX_BLIND`` breaks in a row with no point started fail the
    points they held. The points are waited for in this process's thread (:meth:`run_next`),
    each pool future as it finishes (:attr:`finished`, fed by its done-callback), at a
    constant cost per point (``cf.wait`` on every future in flight cost a time quadratic in
    the points).

    Workers are forked from a fresh server process (``forkserver``), never from this
    one: this process may hold threads (the progress bar's monitor, a Dask client's
    event loop) whose locks a forked child would inherit held. Each runs the main script
    again as it starts (as Python's ``spawn`` does): one that starts the sweep as it is
    imported is refused with one :class:`~tlm.errors.InputError` before the pool starts a worker
    (:func:`_check_guarded`; its workers would end at once: :func:`leave_if_bootstrapping`).
    """

    def __init__(self, jobs: int) -> None:
        self.jobs = jobs
        self.context = mp_context()
        self.waiting: deque[_Job] = deque()  # not handed to the pool yet
        self.suspects: deque[_Job] = deque()  # started when the pool broke: each runs alone next
        self.inflight: dict[cf.Future, _Job] = {}  # the pool's futures
        self.finished: queue.SimpleQueue[cf.Future] = queue.SimpleQueue()  # the pool's futures as they finish
        # (those of a pool replaced since, no longer in inflight, are passed over)
        self.alone: _Job | None = None  # the suspect in flight: nothing else runs beside it
        self.tokens = itertools.count()
        self.settled = 0  # points whose future was set
        self.blind = 0  # breaks in a row with no point started
        if self.context.get_start_method() == "forkserver":
            # the fork server started with SIGINT and SIGHUP ignored, so that the workers forked from it
            # ignore them from their first instruction (they get the server's first handlers):
            # a Ctrl-C at the terminal, which signals the whole process group, reaches the
            # sweep alone, which kills them; no idle worker prints a KeyboardInterrupt's traceback
            from multiprocessing import forkserver

            with _sigint_ignored(), tlm_preloaded():
                forkserver.ensure_running()
        _check_guarded(self.context)
        self._new()

    def _new(self) -> None:
        from tlm.fingerprint import code_fingerprint

        env = {k: v for k, v in os.environ.items() if k.startswith("TLM_")}  # the server's may be older
        self.started = self.context.SimpleQueue()  # (token, pid) from a worker starting a point; one per pool
        self.pids: dict[int, int] = {}  # token -> pid of the worker that started it, in this pool
        self.processes: dict[int, Any] = {}  # pid -> the pool's Process, for its exit code
        self.pool = cf.ProcessPoolExecutor(max_workers=self.jobs, mp_context=self.context, initializer=_worker_init,
                                           initargs=(env, os.getpid(), self.started, code_fingerprint()))

    def submit(self, fn, /, *args, **kwargs):
        job = _Job(cf.Future(), fn, args, kwargs, next(self.tokens))
        self.waiting.append(job)
        self._pump()
        return job.future

    def run_next(self) -> None:
        """Wait until a submitted point has finished or failed for good, replacing the
        pool if it broke meanwhile."""
        settled = self.settled
        while self.settled == settled and self.inflight:
            done = [f for f in take_finished(self.finished) if f in self.inflight]
            if not done:  # (a replaced pool's)
                continue
            if any(_broke(f) for f in done):
                self._replace()
            else:
                self._read_started()
                for f in done:
                    self._settle(self.inflight.pop(f), f)
                self.blind = 0
            self._pump()

    def _pump(self) -> None:
        """Hand points to the pool: a suspect alone once nothing else is in flight, else every waiting one."""
        while self.alone is None and (self.suspects or self.waiting):
            if self.suspects:
                if self.inflight:
                    return
                job = self.alone = self.suspects.popleft()
            else:
                job = self.waiting.popleft()
            try:
                # a signal raised inside the submit could leave a worker the pool forked without
                # knowing it (its pid not read yet): stop() could not kill it, and it would print a
                # traceback once this process's semaphores were gone. It is raised once the pool knows it
                with interrupts_deferred():
                    f = self.pool.submit(_run_started, job.token, job.fn, *job.args, **job.kwargs)
                    self.inflight[f] = job
                    f.add_done_callback(self.finished.put)
                    self.processes.update(getattr(self.pool, "_processes", None) or {})
            except (BrokenProcessPool, RuntimeError):  # a worker died since the last look: not this point's
                # doing (RuntimeError: the broken pool's shutdown raced this submit)
                (self.suspects if job is self.alone else self.waiting).appendleft(job)
                self.alone = None
                self._replace()
                continue

    def _replace(self) -> None:
        """The pool broke: a new one, each point it held settled, charged or queued again."""
        # the broken pool fails every point it holds at once; one it never fails (a submit that
        # raced its shutdown) is taken back after BROKEN_WAIT seconds as if it had failed
        _, lost = cf.wait(list(self.inflight), timeout=BROKEN_WAIT)
        for f in lost:
            f.cancel()
        self.pool.shutdown(wait=True)  # its workers are joined: their exit codes are known
        self._read_started()
        self.started.close()
        if any(p.exitcode == UNGUARDED_EXIT and pid not in self.pids.values() for pid, p in self.processes.items()):
            raise unguarded_error()  # (the script's first sweep passed _check_guarded, this one's call did not)
        pids, processes, alone = self.pids, self.processes, self.alone
        self.alone = None
        held = sorted(self.inflight.items(), key=lambda item: item[1].token)
        self.inflight = {}
        self._new()
        again: list[_Job] = []
        for f, job in held:
            if f not in lost and not _broke(f):  # finished before the break
                self._settle(job, f)
            elif job.token in pids:
                p = processes.get(pids[job.token])
                code = None if p is None else p.exitcode
                if job is alone or code != -signal.SIGTERM:  # SIGTERM: ended by the broken pool, beside the culprit
                    job.deaths += 1
                    job.ends.append(_ended(code))
                if job is alone and job.deaths >= MAX_DEATHS:
                    self._settle(job, error=WorkerDied(
                        f"its worker process died {job.deaths} times running this point, "
                        f"the last time with no other point running ({', '.join(job.ends)})"))
                else:
                    self.suspects.append(job)
            else:
                again.append(job)
        self.blind = 0 if any(job.token in pids for _, job in held) else self.blind + 1
        if self.blind >= MAX_BLIND:  # workers die before running anything: give up on these points
            for job in again:
                self._settle(job, error=WorkerDied(
                    f"the sweep's worker processes died {self.blind} times in a row before starting a point"))
            self.blind, again = 0, []
        for job in reversed(again):  # in their order, before those submitted since
            (self.suspects if job is alone else self.waiting).appendleft(job)

    def _read_started(self) -> None:
        while not self.started.empty():
            token, pid = self.started.get()
            self.pids[token] = pid

    def _settle(self, job: _Job, f: cf.Future | None = None, error: BaseException | None = None) -> None:
        if job is self.alone:
            self.alone = None
        self.settled += 1
        if job.future.done():  # cancelled
            return
        if error is None:
            error = cf.CancelledError() if f.cancelled() else f.exception()
        if error is None:
            job.future.set_result(f.result())
        else:
            job.future.set_exception(error)

    def stop(self) -> list[int]:
        """The sweep was interrupted: every point cancelled and every worker killed now
        (SIGKILL: a point a worker runs is not waited for; its half-written folder is a
        temporary one, removed as a dead process's). Returns the workers' pids."""
        for job in [*self.waiting, *self.suspects, *self.inflight.values()]:
            job.future.cancel()
        self.waiting.clear()
        self.suspects.clear()
        processes = list((getattr(self.pool, "_processes", None) or {}).values())
        for proc in processes:
            with suppress(Exception):
                proc.kill()
        manager = getattr(self.pool, "_executor_manager_thread", None)  # (None once shut down)
        self.pool.shutdown(wait=False, cancel_futures=True)
        # its manager thread, which sees the workers dead and closes the pool's wake-up pipe, is
        # waited for (a little): CPython 3.11's exit handler (concurrent.futures.process._python_exit)
        # writes to that pipe unguarded, and a close in between printed "Exception ignored in:
        # <module 'threading'> ... OSError: [Errno 9] Bad file descriptor" after tlm's own line
        if manager is not None and manager is not threading.current_thread():
            manager.join(timeout=STOP_JOIN)
        return [proc.pid for proc in processes if proc.pid is not None]

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        if cancel_futures:
            for job in [*self.waiting, *self.suspects]:
                job.future.cancel()
            self.waiting.clear()
            self.suspects.clear()
        self.pool.shutdown(wait=wait, cancel_futures=cancel_futures)
        if wait:
            self.started.close()


def _broke(f: cf.Future) -> bool:
    return not f.cancelled() and isinstance(f.exception(), BrokenProcessPool)


def _ended(code: int | None) -> str:
    """How a worker process ended, from its exit code."""
    if code is None:
        return "its exit status is unknown"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exit code {code}"


_STARTED = None  # in a local worker: the queue on which it says which point it starts


def _worker_init(env: dict[str, str], parent: int, started=None, code: str | None = None) -> None:
    """A local worker's set-up: the sweep's ``TLM_*`` variables, SIGINT and SIGHUP ignored, an end with
    the sweep's process, the queue on which it says which point it starts, and the sweep's code
    fingerprint (``code``, :func:`tlm.fingerprint.code_fingerprint` of the sweep's process) as its own.

    The worker runs the code its fork server imported as it started (:data:`TLM_PRELOAD`: the renderer,
    the kernels; under ``spawn``, what it imported as it started), and the sweep hashed its points and
    keyed their frames with its fingerprint; read from the disk at the worker's first point, after an
    edit of the package meanwhile (a checkout worked on while a sweep runs, a worker started late or
    replaced), its own would file frames rendered by that code under another code's key (read as that
    code's by a later run: stale work counts), and miss the frame the sweep's first point of a group
    rendered (each point of the group rendering it again)."""
    global _STARTED
    _STARTED = started
    if code is not None:
        from tlm.fingerprint import use_code

        use_code(code)
    # Ctrl-C and a hang-up ignored: the sweep's process ends its workers (those of the fork server
    # ignore them from their start already: LocalPool; under spawn, from here on)
    for signum in WORKERS_IGNORE:
        signal.signal(signum, signal.SIG_IGN)
    _worker_env(env)
    _exit_with(parent)
    # tqdm's default lock is a multiprocessing semaphore, which a worker killed by an
    # interrupted sweep could not unregister (the resource tracker would warn at exit);
    # a worker's bars are never shown, a thread lock does
    from tqdm import tqdm

    tqdm.set_lock(threading.RLock())


def _run_started(token: int, fn, /, *args, **kwargs):
    """In a local worker: tell the sweep's process that this worker starts point ``token``, run it.

    The message is written before the point runs and at once (a SimpleQueue has no
    feeder thread), so it reaches the sweep even if the point ends the worker.
    """
    _STARTED.put((token, os.getpid()))
    return fn(*args, **kwargs)


def _worker_env(env: dict[str, str]) -> None:
    """Give a worker this process's ``TLM_*`` variables (``TLM_CACHE``) as they are now."""
    for k in [k for k in os.environ if k.startswith("TLM_")]:
        del os.environ[k]
    os.environ.update(env)


def kernel_threads(jobs: int, dask: str | None, points: int) -> int | None:
    """The ``render.threads`` of a point whose config leaves it null, so that the local
    workers' kernel threads share the CPUs without oversubscribing them: the CPUs
    available over the worker processes (:func:`open_executor`'s), at least one. None (the
    worker's own CPUs) for one worker, and for a remote Dask cluster, whose machines are
    not this one: there each point sizes itself
    (:func:`~tlm.experiments.dask_workers.dask_worker_threads`)."""
    from tlm.kernels.threads import shared_threads

    if dask not in (None, "local"):
        return None
    workers = min(jobs, points)
    return None if workers <= 1 else shared_threads(workers)  # (at most DEFAULT_MAX_THREADS, as a null's own)


def open_executor(stack: ExitStack, jobs: int, dask: str | None, points: int,
                  dask_wait: float | None = None) -> cf.Executor:
    """A concurrent.futures executor: in-process (``jobs`` 1), local processes, or a Dask
    client's; no more workers than ``points``. ``dask_wait``: the seconds a Dask sweep
    waits while its scheduler has no worker (None: :data:`NO_WORKERS_WAIT`)."""
    if jobs != 1 or dask is not None:  # (a script on stdin: its workers, and those started again, as python -c's)
        stack.enter_context(main_file_hidden())
    if dask is None:  # a pool even for one point: a point that ends its worker does not end the sweep
        return InProcess() if jobs == 1 else LocalPool(min(jobs, points))
    jobs = min(jobs, points)
    written = stack.enter_context(_host_kept())  # (closed last: the environment and loggers distributed changes,
    # put back; written: the variables it sets in this process, as its nannies will)
    from distributed import Client, LocalCluster

    # a Client left unreachable earlier (one whose connection failed: the constructor raised
    # with its loop started) is collected now: collected by chance while distributed starts
    # the next one's loop, its __del__ re-enters that loop's lock and the process hangs
    gc.collect()

    quiet = _Quiet()  # (DaskPool.trouble silences distributed's logs)
    stack.push(quiet.after)  # restored once the client has closed (not when a signal ends the process)
    quiet.hush()  # (its narration of a closed connection: silent for the client's whole life, from before it connects)
    if dask == "local":
        from distributed.utils import get_mp_context

        written.update(_pre_spawn_env())
        _check_guarded(get_mp_context())  # (the workers' own start method: a script that sweeps at import is
        # one line, where the nannies failed to start their workers)
        # no dashboard, and the scheduler's HTTP server on a free port: with dashboard_address=None
        # it still tries 8787, and warns when that is taken (another cluster, another sweep)
        # silence_logs: the workers' own warnings (a task cancelled by a signal, a worker
        # restarted) would reach the user's terminal as log lines; the sweep says what happened
        # preload: each worker's set-up as it starts (no multiprocessing semaphore of its own: _local_preloads)
        with _sigint_ignored():  # (the workers start with Ctrl-C and SIGHUP ignored: the sweep stops them)
            cluster = stack.enter_context(LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                                       dashboard_address="127.0.0.1:0",
                                                       scheduler_kwargs={"dashboard": False},
                                                       silence_logs=logging.CRITICAL, **_local_preloads()))
        for nanny in list(getattr(cluster, "workers", {}).values()):  # (what each nanny sets, as it computed it)
            written.update(getattr(nanny, "pre_spawn_env", None) or {})
        client = stack.enter_context(_client(Client, cluster))
    else:
        answers(dask)  # (a refused connection at once, where distributed retries it for CONNECT_TIMEOUT s)
        try:
            client = stack.enter_context(_client(Client, dask, timeout=CONNECT_TIMEOUT))
        except (OSError, ValueError, TypeError, MemoryError) as e:  # TimeoutError is an OSError (MemoryError: a
            # message size read from what is not a scheduler)
            raise InputError(f"cannot reach the Dask scheduler {dask!r} ({e})", key="--dask") from None
        cluster = None
    quiet.client = client
    stack.push(quiet.before)  # (runs first as the stack closes: the client, and a local cluster, close silenced
    # on a signal or where the client has lost its scheduler)
    pool = DaskPool(client, dask, remote=dask != "local", quiet=quiet, wait=dask_wait, cluster=cluster)
    pool.watch.start(refuse=pool.remote)  # (a worker that cannot run the points left out, before one is sent)
    return pool


class DaskPool(cf.Executor):
    """A Dask client's executor that can say when the cluster itself has failed the sweep.

    ``remote``: the scheduler is another process's (``--dask tcp://...``): its workers may
    be other machines, with other caches and other file systems. :meth:`trouble` is asked
    while the sweep waits: a point cancelled that the sweep did not cancel means the client
    lost its scheduler (distributed cancels every future then, and the points would
    otherwise be recorded as failed with an empty ``CancelledError``), and a scheduler with
    no worker for ``wait`` seconds (``--dask-wait``; None: :data:`NO_WORKERS_WAIT`) would keep
    the sweep waiting forever.
    """

    def __init__(self, client, address: str, remote: bool, quiet: _Quiet | None = None,
                 wait: float | None = None, cluster=None) -> None:
        self.client = client
        self.cluster = cluster  # a --dask local LocalCluster (this process's nannies: stop)
        self.quiet = _Quiet() if quiet is None else quiet
        self.address = address
        self.remote = remote
        self.executor = client.get_executor(pure=False)
        self.wait = NO_WORKERS_WAIT if wait is None else wait
        self.workerless_since: float | None = None
        self.asked = -float("inf")  # when the scheduler was last asked for its workers
        self.watch = WorkerWatch(client, remote=remote)  # (the workers checked, those lost holding points)
        self.keyed = type(self.executor).__name__ == "ClientExecutor"  # (a client's: each point keyed, for watch)

    def submit(self, fn, /, *args, **kwargs):
        if getattr(self, "keyed", False):  # (keyed, to the good workers only, sent again where they all left)
            return self.watch.send(fn, args, kwargs)
        return self.executor.submit(fn, *args, **kwargs)

    def send_again(self, point: str, record: dict) -> bool:
        """Whether the point ``point``, failed for its worker (:meth:`WorkerWatch.send_again`: then left out), is
        submitted again, to the other workers."""
        return getattr(self, "keyed", False) and hasattr(self, "watch") and self.watch.send_again(point, record)

    def lost(self) -> list[str]:
        """The lines on the workers left out of the sweep (:meth:`WorkerWatch.left_out`), then on those that left
        the cluster while they held some of the sweep's points."""
        return [*self.watch.left_out(), *self.watch.lost()] if hasattr(self, "watch") else []

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        with suppress(Exception):  # (a client whose scheduler is gone cannot cancel anything)
            self.executor.shutdown(wait=wait)
        if hasattr(self, "watch"):
            self.watch.close()

    def stop(self) -> None:
        """The sweep was interrupted: its points cancelled (the executor shut down, not waited
        for) and, for a ``--dask local`` cluster, its workers ended now: each gets
        :data:`STOP_WAIT` seconds to close (an idle one does), then its nanny kills it (a point
        it runs is not waited for: its half-written folder is a temporary one, removed as a dead
        process's; the worker holds no semaphore: :func:`_local_preloads`). Closing the cluster
        then has no worker left to wait for, where its nannies gave a busy one up to 4 s to
        finish its point. A remote cluster's workers are not the sweep's to end."""
        self.shutdown(wait=False)
        nannies = list((getattr(self.cluster, "workers", None) or {}).values())
        if not nannies:
            return

        async def close_all() -> None:
            await asyncio.gather(*(n.close(timeout=STOP_WAIT, reason="tlm-sweep-stopped") for n in nannies),
                                 return_exceptions=True)

        with suppress(Exception):  # (the cluster's close, next, ends what is left as ever)
            self.cluster.sync(close_all)

    def trouble(self, cancelled: bool) -> str | None:
        """Why the sweep cannot go on on this cluster, or None. ``cancelled``: a point's
        future came back cancelled (the sweep had cancelled none)."""
        status = getattr(self.client, "status", "running")
        if status != "running":
            return self._quiet(f"lost the Dask scheduler {self.address} (the connection to it closed)")
        if cancelled:
            return self._quiet(f"the Dask scheduler {self.address} cancelled the sweep's points (its connection "
                               "was lost, or the cluster restarted)")
        now = time.monotonic()
        if now - self.asked < min(WORKERS_POLL, self.wait / 2):  # (a short wait is not overrun by a poll)
            return None
        self.asked = now
        try:
            asked = self.client.nthreads(callback_timeout=ASK_TIMEOUT)
        except Exception as e:  # (a scheduler that does not answer: the same bounded wait)
            if getattr(self.client, "status", "running") != "running":
                return self._quiet(f"lost the Dask scheduler {self.address} ({type(e).__name__}: {e})")
            asked, why = None, f"has not answered ({type(e).__name__}: {e})"
        if asked is None:
            workers = 0
        else:  # (one that joined since: checked; an error of tlm's own there is not a scheduler's silence)
            workers, why = self.watch.seen(asked) if hasattr(self, "watch") else (len(asked), "has had no worker")
        if workers:
            self.workerless_since = None
            return None
        if self.workerless_since is None:
            self.workerless_since = now
        if now - self.workerless_since >= self.wait:
            lost = "".join(f"; {line}" for line in self.lost())  # (why it has none, where a worker that left says)
            return self._quiet(f"the Dask scheduler {self.address} {why} for {now - self.workerless_since:.0f} s "
                               f"(--dask-wait: {self.wait:g} s){lost}")
        return None

    def _quiet(self, reason: str) -> str:
        # the client's own log lines on the lost connection (a page of traceback) would follow
        # the sweep's line: tlm says what happened
        self.quiet.now()
        return reason
