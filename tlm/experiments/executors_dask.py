"""The Dask side of a sweep's executors that stands apart from the pool itself: the check that
something answers, as a Dask scheduler, at a ``--dask tcp://HOST:PORT`` address before the client
connects (:func:`answers`, within :data:`CONNECT_TIMEOUT` seconds), and :class:`SweepStopped`, the
one line that says the cluster, not a point, stopped the sweep; :func:`host_kept`, which puts back
what a local cluster changes in this process (the variables its nannies set, distributed's loggers); the
preloads of a local cluster's workers (:func:`local_preloads`); and :class:`WorkerWatch`, which checks
that each worker can run the sweep's points before any is sent (:class:`WorkerCannotRun` where none can), leaves
out one that cannot, or whose points fail for it, while another can (its points sent to the others, once), sends
a point again whose good workers all left (to the good ones there: :meth:`WorkerWatch.move`), and names a worker
that left the cluster while it ran some of them (each of these events, as the sweep's folder keeps it:
:meth:`WorkerWatch.worker_events`).

:mod:`tlm.experiments.executors` opens the executors and re-exports these names; the Dask
executor itself (:class:`~tlm.experiments.executors.DaskPool`), the seconds it waits and polls,
and the silencing of distributed's logs stay there. What runs on a Dask
worker: :mod:`tlm.experiments.dask_workers`. Nothing here imports distributed at import time.
"""

from __future__ import annotations

import builtins
import concurrent.futures as cf
import logging
import os
import socket
import threading
import types
import uuid
import warnings
from collections import deque
from contextlib import contextmanager, suppress

from tlm.errors import EnvironmentFailure, InputError

CONNECT_TIMEOUT = 10  # seconds to reach a Dask scheduler


SOCKET_SCHEMES = ("tcp", "tls", "ws", "wss")  # distributed's transports over a TCP connection to HOST:PORT


def answers(address: str, timeout: float = CONNECT_TIMEOUT) -> None:
    """An :class:`InputError` (``--dask``) where nothing answers at the scheduler's ``address``,
    told from one TCP connection to its host and port (a transport over TCP: :data:`SOCKET_SCHEMES`;
    any other is left to Dask): a refused one (no process listens on that port: a scheduler not
    started, or another port), an unknown host and an unreachable network are known at once,
    where distributed's connect retries them for its whole timeout and says "Timed out"; a host
    that does not answer (one that is down, a firewall that drops the packets) after ``timeout``
    seconds, as before, with a line that says so. A connection made is closed at once (the
    scheduler logs, at INFO, that one closed before its handshake), and Dask connects next."""
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, loc = parse_address(address)
        host, port = parse_host_port(loc)
    except (ValueError, TypeError):  # (a form Dask refuses itself, and says why)
        return
    if scheme not in SOCKET_SCHEMES:
        return
    where = ("the scheduler's address is the one 'dask scheduler' printed (Scheduler at: ...), "
             "tcp://HOST:8786 by default")
    try:
        with socket.create_connection((host, port), timeout=timeout) as conn:
            odd = _not_dask(conn) if scheme == "tcp" else None
    except ConnectionRefusedError:
        raise InputError(f"nothing answers at {address!r}: no process listens on port {port} of {host} (connection "
                         f"refused: no scheduler started there, or another port); {where}", key="--dask") from None
    except TimeoutError:  # (socket.timeout)
        raise InputError(f"no answer from {address!r} within {timeout:g} s (a host that is down or not there, or a "
                         f"firewall that drops the connection); {where}", key="--dask") from None
    except socket.gaierror as e:
        raise InputError(f"cannot reach {address!r}: its host {host!r} is not known ({e.strerror or e})",
                         key="--dask") from None
    except OSError as e:  # (no route to the host, an unreachable network)
        raise InputError(f"cannot reach {address!r} ({e.strerror or e}); {where}", key="--dask") from None
    if odd is not None:  # (distributed's connect would wait for it forever, or read its bytes as a frame's size)
        raise InputError(f"{address!r} answers, but not as a Dask scheduler ({odd}: a web server, such as the "
                         f"dashboard's, port 8787?); {where}", key="--dask")


HANDSHAKE_MAX = 1 << 20  # bytes: a Dask scheduler's first message (its handshake) is far smaller


