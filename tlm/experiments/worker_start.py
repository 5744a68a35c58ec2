"""How a local pool's worker processes start: tlm's own processes, the fork server's preload, the guard.

A local pool (:class:`~tlm.experiments.executors.LocalPool`) forks its workers from a fresh server
process (``forkserver``, else ``spawn``) whose processes are named as tlm's own (:data:`OWN_PROCESS`,
:func:`mp_context`); the server imports tlm's modules once (:func:`tlm_preloaded`). Each worker runs
the main script again as it starts: one whose script starts a sweep as it is imported ends at once with
:data:`UNGUARDED_EXIT` (:func:`leave_if_bootstrapping`), and the sweep's process says so in one
:class:`~tlm.errors.InputError` (:func:`unguarded_error`), before its pool starts a worker where it can
(:func:`check_guarded`). The processes a sweep starts ignore Ctrl-C and a hang-up (:func:`sigint_ignored`):
the sweep alone takes them and ends its workers.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import sys
import threading
from contextlib import contextmanager, suppress

from tlm.errors import InputError

UNGUARDED_EXIT = 79  # the exit status of a worker that, re-running the main script as it starts, was asked
# for a sweep there (the script's is not under ``if __name__ == "__main__":``: leave_if_bootstrapping)
TLM_PRELOAD = ("tlm.experiments.sweep", "tlm.experiments.run")  # imported once by the fork server, not per worker

# the signals a sweep's workers ignore: Ctrl-C's and a hang-up's (a terminal closed, an ssh dropped),
# which the kernel sends to the whole process group: the sweep alone takes them and ends its workers
WORKERS_IGNORE = tuple(getattr(signal, n) for n in ("SIGINT", "SIGHUP") if hasattr(signal, n))


@contextmanager
def sigint_ignored():
    """SIGINT (and SIGHUP: :data:`WORKERS_IGNORE`) ignored while the block starts processes, which
    inherit it: a Ctrl-C at the terminal (a hang-up), which signals the whole process group, then
    reaches the sweep alone, which ends the cluster, and no worker prints its own traceback (a
    page of them, before) or dies of it. A signal meanwhile is not lost (an ignored signal is
    dropped: the sweep went on to its end, exit status 0): they are blocked as well, so it waits,
    and is taken once the block ends (unless another thread, which does not block it, takes it
    meanwhile: dropped, as before). A no-op off the main thread."""
    mask = getattr(signal, "pthread_sigmask", None)  # (POSIX)
    blocked = mask(signal.SIG_BLOCK, set(WORKERS_IGNORE)) if mask is not None else None
    before = {}
    try:
        for signum in WORKERS_IGNORE:
            before[signum] = signal.signal(signum, signal.SIG_IGN)
    except ValueError:  # not the main thread (the first one refused: none changed)
        if mask is not None:
            mask(signal.SIG_SETMASK, blocked)
        yield
        return
    try:
        yield
    finally:
        for signum, handler in before.items():
            signal.signal(signum, handler)
        if mask is not None:
            mask(signal.SIG_SETMASK, blocked)  # (a signal that came meanwhile is taken now)


OWN_PROCESS = "tlm-"  # the start of the name of every process a local pool of tlm's starts


class _OwnProcess:
    """A process of tlm's own pool: named :data:`OWN_PROCESS`..., a name the process has before
    it runs the main script again (:func:`leave_if_bootstrapping`); mixed into a context's class."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        if not self.name.startswith(OWN_PROCESS):
            self.name = OWN_PROCESS + self.name


class _SpawnWorker(_OwnProcess, multiprocessing.context.SpawnProcess):
    """A ``spawn`` process of tlm's own pool."""


class _SpawnContext(multiprocessing.context.SpawnContext):
    """The ``spawn`` context whose processes are tlm's own (:class:`_SpawnWorker`)."""

    Process = _SpawnWorker


if hasattr(multiprocessing.context, "ForkServerContext"):  # (POSIX)
    class _ForkServerWorker(_OwnProcess, multiprocessing.context.ForkServerProcess):
        """A ``forkserver`` process of tlm's own pool."""

    class _ForkServerContext(multiprocessing.context.ForkServerContext):
        """The ``forkserver`` context whose processes are tlm's own (:class:`_ForkServerWorker`)."""

        Process = _ForkServerWorker


