"""The lock on an output folder (out of :mod:`tlm.storage`, which re-exports it).

* :func:`folder_lock` — an exclusive ``flock`` on a folder as it is now, held while a writer swaps a
  new folder in for it (:func:`tlm.storage.atomic_folder`) and while a command reads the folder it
  just wrote (its report); who holds it: :func:`tlm.claims.lock_holder`.
"""

from __future__ import annotations

import fcntl
import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def folder_lock(out: Path, waiting: Callable[[], None] | None = None) -> Iterator[None]:
    """An exclusive lock on the folder ``out`` as it is now (``flock`` on the folder itself),
    held while a writer swaps a new folder in for it, and while a command reads the folder
    it just wrote (its report), so that no other writer replaces it meanwhile. A folder
    replaced while this waited for the lock is locked in its turn; no folder, no lock.
    ``waiting`` is called once, before this waits, where another holds the lock (who:
    :func:`tlm.claims.lock_holder`)."""
    out = Path(out)
    for _ in range(1000):
        try:
            fd = os.open(out, os.O_RDONLY | os.O_DIRECTORY)
        except FileNotFoundError:
            time.sleep(0.01)  # (another writer may be between its two renames)
            if out.exists() or out.is_symlink():
                continue
            break
        except OSError:
            break  # not a folder, or not ours to open: no lock
        try:
            if waiting is None:
                fcntl.flock(fd, fcntl.LOCK_EX)
            else:
                try:
                    fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                except BlockingIOError:  # (held by another: said, once, then waited for)
                    told, waiting = waiting, None
                    told()
                    fcntl.flock(fd, fcntl.LOCK_EX)
            try:
                same = os.stat(out).st_ino == os.fstat(fd).st_ino
            except OSError:
                same = False
            if same:
                yield
                return
        finally:
            os.close(fd)  # releases the lock
    yield