def _not_dask(conn: socket.socket) -> str | None:
    """Why what answers on the TCP connection ``conn`` is not a Dask scheduler, or None: a
    scheduler writes its handshake as soon as it accepts, its first 8 bytes the size of the
    message (little-endian); a web server writes nothing before a request (``conn``'s timeout:
    it said nothing), or an answer whose bytes are no such size."""
    got = b""
    try:
        while len(got) < 8:
            more = conn.recv(8 - len(got))
            if not more:
                return None if got else "it closed the connection at once"  # (a scheduler busy elsewhere: Dask's)
            got += more
    except TimeoutError:
        return "it said nothing" if not got else None
    except OSError:
        return None
    if not 0 < int.from_bytes(got, "little") <= HANDSHAKE_MAX:
        return f"its first bytes are {got!r}"
    return None


class SweepStopped(EnvironmentFailure):
    """The cluster, not a point, stopped the sweep (its Dask scheduler lost, or without
    workers too long): one line, exit status 1; the points done are kept, and a rerun
    into the folder runs the others."""


@contextmanager
def host_kept():
    """The variables of the calling process's ``os.environ`` that distributed sets, and the ``distributed``,
    ``tornado`` and ``bokeh`` loggers' handlers and ``propagate``, put back as they were once the block ends:
    distributed sets the variables its nannies' workers inherit (``OMP_NUM_THREADS=1``,
    ``MALLOC_TRIM_THRESHOLD_``, ``PYTHONHASHSEED``, ...: its ``pre-spawn-environ``) in this process, and its
    import gives those loggers a handler of its own (a notebook's session would keep both after its sweep).
    Yields the record of what it sets (a dict the caller fills: :func:`pre_spawn_env`, the nannies' own); a
    variable is put back only where its value is still what distributed wrote, so that one another thread set
    meanwhile stays (the whole environment was put back, undoing it). Their levels are
    :class:`tlm.experiments.executors_quiet.Quiet`'s."""
    env = dict(os.environ)
    written: dict[str, str] = {}
    loggers = {n: (list(logging.getLogger(n).handlers), logging.getLogger(n).propagate) for n in _HOST_LOGGERS}
    try:
        yield written
    finally:
        for k, v in written.items():
            if os.environ.get(k) == v and env.get(k) != v:  # (still distributed's, not another thread's since)
                if k in env:
                    os.environ[k] = env[k]
                else:
                    os.environ.pop(k, None)
        for name, (handlers, propagate) in loggers.items():
            logger = logging.getLogger(name)
            logger.handlers[:] = handlers
            logger.propagate = propagate


def pre_spawn_env() -> dict[str, str]:
    """The variables a local cluster's nannies will set in this process before each worker starts, as
    ``distributed.nanny.Nanny`` computes them (Dask's ``distributed.nanny.pre-spawn-environ``, a variable
    already set keeping its value; ``PYTHONHASHSEED``; ``__DASK_PARENT_PID``, for the workers' process
    titles), for :func:`host_kept` to put back: known before the cluster starts, in case its start fails."""
    import dask

    given = dask.config.get("distributed.nanny.pre-spawn-environ", None)
    env = {k: os.environ.get(k, str(v)) for k, v in (given if isinstance(given, dict) else {}).items()
           if v is not None}
    if env.get("PYTHONHASHSEED") in (None, "0"):
        env["PYTHONHASHSEED"] = "6640"  # (distributed's own choice, dask/distributed#8400)
    env["__DASK_PARENT_PID"] = str(os.getpid())
    return env


_HOST_LOGGERS = ("distributed", "tornado", "bokeh")  # the loggers distributed's import configures


def quiet_client(client_class, *args, **kwargs):
    """``client_class(*args, **kwargs)`` (a ``distributed.Client``) without Dask's ``VersionMismatchWarning``,
    which it warns as it connects where the scheduler's, the workers' and this process's packages differ (a
    table over several lines, with a file's path): the points of a worker whose numpy, numba or Python differ
    fail with tlm's own line on it (:class:`~tlm.experiments.dask_workers.OtherVersionsOnWorker`), and the
    versions each point ran with are in its ``results.json``. The filter is the process's while the client
    connects (its loop's thread warns it, and a sync client waits for that), put back after."""
    from distributed.versions import VersionMismatchWarning

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", category=VersionMismatchWarning)
        return client_class(*args, **kwargs)


