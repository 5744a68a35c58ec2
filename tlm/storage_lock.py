"""The lock on an output folder, and the swap of a new folder for an old one in one call (out of
:mod:`tlm.storage`, which re-exports :func:`folder_lock`).

* :func:`folder_lock` — an exclusive ``flock`` on a folder as it is now, held while a writer swaps a
  new folder in for it (:func:`tlm.storage.atomic_folder`) and while a command reads the folder it
  just wrote (its report); who holds it: :func:`tlm.claims.lock_holder`.
* :func:`exchange` — two paths swapped in one call (Linux's ``renameat2`` with ``RENAME_EXCHANGE``):
  how a writer puts its new folder in place of an old one, so that the destination is never missing
  meanwhile; where this system or the folder's file system cannot (another OS, a kernel before 3.15,
  NFS, some overlays), the writer renames the old folder aside and its own into place (two renames).
* :func:`exchanges_in` — whether a folder's file system does :func:`exchange` (asked once per file
  system and process, a yes again after :data:`TRUST_S`; a reader's lock asks only what is known, writing
  nothing): there a missing folder is no folder, not a writer between its two renames.
* :func:`sibling_stem` — what the names tlm makes beside a destination carry of its name, within the file
  system's NAME_MAX (:func:`name_max`): here, below :mod:`tlm.storage_live` (which imports both), since the
  probe of :func:`exchanges_in` names its folders so too.
"""

from __future__ import annotations

import ctypes
import errno
import fcntl
import functools
import hashlib
import itertools
import math
import os
import platform
import re
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from pathlib import Path

from tlm.errors import InputError


def _host() -> str:
    """This machine's name as a temporary folder's names carry it (``h`` and its letters
    and digits): on a folder shared between machines, a process id alone names no process."""
    return "h" + (re.sub(r"[^A-Za-z0-9]", "", socket.gethostname())[:32] or "local")


# the most bytes a hidden sibling's name adds to ``.<stem>``: ``.old-h<host, 33>-<pid>-<n>-<m>``, a thread's ``-t<id>``
# (a folder probe's, tlm.storage_lock.exchanges_in: ``.old-h<host, 33>-<pid>-<thread>-<n>-<0 or 1>``, within it too)
_SIBLING_ROOM = 80


def name_max(folder: Path) -> int:
    """The most bytes a name may have in ``folder`` (its nearest folder that exists): ``PC_NAME_MAX``, 255 untold."""
    for d in (folder, *folder.parents):
        try:
            return int(os.pathconf(d, "PC_NAME_MAX"))
        except (FileNotFoundError, NotADirectoryError):
            continue
        except (OSError, ValueError):
            break
    return 255


def sibling_stem(path: str | os.PathLike, strict: bool = True) -> str:
    """What the siblings tlm makes beside ``path`` (``.<stem>.tmp-...``, ``.<stem>.tlm-running``,
    ``<stem>.unsaved-...``) carry of its name: the name itself where the longest of them stays within
    the file system's NAME_MAX (:func:`name_max`), else a prefix of it, ``~`` and 12 hex digits of the
    name's sha256: unique in its folder, the same in every process, and matched by the patterns that find
    them (:func:`tlm.storage.clean_stale`). ``strict``: a name past NAME_MAX itself is refused (an InputError: no
    such file or folder can be); else returned as it is."""
    path = Path(path)
    name = path.name
    size = len(os.fsencode(name))
    if size + 1 + _SIBLING_ROOM <= 128 or name in ("", ".", ".."):  # (within every NAME_MAX but the oldest ones)
        return name
    limit = name_max(path.parent)
    if size > limit:
        if strict:
            raise InputError(f"a name of {size} bytes, past the {limit} this file system allows: give a shorter one",
                             source=str(path))
        return name
    keep = limit - 1 - _SIBLING_ROOM
    if size <= keep:
        return name
    digest = hashlib.sha256(os.fsencode(name)).hexdigest()[:12]
    prefix = name
    while prefix and len(os.fsencode(prefix)) > max(keep - 13, 0):
        prefix = prefix[:-1]
    return f"{prefix}~{digest}"



