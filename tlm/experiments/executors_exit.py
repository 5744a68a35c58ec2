"""How the processes of a sweep's local pool end (out of :mod:`tlm.experiments.executors`, which imports every
name from here under its old name): a worker with the sweep's process (:func:`exit_with`, even a killed one's),
and the sweep's process with its multiprocessing semaphores released before an ``os._exit``
(:func:`release_semaphores`).
"""

from __future__ import annotations

import os
import select
import sys
import threading
import time
import warnings
from contextlib import suppress

from tlm.kernels.threads import die_with_parent

PARENT_POLL = 0.5  # seconds between a worker's checks that the sweep's process lives (without a pidfd)


def release_semaphores() -> None:
    """Unlink this process's multiprocessing semaphores now (a local pool's queues' locks)
    and tell the resource tracker, as multiprocessing's finalizers do at a normal exit: for
    a process about to end with ``os._exit``, which runs none. Without this the tracker, the
    last to hold their names, unlinks them itself and prints "resource_tracker: There appear
    to be N leaked semaphore objects to clean up at shutdown" and a line of its source.

    The semaphores are found by their finalizers (``multiprocessing.util``'s registry, where
    a named ``SemLock`` enters itself with ``SemLock._cleanup``); a finalizer runs once, so
    an exit after this does not run it again. Meant for a signal handler: it waits for
    nothing but the tracker's lock, which is held only while a message is written. Where
    this thread holds it (the signal came during one of the tracker's own calls) the
    tracker warns that it is called reentrantly and still writes the message; that
    warning is not shown."""
    synchronize, util = sys.modules.get("multiprocessing.synchronize"), sys.modules.get("multiprocessing.util")
    registry = getattr(util, "_finalizer_registry", None)
    if synchronize is None or registry is None:  # (no semaphore made)
        return
    cleanup = synchronize.SemLock._cleanup
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for finalizer in list(registry.values()):
            if getattr(finalizer, "_callback", None) is cleanup:
                with suppress(Exception):
                    finalizer()


def exit_with(parent: int) -> None:
    """End this worker when the sweep's process ``parent`` dies.

    A killed sweep (SIGKILL: no shutdown runs) would otherwise leave its workers running
    the points queued to them, and then waiting for more forever. On Linux the kernel
    kills a worker whose parent process dies (:func:`tlm.kernels.threads.die_with_parent`); but under
    ``forkserver`` that parent is the fork server, which lives as long as its children.
    So a daemon thread also waits for ``parent`` itself to end (on a pidfd, else polling
    its pid and this process's parent) and ends the worker with ``os._exit``.
    """
    die_with_parent()
    threading.Thread(target=watch_parent, args=(parent, os.getppid()), name="tlm-watch-sweep",
                     daemon=True).start()


def watch_parent(parent: int, ppid: int) -> None:
    pidfd = None
    with suppress(AttributeError, OSError):  # no pidfd (not Linux >= 5.3), or ``parent`` is gone already
        pidfd = os.pidfd_open(parent)
    if pidfd is not None:
        select.select([pidfd], [], [])  # readable once ``parent`` has ended
    else:
        while alive(parent) and os.getppid() == ppid:
            time.sleep(PARENT_POLL)
    os._exit(1)


def alive(pid: int) -> bool:
    if os.name != "posix":  # os.kill(pid, 0) would terminate it there: the parent check alone
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        pass  # it exists (another user's pid: ours was reused); the parent check still holds
    return True