def local_preloads() -> dict[str, list]:
    """The ``preload`` and ``preload_argv`` of a ``--dask local`` cluster's workers: those of
    Dask's config (``distributed.worker.preload``, which an explicit ``preload`` would
    replace), then :mod:`tlm.experiments.dask_workers`, whose
    :func:`~tlm.experiments.dask_workers.dask_setup` gives the worker's progress bars a thread
    lock: a worker then holds no multiprocessing semaphore that the resource tracker it shares
    with the sweep would report leaked on the sweep's stderr when the worker is killed (an
    interrupted sweep's cluster closed while its points run, a SIGTERM to the process group,
    a worker killed -9)."""
    import dask

    from tlm.experiments import dask_workers

    preload = dask.config.get("distributed.worker.preload", None) or []
    argv = dask.config.get("distributed.worker.preload-argv", None) or []
    preload = [preload] if isinstance(preload, str) else list(preload)
    if argv and not isinstance(argv[0], str):  # one list per preload: none for tlm's (a flat list: one for all)
        argv = [*argv, []]
    return {"preload": [*preload, dask_workers.__name__], "preload_argv": list(argv)}


RUNNER = "tlm.experiments.sweep_point"  # the module a worker unpickles each point's task from (run_point, Task)
PROBE_MODULE = "tlm worker probe"  # the probe's module name: none a process can import (it pickles by value)


class WorkerCannotRun(EnvironmentFailure):
    """A remote Dask worker cannot load the sweep's points (its tlm is older than the sweep's, or it has
    none): Dask would end the worker at its first point, unpickling it, and the sweep would say only that
    its scheduler has no worker. Said before any point is sent: one line, exit status 1, nothing written."""


def _on_worker(runner: str, dask_worker=None) -> dict:
    """What a Dask worker has of tlm: its host, its name (``dask_worker``'s, which ``Client.run`` passes: the
    ``--name`` it was given, for the lines on it), the folder its ``tlm`` imports from, whether it has the module
    ``runner`` and, where its tlm can say, its code fingerprint (a worker with the runner too: :func:`other_code`
    compares it with the sweep's). Run on the worker as :func:`worker_probe`'s
    copy, pickled by value: the standard library only, and no exception leaves it (a worker whose tlm is older
    than the sweep's lacks modules that the sweep has, this one's included)."""
    import contextlib
    import importlib
    import importlib.util
    import socket

    seen: dict = {"host": socket.gethostname(), "tlm": None, "runner": False, "fingerprint": None, "error": None}
    name = getattr(dask_worker, "name", None)
    seen["name"] = name if isinstance(name, str) else None  # (plain data: a cluster's numbers are not names)
    try:
        spec = importlib.util.find_spec("tlm")
        if spec is not None:
            places = list(spec.submodule_search_locations or [])
            seen["tlm"] = places[0] if places else spec.origin
            seen["runner"] = importlib.util.find_spec(runner) is not None
    except ModuleNotFoundError as e:  # (a package above the runner's module not there: a tlm older still)
        if not (e.name and (runner + ".").startswith(e.name + ".")):
            seen["error"] = f"{type(e).__name__}: {e}"
    except Exception as e:  # (a tlm that fails as it is imported)
        seen["error"] = f"{type(e).__name__}: {e}"
    if seen["tlm"] is not None and seen["error"] is None:  # (compared with the sweep's, and for the line on it)
        with contextlib.suppress(Exception):  # (a tlm too old, or too odd, to say)
            seen["fingerprint"] = str(importlib.import_module("tlm.fingerprint").code_fingerprint())
    return seen


def worker_probe():
    """:func:`_on_worker` as a function of no module a worker could lack: distributed's pickle cannot find it
    by name (:data:`PROBE_MODULE`), so it pickles it by value (cloudpickle), its code and no global of this
    module, and a worker whose tlm has no :mod:`tlm.experiments.executors_dask` runs it all the same."""
    probe = types.FunctionType(_on_worker.__code__, {"__builtins__": builtins, "__name__": PROBE_MODULE},
                               _on_worker.__name__, _on_worker.__defaults__)
    probe.__module__ = PROBE_MODULE
    probe.__qualname__ = _on_worker.__name__
    return probe