@contextmanager
def folder_lock(out: Path, waiting: Callable[[], None] | None = None, *, probe: bool = True) -> Iterator[None]:
    """An exclusive lock on the folder ``out`` as it is now (``flock`` on the folder itself),
    held while a writer swaps a new folder in for it, and while a command reads the folder
    it just wrote (its report), so that no other writer replaces it meanwhile. A folder
    replaced while this waited for the lock is locked in its turn; no folder, no lock.
    ``waiting`` is called once, before this waits, where another holds the lock (who:
    :func:`tlm.claims.lock_holder`). ``probe``: False for a reader (a report reading its run folder, one
    shared read-only on a lab server), which never writes: the file system is not probed by making
    folders in ``out``'s parent, only what this process knows of it is used (:func:`exchanges_in`).

    A missing ``out`` is looked for again 10 ms later where a writer may be between its two renames
    (the old folder renamed aside, the new one not yet in). Where ``out``'s parent is on a file system
    that does :func:`exchange` (:func:`exchanges_in`), this machine's writers swap the two folders in
    one call, ``out`` is never missing between them, and a missing folder is no folder, told at once
    (each new point of a sweep). Mixed cases: a writer on another machine through NFS gets EINVAL and
    renames twice, and a reader through NFS (there, or here through an NFS mount) finds that NFS does
    not exchange either, and waits as before. Not waited for: a writer that renames twice on a file
    system this machine exchanges on (an older tlm; a container whose seccomp filter refuses
    ``renameat2``; another machine writing through NFS a disk this one reads locally), caught between
    its renames: a reader finds no folder (as it would have after 10 ms of a slow writer), and a writer
    here finds none to carry the user's files over from, so it puts its folder in place of the one the
    other renames in next (:func:`tlm.storage_swap.swap_tries`), removing what that one carried over."""
    out = Path(out)
    for _ in range(1000):
        try:
            fd = os.open(out, os.O_RDONLY | os.O_DIRECTORY)
        except FileNotFoundError:
            if not exchanges_in(out.parent, out.name, probe=probe):
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


_AT_FDCWD = -100
_RENAME_EXCHANGE = 2
_SYS_RENAMEAT2 = {"x86_64": 316, "amd64": 316, "aarch64": 276, "arm64": 276}  # (where libc has no renameat2)
# (what says that this system or this file system cannot exchange; EPERM: a seccomp filter that refuses the
# call, and otherwise a refusal the two renames then meet and raise)
_CANNOT = frozenset({errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EPERM})
_EXCHANGES: dict[int, bool] = {}  # a file system (st_dev) -> whether it exchanged (once it could not: False)
# a file system (st_dev) -> when an exchange last worked there (time.monotonic()): a yes is trusted for TRUST_S only
_EXCHANGED_AT: dict[int, float] = {}
TRUST_S = 30.0  # seconds a file system's yes is trusted (then asked again: an st_dev is reused after an unmount)
_PROBES = itertools.count()
# a file system (st_dev) -> when a probe there could not make its folders (time.monotonic()): not probed again
# for TRUST_S from a folder this process cannot write (a results folder shared read-only)
_UNWRITABLE: dict[int, float] = {}
_NOT_WRITABLE = frozenset({errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT})