def mp_context():
    """A local pool's multiprocessing context: ``forkserver`` (else ``spawn``), whose processes
    are named as tlm's own (:data:`OWN_PROCESS`)."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return _SpawnContext()
    return _ForkServerContext()


@contextmanager
def tlm_preloaded():
    """While the block starts the fork server (if none runs yet: it is one per process), the
    server imports :data:`TLM_PRELOAD` once, not each worker: added to the host program's
    preload list (``multiprocessing.set_forkserver_preload``), which is put back as it was
    afterwards. What stays changed: a fork server started here has tlm's modules imported, and
    serves the host's own forkserver processes too (they fork with tlm imported). The default
    list's ``__main__`` is left out for the start, as tlm's own list always left it: where
    Python passes the server the main script's path, the server would run it, and an
    unguarded script's sweep there."""
    from multiprocessing import forkserver

    with _PRELOAD_LOCK:  # (two threads starting pools at once: the second would keep the first's list as the host's)
        server = getattr(forkserver, "_forkserver", None)
        host = getattr(server, "_preload_modules", None)  # (no public reader)
        if not isinstance(host, list):  # (another Python's fork server: tlm's list alone, as before)
            forkserver.set_forkserver_preload(list(TLM_PRELOAD))
            yield
            return
        forkserver.set_forkserver_preload([*(m for m in host if m != "__main__"),
                                           *(m for m in TLM_PRELOAD if m not in host)])
        try:
            yield
        finally:
            forkserver.set_forkserver_preload(host)


_PRELOAD_LOCK = threading.Lock()


def leave_if_bootstrapping() -> None:
    """End this process at once, quietly, with :data:`UNGUARDED_EXIT` if it is a worker process
    still bootstrapping (Python's own test: ``multiprocessing.spawn._check_not_importing_main``).
    A forkserver or spawn worker runs the main script again as it starts (as ``__mp_main__``); one
    that calls ``tlm.sweep`` not under ``if __name__ == "__main__":`` asks for a sweep there. It
    would start nothing (Python refuses a new process then: each worker printed that
    RuntimeError's traceback, and the sweep saw its workers die before any point); its exit
    status tells the sweep's process why (:func:`check_guarded`,
    :meth:`~tlm.experiments.executors.LocalPool._replace`).
    Only tlm's own processes leave (named :data:`OWN_PROCESS`..., a name they have before they
    run the script): a process of the host's own (its pool, a Dask nanny's worker) that runs the
    script again runs its sweep as before (in-process; a pool of its own is Python's to refuse)."""
    me = multiprocessing.current_process()
    if getattr(me, "_inheriting", False) and me.name.startswith(OWN_PROCESS):
        os._exit(UNGUARDED_EXIT)


def main_script() -> str | None:
    """The main script (its path; a module's name under ``python -m``) that a ``forkserver`` or
    ``spawn`` worker process runs again as it starts, as ``multiprocessing.spawn`` finds it; None
    where it runs none (``python -c``, a script on standard input, a notebook, IPython, a package's
    ``__main__``: :func:`main_file_hidden`)."""
    main = sys.modules.get("__main__")
    name = getattr(getattr(main, "__spec__", None), "name", None)
    path = getattr(main, "__file__", None)
    if name is not None:  # (python -m: imported again by its name, but a package's __main__)
        return None if name == "__main__" or name.endswith(".__main__") else (path or name)
    if path is None or os.path.splitext(os.path.basename(path))[0] == "ipython" or _no_file(path):
        return None
    return os.path.abspath(path)


def _no_file(path: object) -> bool:
    """Whether the main module's ``__file__`` ``path`` names no file: ``<stdin>`` (``python - < script.py``),
    ``<string>`` and their kin, which Python sets for code it did not read from a file."""
    return isinstance(path, str) and path.startswith("<") and path.endswith(">")