def cannot_run(seen, sweeps: str | None = None) -> str | None:
    """Why a worker whose :func:`_on_worker` answer is ``seen`` cannot load the sweep's points, or None (it can,
    or it could not be asked: its points say what they meet). ``sweeps``: the sweep's code fingerprint."""
    if not isinstance(seen, dict) or seen.get("runner"):
        return None
    if seen.get("tlm") is None:
        return "it has no tlm" + (f" ({seen['error']})" if seen.get("error") else "")
    theirs = f"; the sweep's {sweeps}" if sweeps else ""
    code = f" (code fingerprint {seen['fingerprint']}{theirs})" if seen.get("fingerprint") else ""
    if seen.get("error"):
        return f"its tlm at {seen['tlm']}{code} fails as it is imported ({seen['error']})"
    return f"its tlm at {seen['tlm']}{code} has no {RUNNER} (it is older than the sweep's)"


def other_code(seen, sweeps: str | None) -> str | None:
    """Why a worker whose :func:`_on_worker` answer is ``seen``, which can load the sweep's points, would fail each
    (``OtherCodeOnWorker``): its code fingerprint is not the sweep's (``sweeps``); None where it is, or where either
    is not known (its points say what they meet)."""
    if not isinstance(seen, dict) or not seen.get("runner") or not sweeps or not seen.get("fingerprint"):
        return None
    if seen["fingerprint"] == sweeps:
        return None
    return (f"its tlm at {seen.get('tlm')} runs other code (code fingerprint {seen['fingerprint']}; the sweep's "
            f"{sweeps}): install the sweep's tlm on the workers, and restart them after an update of it")


ASK_WORKERS = 30.0  # seconds the workers get to answer the probe
# the errors of a point that say its worker cannot run the sweep's points (tlm.experiments.sweep_point,
# tlm.experiments.dask_workers): that worker is left out, the point sent to the others (WorkerWatch.send_again)
WORKER_CAUSED = frozenset({"PathNotOnWorker", "OtherCodeOnWorker", "OtherInputsOnWorker", "OtherVersionsOnWorker"})


