"""This process's writers, and the processes that left temporary files and folders behind (out of
:mod:`tlm.storage`, which imports every name from here and keeps the leftovers' cleaning,
:func:`tlm.storage.clean_stale`).

* :func:`pid_alive` — whether a process of this machine runs; :func:`process_tag` — this process as the
  names of its writers' temporary files and folders carry it (``h<host>-<pid>``); :func:`process_start` — when
  a process started (``/proc``'s clock ticks since boot): a process id reused names another process.
* :func:`_writer`, :func:`_thread_tag`, :func:`_hold`, :func:`_release` — one writer of a folder, a
  thread's temporary file, the temporary folders this process's writers are using now (:data:`_LIVE`,
  :data:`_FILES`, under :data:`_LIVE_LOCK`, which a forked child makes anew: read it as
  ``storage_live._LIVE_LOCK``, never a copy of it).
* :func:`left_by_the_gone` — the entries of a folder that a process now gone left.
* :func:`sibling_stem` — what those names carry of their destination's name: a long name's prefix and hash, so
  that they stay within the file system's NAME_MAX (:func:`name_max`); both defined in :mod:`tlm.storage_lock`
  (whose probe of a file system names its folders so too), imported from here as before.
"""

from __future__ import annotations

import itertools
import os
import re
import threading
from collections.abc import Callable
from pathlib import Path

# (name_max, sibling_stem: in tlm.storage_lock since h527, whose folder probe names its folders with them too;
# imported from here as before)
from tlm.storage_lock import _SIBLING_ROOM as _SIBLING_ROOM
from tlm.storage_lock import _host
from tlm.storage_lock import name_max as name_max
from tlm.storage_lock import sibling_stem as sibling_stem

# The files of tlm.claims.sharing in a sweep's folder (its lock, and one per running sweep): here, below both
# tlm.storage (which skips them) and tlm.claims (which writes them), so that neither imports the other
_GUARD = ".tlm-lock"
LOCK_NAME = _GUARD  # (the lock's name, for the layers above: a sweep's rows are written under it)
_RUNNING = ".tlm-running-"


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` runs (a zombie, ended but not yet reaped, does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:
        pass  # alive (another user's) or unknown
    try:
        line = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return True  # no /proc: it exists
    return not line[line.rindex(")") + 2:].startswith(("Z", "X"))


def process_start(pid: int) -> int | None:
    """When process ``pid`` started, in clock ticks since the machine booted (``/proc/<pid>/stat``'s field 22,
    ``starttime``): a process that ended and another given its id have two; None where there is no ``/proc``
    (or the process is gone, or its line cannot be read)."""
    try:
        line = Path(f"/proc/{pid}/stat").read_text()
        return int(line[line.rindex(")") + 2:].split()[19])  # (fields 3 on, after the name in parentheses)
    except (OSError, ValueError, IndexError):
        return None


def process_tag() -> str:
    """``h<host>-<pid>``: this process, as the names a writer makes beside a destination (temporary
    files and folders, claims), a sweep folder's holder record and a traceback file carry it: on a
    disk shared between machines a process id alone names no process."""
    return f"{_host()}-{os.getpid()}"


# (reentrant, as tlm.claims' lock: a write_atomic or atomic_folder block left open in a reference cycle is closed
# by the garbage collector, whose close takes this lock in whatever thread it runs, one holding it too, as
# tlm.storage._temporary_file allocates under it: a plain lock waited there for ever; each section adds, removes
# or looks up its own name, never walks a set, so a section entered again there is safe: h431)
_LIVE_LOCK = threading.RLock()
_LIVE: set[str] = set()  # the names of the temporary folders this process's writers are using now
_WRITERS = itertools.count()  # (numbers the writers of this process; under _LIVE_LOCK)
_FILES: set[str] = set()  # the temporary files this process's write_atomic blocks are writing now
_CLEANED: set[str] = set()  # the folders whose leftovers this process looked for once (atomic_folder's clean_once)


def _writer() -> str:
    """``<host>-<pid>-<n>``: one writer of a folder, ``n`` counting this process's writers, so
    that two threads (or two writers of one thread) never share a temporary folder."""
    with _LIVE_LOCK:
        n = next(_WRITERS)
    return f"{process_tag()}-{n}"


def _thread_tag() -> str:
    """What a temporary file's name adds for the thread writing it: nothing in the main thread,
    ``-t<id>`` in any other, so two threads writing one file never share its temporary file."""
    if threading.current_thread() is threading.main_thread():
        return ""
    return f"-t{threading.get_native_id()}"


def _hold(name: str) -> None:
    """Note the temporary folder ``name`` as in use by this process (:func:`tlm.storage.clean_stale` keeps it)."""
    with _LIVE_LOCK:
        _LIVE.add(name)


def _release(name: str) -> None:
    """The temporary folder ``name`` is no longer in use (it was renamed or removed)."""
    with _LIVE_LOCK:
        _LIVE.discard(name)


# (the public names of the three above, for a writer's own temporary folder outside tlm.storage: a sweep's report set
# aside, tlm.experiments.sweep_folder; its references' held folder, tlm.experiments.sweep_reference)
new_writer, hold, release = _writer, _hold, _release


def _forget_live() -> None:
    """In a forked child: the parent's folders carry the parent's pid, and its locks may be held."""
    global _LIVE_LOCK
    _LIVE_LOCK = threading.RLock()
    _LIVE.clear()
    _FILES.clear()
    _CLEANED.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_live)


def left_by_the_gone(folder: Path, pattern: re.Pattern, kind: Callable[[Path], bool],
                     in_use: Callable[[Path], bool], alive: Callable[[int], bool] = pid_alive,
                     host_of: Callable[[], str] = _host) -> list[Path]:
    """The entries of ``folder`` (not links; of ``kind``) whose names ``pattern`` matches (its
    groups: the host, None for an older writer's name, and the process id) that a process of this
    machine now gone left, or this process before (its id reused) where ``in_use`` (asked
    under the lock of this process's writers) says none of its writers uses it now; ``alive``: whether a
    process of this machine runs (:func:`pid_alive`), ``host_of``: this machine's name (``_host``):
    :func:`tlm.storage._left_by_the_gone` passes its own of both, what a test replaces there."""
    try:
        entries = list(Path(folder).iterdir())
    except OSError:
        return []
    host, gone = host_of(), []
    for e in entries:
        m = pattern.fullmatch(e.name)
        if not m or (m[1] is not None and m[1] != host) or e.is_symlink() or not kind(e):
            continue
        pid = int(m[2])
        if pid == os.getpid():
            with _LIVE_LOCK:
                if in_use(e):
                    continue
        elif alive(pid):
            continue
        gone.append(e)
    return gone