@functools.cache
def _renameat2() -> Callable[[bytes, bytes], int] | None:
    """``renameat2(AT_FDCWD, a, AT_FDCWD, b, RENAME_EXCHANGE)`` through ctypes (libc's, glibc >= 2.28;
    else the system call by its number on x86_64 and aarch64): -1 with ``errno`` set where it fails.
    None on another OS, or where libc has neither."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        libc = ctypes.CDLL(None, use_errno=True)
    except OSError:
        return None
    call = getattr(libc, "renameat2", None)
    if call is not None:
        call.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
        call.restype = ctypes.c_int
        return lambda a, b: call(_AT_FDCWD, a, _AT_FDCWD, b, _RENAME_EXCHANGE)
    number, syscall = _SYS_RENAMEAT2.get(platform.machine()), getattr(libc, "syscall", None)
    if number is None or syscall is None:
        return None
    syscall.restype = ctypes.c_long
    return lambda a, b: syscall(ctypes.c_long(number), ctypes.c_int(_AT_FDCWD), ctypes.c_char_p(a),
                                ctypes.c_int(_AT_FDCWD), ctypes.c_char_p(b), ctypes.c_uint(_RENAME_EXCHANGE))


def exchange(a: Path, b: Path) -> bool:
    """Swap the paths ``a`` and ``b`` (two folders, both there) in one call: True when done. False,
    nothing changed, where this system or ``b``'s file system cannot (another OS, no ``renameat2``:
    ENOSYS; a file system without the exchange, NFS among them: EINVAL, ENOTSUP; EPERM), which
    :func:`exchanges_in` then answers for that file system. Any other failure is the OSError of the
    call, nothing changed (ENOENT where either is gone, EBUSY for a mount point)."""
    call = _renameat2()
    if call is None:
        return False
    if call(os.fsencode(a), os.fsencode(b)) == 0:
        _note(b, True)
        return True
    err = ctypes.get_errno()
    if err in _CANNOT:
        _note(b, False)
        return False
    raise OSError(err, os.strerror(err), str(a), None, str(b))


def is_at(path: Path, folder: os.stat_result) -> bool:
    """Whether ``path`` is the folder ``folder`` is the status of (a folder swapped in, then a signal)."""
    try:
        return os.path.samestat(folder, os.lstat(path))
    except OSError:
        return False


def _note(path: Path, exchanged: bool) -> None:
    """Note whether an exchange worked on the file system of ``path``'s folder (a failure sticks:
    an overlay may exchange some folders and not others, and where one could not, a reader waits; a
    success is trusted for :data:`TRUST_S` from now, :func:`exchanges_in`)."""
    with suppress(OSError):
        dev = os.stat(os.path.dirname(os.path.abspath(path))).st_dev
        if exchanged:
            if _EXCHANGES.setdefault(dev, True):
                _EXCHANGED_AT[dev] = time.monotonic()
        else:
            _EXCHANGES[dev] = False


def _probe_base(folder: Path, name: str) -> str:
    """The name of :func:`exchanges_in`'s two folders in ``folder`` but their ``-0``/``-1``:
    ``.<stem>.old-<host>-<pid>-<thread>-<n>``, ``stem`` the name ``name`` itself, or a long one's prefix and
    hash (:func:`sibling_stem`: within NAME_MAX, and what :func:`tlm.storage.clean_stale` looks for beside
    ``name``'s folder; a name near NAME_MAX made names too long, the probe failed and said no: h527)."""
    stem = sibling_stem(Path(folder) / name, strict=False)
    return f".{stem}.old-{_host()}-{os.getpid()}-{threading.get_native_id()}-{next(_PROBES)}"


def exchanges_in(folder: Path, name: str = "tlm", probe: bool = True) -> bool:
    """Whether the file system of ``folder`` does :func:`exchange`: known from an exchange of this
    process there, else probed per file system (``st_dev``) by exchanging two empty folders
    made in ``folder`` and removed at once (``.<name>.old-<host>-<pid>-<thread>-<n>-0`` and ``-1``, a long
    ``name`` shortened as the other siblings' are, :func:`sibling_stem`: names :func:`tlm.storage.clean_stale`
    removes where a killed process left them). ``probe`` False
    (a reader: :func:`folder_lock`'s): nothing written, what is known of the file system, else False.
    False where the probe cannot tell: one of the two removed meanwhile by another writer's clean-up
    (asked again next time); a folder it cannot write into (read-only, not the user's: remembered for
    that file system, not probed again for :data:`TRUST_S` from a folder this process cannot write).
    A yes is trusted for :data:`TRUST_S` after the last exchange that worked there, then probed again:
    a long-lived process (a Dask worker, a notebook) may outlive the mount, and a tmpfs or NFS mounted later
    may get its device number (a no sticks: it only costs a reader the 10 ms wait of :func:`folder_lock`)."""
    try:
        dev = os.stat(folder).st_dev
    except OSError:
        return False
    known = _EXCHANGES.get(dev)
    if known and time.monotonic() - _EXCHANGED_AT.get(dev, -math.inf) > TRUST_S:
        _EXCHANGES.pop(dev, None)  # (asked again: the file system there may be another now)
        known = None
    if known is not None:
        return known
    if not probe:
        return False
    if _renameat2() is None:
        _EXCHANGES[dev] = False
        return False
    if time.monotonic() - _UNWRITABLE.get(dev, -math.inf) <= TRUST_S and not os.access(folder, os.W_OK | os.X_OK):
        return False  # (a probe there could not write a while ago, and this folder is not writable either)
    base = os.path.join(folder, _probe_base(folder, name))
    made: list[str] = []
    try:
        for path in (f"{base}-0", f"{base}-1"):
            os.mkdir(path)
            made.append(path)
        return exchange(*made)
    except OSError as e:
        if not made and e.errno in _NOT_WRITABLE:
            _UNWRITABLE[dev] = time.monotonic()
        return False
    finally:
        for path in made:
            with suppress(OSError):
                os.rmdir(path)