class WorkerWatch:
    """The workers a Dask sweep sends its points to: each checked to load them (:meth:`check`: by the sweep,
    before it sends one, and as a worker joins while it runs), and the lines on those that left the cluster
    while they ran some of them (:meth:`lost`, from the scheduler's ``remove-worker`` events, which name the
    tasks a worker held). The sweep's points are known by their keys (:meth:`key`)."""

    def __init__(self, client, code: str | None = None, remote: bool = True) -> None:
        self.client = client
        self.remote = remote  # (a --dask local cluster's workers run the sweep's own tlm)
        self.code = code  # the sweep's code fingerprint, for the lines
        self.keys: set[str] = set()
        self.hosts: dict[str, str] = {}  # a worker's address -> its host, as it said
        self.names: dict[str, str] = {}  # a worker's address -> the name it was given (dask worker --name), as it said
        self.why: dict[str, str] = {}  # a worker's address -> why it cannot load the sweep's points
        self.checked: set[str] = set()
        self.lines: list[str] = []
        self.alive: set[str] = set()  # the workers the scheduler had when last asked (check, DaskPool.trouble)
        self.bad: dict[str, list] = {}  # a worker left out (its address) -> [why, how many of its points ran again]
        self.back: dict[str, list] = {}  # those left out that came back at their address, answering well (lines kept)
        self.again: set[str] = set()  # the points (their hashes) sent again to the good workers: once each
        self.last: set[str] = set()  # the workers found bad, by a point, when none good was left beside them
        self.failed_on: dict[str, str] = {}  # a point sent again (its hash) -> the worker it failed for (its address)
        self.back_again: dict[str, list[str]] = {}  # one re-admitted -> the points sent again from it before (hashes)
        self.gone: list[dict] = []  # the workers that left while they held some of the sweep's points (lost: events)
        # a point's future as the sweep holds it -> [its Dask future, the workers it went to (None: any), fn, args,
        # kwargs]: sent again where those all left (move); its entry dropped once it is done
        self.sent: dict[cf.Future, list] = {}
        self.kept: list[str] = []  # the good workers last there (targets: while none is, a point waits for one)
        self.lock = threading.Lock()  # (sent: the Dask futures' callbacks run in threads of their own)
        self.events: deque = deque()  # (time, message) of the scheduler's "all" topic, appended by the client's loop
        self.subscribed = False
        subscribe = getattr(client, "subscribe_topic", None)
        if subscribe is not None:
            with suppress(Exception):  # (a scheduler that cannot: a worker lost is said as before, not named)
                subscribe("all", self._event)
                self.subscribed = True

    def _event(self, event) -> None:
        """One of the scheduler's events: a worker's removal, kept for :meth:`lost` (no other event is kept); the
        worker is no longer checked (one that a nanny restarts at the same address may run another tlm: asked
        again), what was known of it kept with the event."""
        msg = event[1] if isinstance(event, tuple) and len(event) == 2 else None
        if not isinstance(msg, dict) or msg.get("action") != "remove-worker":  # (every client's gathers, scatters,
            return  # runs, on a shared scheduler: not kept for a long sweep)
        address = str(msg.get("worker"))
        event = (*event, self.why.pop(address, None), address in self.checked, self.where(address))
        self.checked.discard(address)
        self.alive.discard(address)
        self.names.pop(address, None)  # (another worker at that address says its own name, or none, when asked)
        self.events.append(event)

    def close(self) -> None:
        """The scheduler's events no longer sent to this client: before it closes (else an in-process scheduler
        logs, at CRITICAL, the event of the client's own close that it could not send it); the points still sent
        (:meth:`send`: a sweep stopped) cancelled."""
        with self.lock:
            left = [entry[0] for entry in self.sent.values() if entry[0] is not None]
            self.sent.clear()
        if left:
            with suppress(Exception):  # (a client whose scheduler is gone cannot cancel anything)
                self.client.cancel(left)
        if self.subscribed:
            self.subscribed = False
            with suppress(Exception):
                self.client.unsubscribe_topic("all")

    def key(self, fn) -> str:
        """A new key for a point of the sweep's, as Dask's own for an impure call (its function's name, a uuid)."""
        key = f"{getattr(fn, '__name__', 'point')}-{uuid.uuid4()}"
        self.keys.add(key)
        return key

    def send(self, fn, args: tuple, kwargs: dict) -> cf.Future:
        """The point ``fn(*args, **kwargs)`` submitted to the workers that can run it (:meth:`targets`, each time it
        is sent), keyed (:meth:`key`); the future the sweep holds, which takes the Dask future's outcome. Where the
        workers it was sent to all left (a nanny that restarts its worker gives it another port), it is sent again
        to the good ones there (:meth:`move`): Dask keeps it for the gone addresses, and the sweep waited for ever."""
        held: cf.Future = cf.Future()
        with self.lock:
            self.sent[held] = [None, None, fn, args, kwargs]
        held.add_done_callback(self._dropped)
        self._submit(held)
        return held

    def _submit(self, held: cf.Future) -> None:
        """``held``'s point submitted to the workers that can run it now (:meth:`send`)."""
        with self.lock:
            entry = self.sent.get(held)
        if entry is None:  # (cancelled by the sweep meanwhile)
            return
        fn, args, kwargs = entry[2:]
        good = self.targets()
        where = {} if good is None else {"workers": good, "allow_other_workers": False}
        future = self.client.submit(fn, *args, key=self.key(fn), pure=False, **kwargs, **where)
        with self.lock:
            mine = self.sent.get(held) is entry
            if mine:
                entry[0], entry[1] = future, good
        if not mine:  # (cancelled by the sweep meanwhile)
            with suppress(Exception):
                future.cancel()
            return
        future.add_done_callback(lambda done: self._done(held, done))

    def _done(self, held: cf.Future, future) -> None:
        """The Dask ``future`` of ``held`` done: its outcome ``held``'s, where it is still ``held``'s (not one sent
        since: :meth:`move`)."""
        with self.lock:
            entry = self.sent.get(held)
            if entry is None or entry[0] is not future:
                return
            del self.sent[held]
        with suppress(cf.InvalidStateError):  # (the sweep cancelled it meanwhile)
            if future.status == "cancelled":  # (by the scheduler: a lost connection, a restarted cluster)
                held.cancel()
                held.set_running_or_notify_cancel()
                return
            try:
                held.set_result(future.result())
            except Exception as e:  # (the point's worker died: KilledWorker; the scheduler lost)
                held.set_exception(e)
            except BaseException:  # (cancelled as it was read)
                held.cancel()
                held.set_running_or_notify_cancel()

    def _dropped(self, held: cf.Future) -> None:
        """``held`` done: cancelled by the sweep (an interrupt), its Dask future too."""
        if held.cancelled():
            with self.lock:
                entry = self.sent.pop(held, None)
            if entry is not None and entry[0] is not None:
                with suppress(Exception):
                    entry[0].cancel()

    def move(self) -> int:
        """The points whose workers (those they were sent to: :meth:`send`) all left the cluster, sent again to the
        good workers there (:meth:`targets`); how many. None moved where no worker is left out (their Dask futures
        go to any worker) or none good is there (the sweep's wait for one: :meth:`seen`)."""
        if not self.bad or not self.good():
            return 0
        with self.lock:
            stuck = [(held, entry[0]) for held, entry in self.sent.items()
                     if entry[0] is not None and entry[1] and not self.alive.intersection(entry[1])
                     and not entry[0].done()]
        for held, old in stuck:
            self._submit(held)
            with suppress(Exception):
                old.cancel()
        return len(stuck)

    def sweeps_code(self) -> str | None:
        """The sweep's code fingerprint (this process's tlm), for a line on a worker of another."""
        if self.code is None:
            with suppress(Exception):
                from tlm.fingerprint import code_fingerprint

                self.code = code_fingerprint()
        return self.code

    def where(self, address: str) -> str:
        """The worker at ``address`` in a line: by its name where it was given one, its host where it said it."""
        from tlm.experiments.dask_workers import worker_words

        return worker_words(self.names.get(address), address, self.hosts.get(address))

    def check(self, addresses=None) -> list[str]:
        """The workers at ``addresses`` (None: every worker the scheduler has) not checked yet, asked what
        they have of tlm (:func:`worker_probe`); one line for each that cannot load the sweep's points. A
        worker that cannot be asked is not refused (its points say what they meet)."""
        if addresses is not None:
            addresses = [a for a in addresses if a not in self.checked]
            if not addresses:
                return []
        try:
            got = self.client.run(worker_probe(), RUNNER, workers=addresses, on_error="return",
                                  callback_timeout=ASK_WORKERS)
        except Exception:  # (a scheduler that does not answer: the sweep's own wait says it)
            return []
        lines = []
        self.alive.update(got)
        for address, seen in sorted(got.items()):
            self.checked.add(address)
            if address in self.bad and address not in self.why and cannot_run(seen) is None and \
                    other_code(seen, self.sweeps_code()) is None:  # (a worker back at the address of one left out:
                self.back[address] = self.bad.pop(address)  # asked afresh; its points say what they meet)
                # (the points sent again from it so far: its left-out event's, not those of its leaving out again)
                self.back_again[address] = sorted(p for p, a in self.failed_on.items() if a == address)
                for p in self.back_again[address]:
                    del self.failed_on[p]
            if isinstance(seen, dict) and seen.get("host"):
                self.hosts[address] = str(seen["host"])
            if isinstance(seen, dict) and isinstance(seen.get("name"), str):
                self.names[address] = seen["name"]
            why = cannot_run(seen)
            if why is not None:
                why = cannot_run(seen, self.sweeps_code())
                self.why[address] = why
                lines.append(f"{self.where(address)} cannot run tlm's points: {why}")
            elif (other := other_code(seen, self.sweeps_code())) is not None:  # (each of its points would fail)
                self.why[address] = other
        for address in sorted(a for a in list(self.alive) if a in self.why):  # (found before a good one joined too;
            # a copy: the client's loop thread drops a worker that leaves, _event)
            self.leave_out(address, f"it cannot run tlm's points: {self.why[address]}")
        return lines

    def seen(self, workers) -> tuple[int, str]:
        """The scheduler's ``workers`` (their addresses) as it lists them now: kept, for :meth:`targets`, and each
        that joined since asked (:meth:`check`). How many the sweep's points can go to, and the words for none
        (``has had no worker``): the points sent to the good workers only wait for one, beside those left out."""
        self.alive = set(workers)
        self.check(list(workers))
        self.move()  # (the points sent to good workers that all left since: to those there now)
        if self.alive and self.bad and not self.good():
            return 0, "has had no worker that can run the sweep's points"
        return len(self.alive), "has had no worker"

    def start(self, refuse: bool) -> None:
        """Before the first point: every worker asked (:meth:`check`); those that cannot run the sweep's points are
        left out (:meth:`leave_out`) while a good one remains. Where none does, as before: ``refuse`` (a remote
        cluster), :class:`WorkerCannotRun` where a worker cannot load the points (:meth:`refuse`); else the points
        are sent to them all, and fail there with why (a tlm of other code: ``OtherCodeOnWorker``)."""
        lines = self.check()
        if lines and refuse and not self.targets():
            self.refuse(lines)

    def leave_out(self, address: str, why: str) -> bool:
        """The worker at ``address`` is left out of the sweep's points from now on (:meth:`targets`), for ``why``
        (said once: :meth:`left_out`), where another worker of the scheduler's is not (else, as before, the points
        go to every worker, and fail there with why). Whether it is left out."""
        if address in self.bad:
            return True
        if not self.alive - set(self.bad) - set(self.why) - {address}:  # (no good worker but it)
            return False
        self.bad[address] = [why, 0]
        self.kept = self.good()
        return True

    def good(self) -> list[str]:
        """The workers there (as last asked) that are not left out (:meth:`leave_out`) nor found unable to run the
        sweep's points."""
        return sorted(self.alive - set(self.bad) - set(self.why))

    def targets(self) -> list[str] | None:
        """The workers the sweep's points go to (``Client.submit``'s ``workers``, no other allowed): those not left
        out (:meth:`leave_out`); None where none is left out (every worker, as before). Where none of them is there
        (a good worker that its nanny restarts is gone a moment, and back at another port), those last there: the
        point waits for a good worker (:meth:`move`, within --dask-wait: :meth:`seen`), where it went to a bad one
        and failed there."""
        if not self.bad:
            return None
        if good := self.good():
            self.kept = good
        return self.kept or None

    def send_again(self, point: str, record: dict) -> bool:
        """Whether the point ``point`` (its hash), whose worker's record is ``record``, goes again to the other
        workers: it failed for its worker (:data:`WORKER_CAUSED`: that worker's code, versions, view of the sweep's
        files), which is then left out (:meth:`leave_out`), and it was not sent again before (a point that fails
        again on another worker fails, as before)."""
        error = record.get("error") if record.get("status") == "failed" else None
        if not isinstance(error, dict) or error.get("type") not in WORKER_CAUSED:
            return False
        address = self.address_of((record.get("ran") or {}).get("worker"))
        if address is None:
            return False
        if not self.leave_out(address, f"{error['type']}: {error.get('message')}"):
            self.last.add(address)  # (no good worker but it: the points fail with why, as before)
            return False
        if point in self.again or not self.targets():
            return False
        self.again.add(point)
        self.failed_on[point] = address
        self.bad[address][1] += 1
        return True

    def address_of(self, worker) -> str | None:
        """The address of the worker a point's record names (``ran.worker``: its name, else its address), or None."""
        if not isinstance(worker, str):
            return None
        if worker in self.alive or worker in self.bad:
            return worker
        named = [a for a, n in list(self.names.items()) if n == worker]  # (a copy: _event drops one that leaves)
        return named[0] if len(named) == 1 else None

    def left_out(self) -> list[str]:
        """One line on each worker left out of the sweep (:meth:`leave_out`): which, why, and that its points went
        to the other workers (how many ran again there). Where the other workers turned out bad too (their points
        failed with why: as on a cluster of none good), only those the probe found, which no row names."""
        lines = []
        for address, (why, n) in [*self.back.items(), *self.bad.items()]:
            if self.last and address not in self.why:
                continue
            again = (f"{n} of them run again there" if n else "none was sent to it" if address in self.why else
                     "none of them run again there")  # (its failed point had run again already: it fails)
            lines.append(f"{self.where(address)} was left out of the sweep ({why}); its points went to the other "
                         f"workers ({again})")
        return lines

    def refuse(self, lines: list[str] | None = None) -> None:
        """:class:`WorkerCannotRun` naming each worker that cannot load the sweep's points (``lines``: those
        :meth:`check` gave; None: asked now), before any is sent."""
        lines = self.check() if lines is None else lines
        if lines:
            self.close()
            raise WorkerCannotRun(f"{'; '.join(lines)}: install the sweep's tlm on the workers and restart them "
                                  "(no point was sent)")

    def lost(self) -> list[str]:
        """Every line so far on a worker that left the cluster while it ran (or held) some of the sweep's
        points (the scheduler runs them again on another worker), with why where it is known."""
        while self.events:  # (each a worker's removal, with what was known of it then: _event)
            _, msg, why, checked, where = self.events.popleft()
            held = len(self.keys.intersection(msg.get("processing-tasks") or ()))
            if not held:
                continue
            if why is not None:
                why = f"it cannot run tlm's points: {why}"
            elif checked or not self.remote:
                why = "why is in its own log"
            else:  # (it joined, and left, between two of the sweep's polls)
                why = ("why is in its own log; it left before the sweep could ask what tlm it has: one whose tlm is "
                       "older than the sweep's leaves so at its first point")
            self.lines.append(f"{where} left the cluster while it held {held} of the sweep's points ({why})")
            self.gone.append({"event": "left-cluster", "worker": str(msg.get("worker")), "why": why,
                              "points_held": held, "line": self.lines[-1]})
        return list(self.lines)

    def worker_events(self, records: dict[str, dict]) -> list[dict]:
        """What the sweep's folder keeps of its workers (``workers.json``: :func:`~tlm.experiments.sweep_rows.
        keep_worker_events`), one plain-data event for each line of :meth:`left_out` and :meth:`lost`: ``left-out``
        (the worker's address, name and host, why, and each point sent again from it: its hash, and from
        ``records``, the sweep's record of each point by its hash, the worker it ran on then and how it ended),
        ``re-admitted`` (one left out that came back at its address answering well) and ``left-cluster``
        (how many of the sweep's points it held), each with its ``line``, as said."""
        out = []
        lines = iter(self.left_out())
        # (one re-admitted and left out again is in both: its events in that order, each with its own points)
        entries = [*((a, v, True) for a, v in self.back.items()), *((a, v, False) for a, v in self.bad.items())]
        for address, (why, _), readmitted in entries:
            if self.last and address not in self.why:  # (as left_out: no line on it)
                continue
            again = []
            points = self.back_again.get(address, []) if readmitted else \
                sorted(p for p, a in self.failed_on.items() if a == address)
            for point in points:
                record = records.get(point) or {}
                ran = record.get("ran") if isinstance(record.get("ran"), dict) else {}
                again.append({"hash": point, "ran_on": ran.get("worker"), "host": ran.get("host"),
                              "status": record.get("status", "not run")})
            worker = {"worker": address, "name": self.names.get(address), "host": self.hosts.get(address)}
            out.append({"event": "left-out", **worker, "why": why, "sent_again": again, "line": next(lines, None)})
            if readmitted:
                out.append({"event": "re-admitted", **worker, "line": f"{self.where(address)}, left out of the "
                            "sweep, came back at its address answering well and took the sweep's points again"})
        self.lost()
        return [*out, *self.gone]