@contextmanager
def main_file_hidden():
    """While the block runs (a sweep's pool or Dask cluster, whose workers start, and start again, as
    it runs), a worker process started by ``spawn`` or ``forkserver`` is not told to run again a main
    module whose ``__file__`` names no file (``<stdin>``: a script given on standard input, ``python - <
    script.py``), as ``python -c``'s, which has none: it would (``FileNotFoundError: '<stdin>'``, each
    worker dead before any point). Only what :func:`multiprocessing.spawn.get_preparation_data` tells
    a new process is changed (its ``init_main_from_path``), not ``__main__``: the script's own threads
    still read its ``__file__`` (it was deleted for the whole sweep, a NameError in the caller's other
    threads). Blocks may nest and overlap, in threads: the first in puts the change in, the last out
    takes it away.

    Another library's wrapper of the same function (a user's code, another tool) is kept working, put
    over this one or under it: this one's wrapper calls what it wrapped (its own, not a shared slot), is
    taken away only where it is still the outermost, and otherwise stays under the other, passing calls
    through once no block is open; where it is found in place again (the other library took its own
    away), it is used again rather than wrapped in another (no wrapper calling itself: a RecursionError
    at the next sweep's first worker)."""
    global _hiding
    from multiprocessing import spawn

    with _HIDE_LOCK:
        if _hiding == 0:
            now = spawn.get_preparation_data
            if _wraps(now) is not None:  # (tlm's own, still outermost: used again)
                _PREPARATION[:] = [now]
            else:
                _PREPARATION[:] = [_wrapper(now)]
                spawn.get_preparation_data = _PREPARATION[0]
        _hiding += 1
    try:
        yield
    finally:
        with _HIDE_LOCK:
            _hiding -= 1
            ours = _PREPARATION[0] if _PREPARATION else None
            if _hiding == 0 and ours is not None and spawn.get_preparation_data is ours:
                spawn.get_preparation_data = _wraps(ours)  # (what it wrapped; a call under way keeps it)


_HIDE_LOCK = threading.Lock()
_hiding = 0  # main_file_hidden blocks open
_PREPARATION: list = []  # tlm's wrapper put in by the first block (:func:`_wrapper`), while they are open
_WRAPPED = "_tlm_wraps"  # the attribute of tlm's wrapper: (the wrapper itself, the function it wraps)


def _wraps(function):
    """The function tlm's wrapper ``function`` wraps; None where ``function`` is not tlm's (another's, one made
    with ``functools.wraps`` of tlm's among them: that copies the attribute, which names tlm's wrapper, not it)."""
    mark = getattr(function, _WRAPPED, None)
    return mark[1] if isinstance(mark, tuple) and len(mark) == 2 and mark[0] is function else None


def _wrapper(inner):
    """tlm's :func:`multiprocessing.spawn.get_preparation_data` over ``inner`` (the function it was):
    :func:`_preparation_data`'s change while a :func:`main_file_hidden` block is open, else ``inner``'s
    data as they are (left under another library's wrapper, it passes calls through)."""
    def get_preparation_data(name: str) -> dict:
        return _preparation_data(inner, name) if _hiding else inner(name)

    setattr(get_preparation_data, _WRAPPED, (get_preparation_data, inner))
    return get_preparation_data


def _preparation_data(inner, name: str) -> dict:
    """``inner(name)`` (:func:`multiprocessing.spawn.get_preparation_data`, or the wrapper it was), less
    ``init_main_from_path`` where the main module's ``__file__`` names no file (:func:`main_file_hidden`)."""
    data = inner(name)
    main = sys.modules.get("__main__")
    if getattr(getattr(main, "__spec__", None), "name", None) is None and _no_file(getattr(main, "__file__", None)):
        data.pop("init_main_from_path", None)
    return data


def unguarded_error() -> InputError:
    """The error of a main script that starts a sweep as it is imported (:func:`leave_if_bootstrapping`)."""
    return InputError("the script starts a sweep as it is imported, and each of the sweep's worker processes imports "
                      "it again as it starts (Python's multiprocessing runs the main script in every new process): "
                      "put the call that starts the sweep (tlm.sweep, tlm.run_sweep, the study) under "
                      "`if __name__ == \"__main__\":`", source=main_script() or "__main__")


def check_guarded(context) -> None:
    """Raise :func:`unguarded_error` where a process of ``context`` that runs the main script again
    as it starts (:func:`main_script`) ends with :data:`UNGUARDED_EXIT`: before the pool
    starts a worker, and before the sweep writes anything (it claims its folder once its
    executor opened). One process that does nothing (the cost of a worker's start, once per
    pool); none where no script is run again, nor under ``fork``."""
    if context.get_start_method() == "fork" or main_script() is None:
        return
    probe = context.Process(name=f"{OWN_PROCESS}guard-check")  # (no target: it runs nothing)
    with sigint_ignored():  # (as a worker: a Ctrl-C reaches the sweep alone)
        probe.start()
    try:
        probe.join()
    finally:
        if probe.exitcode is None:  # (interrupted while it starts)
            with suppress(Exception):
                probe.kill()
            probe.join()
    if probe.exitcode == UNGUARDED_EXIT:
        raise unguarded_error()