def killed_worker_line(e: BaseException) -> str | None:
    """tlm's line for Dask's ``KilledWorker`` (``distributed.scheduler.KilledWorker``: the workers that held the point
    died more times than ``distributed.scheduler.allowed-failures`` allows), in place of Dask's own (which points to a
    web page): the last worker, where Dask names it, the setting and its value, that the point need not be the cause
    (a point only queued on a worker that died counts too) and that a rerun into the folder runs it again. None for
    any other exception."""
    if type(e).__name__ != "KilledWorker" or not type(e).__module__.startswith("distributed"):
        return None
    from tlm.experiments.dask_workers import worker_words

    worker = getattr(e, "last_worker", None) if len(e.args) >= 2 else None
    last = getattr(worker, "address", None)
    failures = e.args[2] if len(e.args) >= 3 and isinstance(e.args[2], int) else None
    times = f"{failures + 1} times" if failures is not None else "too many times"
    allowed = f" ({failures})" if failures is not None else ""
    last = f", the last {worker_words(getattr(worker, 'name', None), last)}" if isinstance(last, str) and last else ""
    return (f"the Dask workers that held this point died {times}{last}: Dask gives a point up after "
            f"distributed.scheduler.allowed-failures{allowed} such deaths, whether it ran there or only waited "
            "in the worker's queue (another point may have killed it: out of memory, a crash); the workers' logs "
            "say why; a rerun into the folder runs the point again")
